#pragma once
// Cloth self-collision and cloth-against-cloth collision (Bridson, Fedkiw & Anderson 2002, "Robust
// treatment of collisions, contact and friction for cloth animation"), for spring networks with surface
// triangles and `self_collision = true`.
//
// Each such network keeps an AABB hierarchy over its triangles (systems/bvh.h), each box swept from where
// the triangle was at the start of the step to where the integrator (and the collisions with rigid bodies)
// left it, inflated by the thickness; refitted every step, rebuilt when it loosens. Pairs of triangles that
// share no vertex and whose boxes overlap give vertex-triangle and edge-edge pairs (each once), then:
//   1. proximity: a pair closer than the thickness at the end of the step is pushed apart to the
//      thickness; the velocity with which it approaches is removed (an inelastic repulsion) and its sliding
//      velocity loses friction * the normal change (Coulomb);
//   2. continuous collision: for each pair, the times in the step at which its four points are coplanar
//      (the roots of a cubic), and at the first such time where they actually touch, an impulse that stops
//      the crossing, keeping a small gap; repeated (a few passes) until no pair crosses.
// Corrections are shared by the points' inverse masses and barycentric weights (pinned masses do not
// move), applied to positions and, divided by dt, to velocities, so the step stays consistent for every
// integrator. Bridson's last resort (rigid impact zones) is not implemented: a pair still crossing after
// the passes is left to the next step.
//
// System: reads and writes SpringNetwork x, v; keeps a ClothCollision component per network. Phase: fixed,
// after the collisions with rigid bodies.

#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"
#include "systems/bvh.h"

#include <vector>

namespace tumble {

/// A network's collision state: positions at the start of the step, the hierarchy and scratch.
struct ClothCollision {
    std::vector<Vec3> previous; ///< m, where the masses were when the step began
    std::vector<Aabb> boxes;    ///< per triangle, swept and inflated
    std::vector<std::vector<std::uint32_t>> linked; ///< per mass, the masses a spring joins it to, sorted
    std::vector<std::uint32_t> vertexOwner;         ///< per mass, the first triangle that holds it
    std::vector<std::uint8_t> edgeOwned;            ///< per triangle, bit k: it is the first with edge k
    Bvh tree;
    std::size_t rebuilds = 0; ///< times the tree was rebuilt after its first build
};

/// One step of self- and cloth-cloth collision for every network that asks for it.
void collideCloth(World& world, const StepContext& ctx);

/// Registers the system.
void registerClothCollisionSystem(Catalog& catalog);

/// Exact test: do the two triangles intersect (share a point)? For checking results.
bool trianglesIntersect(const Vec3& a0, const Vec3& a1, const Vec3& a2, const Vec3& b0, const Vec3& b1,
                        const Vec3& b2);

/// Distance from p to the triangle abc (and the barycentric weights of the closest point).
double pointTriangleDistance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, double w[3]);

} // namespace tumble
