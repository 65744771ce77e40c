#pragma once
// Cloth contact that never ends crossed: self-collision and cloth-against-cloth collision for spring
// networks with surface triangles and `self_collision = true`, after Bridson, Fedkiw and Anderson 2002
// ("Robust treatment of collisions, contact and friction for cloth animation"), with Harmon et al. 2008's
// inelastic projection and Provot 1997's rigid impact zones as the fail-safe.
//
// Two surfaces are kept the mean of their cloths' thicknesses apart (half of each, either side of its
// mid-surface); a cloth keeps its own thickness from itself.
//
// Which pairs collide (the one place this rule is stated): every vertex against every triangle it is not a
// corner of, and every edge against every edge it shares no vertex with, within one cloth and between
// cloths; masses two cells apart included. The only other exclusion is a pair, within one cloth, whose
// distance in the rest state (the positions the cloth was loaded with) is below the thickness, as NvCloth
// and Unity do: such a pair would be pushed apart while the cloth lies flat, fighting its own springs. It
// is left out of the repulsion only: the continuous tests still keep it from crossing (left out of those
// too, two parallel diagonals of neighbouring quads passed through each other in a sheet whose thickness
// was 0.72 of its spacing).
//
// Each step, over all such cloths at once (their vertices and triangles in one flat array):
//   refit     one AABB hierarchy over every triangle, each box swept from where the triangle was at the
//             start of the step to where the integrator (and the colliders) left it, inflated by its
//             cloth's thickness; refitted, rebuilt when loose;
//   pairs     vertex-triangle and edge-edge candidates, each once, by the rule above; kept from step to
//             step while no mass has moved half its thickness from where its pairs were gathered (the boxes
//             are inflated to match, and a pair left out is one that cannot come within the thickness
//             meanwhile); when only a few masses have, only their pairs are gathered again (their triangles
//             looked up in the tree); the pairs of triangles that share a vertex, whose boxes always
//             overlap, are listed once with the layout and only measured;
//   proximity pairs closer than the thickness at the end of the step pushed apart to it, their approach
//             speed removed and their sliding slowed by friction (inelastic repulsion), a few passes;
//   ccd       continuous tests of every candidate's motion over the step (systems/ccd.h: inclusion-based,
//             conservative), each contact stopped a small gap short, a few passes, each testing again only
//             the candidates whose masses the pass before moved. A pair that begins closer than the distance
//             looked for counts when it comes within half of where it began (so a pair resting in contact
//             is not found at the start of every pass), and one that moves rigidly not at all;
//   zones     the fail-safe, only while a continuous test still finds a contact: inelastic projection of
//             all the remaining contacts together (Gauss-Seidel to convergence, constraints kept across
//             rounds) while it makes progress, then rigid impact zones: the masses of each knot of contacts
//             move as one rigid body from where they started (its momentum and angular momentum kept),
//             zones merging round by round; a zone that holds a mass of infinite mass (pinned, or resting
//             on a collider) stays where it started. Then, if contacts remain, their masses are frozen
//             where the step began, round by round. Every loop has a cap; past the last, every free mass
//             stays where the step began, which was clean. So no step ends with a crossing the step before
//             it did not have;
//   untangle  only while a cloth is crossed already (loaded so, moved through itself by hand, or dragged
//             through by a pinned or anchored mass, which contact cannot move): a few rounds a step of global
//             intersection analysis (systems/cloth_untangle.h; Baraff, Witkin and Kass 2003): the part the
//             crossing cuts off on the wrong side moves back through, a quarter of an edge a round; where
//             nothing is cut off, intersection contour minimisation (Volino and Magnenat-Thalmann 2006).
//             Meanwhile the pairs between the crossed parts, and between a part moving back and the crossed
//             parts, are left out of the proximity and continuous tests (they would hold it where it is);
//             a part moving back keeps its contacts with everything else;
//   audit     an exact triangle-triangle test of every non-incident pair (CGAL's exact predicates): where
//             the first step begins (a cloth that starts crossed gets a note naming it, and is untangled),
//             where a step begins when ClothCollision::recheck asks, after a step that began tangled or
//             that moved a pinned mass and had to be held still, and with `run --check-contact` after
//             every step, where a crossing
//             between parts that were not being untangled fails the run like a blow-up. The profile
//             counts the crossed pairs after each step (counter cloth_collision.tangled_pairs).
// Colliders (the ground, static and moving bodies) take part as infinite-mass members: a mass within
// 1.25 thicknesses of a collider surface is seated on it for the step (the cloth's own contacts cannot
// push it into the collider, only along it), and a mass the cloth pushed into a collider anyway is put
// back out and seated, and the fail-safe runs again, freezing at once (a frozen mass goes back to where it
// began, outside a static collider).
// Each stage is timed as its own profile entry (cloth_collision.refit, ...).
//
// System: reads RigidBody; reads and writes SpringNetwork x, v and ClothCollision. Phase: fixed, after the
// collisions with rigid bodies.

#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"
#include "systems/bvh.h"

#include <array>
#include <cstdint>
#include <vector>

namespace tumble {

/// A self-colliding network's contact state, made when the cloth is loaded.
struct ClothCollision {
    std::vector<Vec3> rest; ///< m, the positions the cloth was loaded with (the rest state of the pair rule)
    std::vector<Vec3> previous;          ///< m, where the masses were when the step began
    std::uint64_t crossingsReported = 0; ///< the audit's failures already said for this cloth
    std::uint64_t crossingNotes = 0;     ///< and its notes (crossings being untangled)
    /// Set by whatever moves the masses outside the step (by hand, as a viewer dragging a mass directly
    /// would): the next step looks for crossings where it begins, and untangles what it finds.
    bool recheck = false;
};

/// What the last step of cloth contact did (a world resource, for the tests and the profile).
struct ClothContactStats {
    std::size_t vertexTriangle = 0; ///< candidate pairs
    std::size_t edgeEdge = 0;
    int ccdContacts = 0;       ///< contacts the continuous passes stopped
    int projectionRounds = 0;  ///< rounds of inelastic projection the fail-safe needed
    int zoneRounds = 0;        ///< rounds of rigid impact zones
    int freezeRounds = 0;      ///< rounds that froze the masses of the contacts left where the step began
    bool heldStill = false;    ///< every cap was reached: the free masses stayed where the step began
    std::size_t crossings = 0; ///< intersecting non-incident triangle pairs after the step (audit only)
    std::size_t tangled = 0;   ///< crossed pairs known after the step (the audit's, or the tangles')
    std::uint64_t steps = 0;   ///< steps run
    std::uint64_t stepsWithZones = 0;
    std::uint64_t stepsHeldStill = 0;
    std::uint64_t stepsTangled = 0; ///< steps that began with crossed pairs to untangle
};

/// One step of self- and cloth-cloth collision for every network that asks for it.
void collideCloth(World& world, const StepContext& ctx);

/// The scratch the system keeps between steps (a world resource, private to it).
struct ClothScratch;

/// The collision state a self-colliding network starts with (its current positions as rest and start).
ClothCollision makeClothCollision(const std::vector<Vec3>& x);

/// For the tests: the candidate pairs cloth contact keeps between steps, over all self-colliding cloths laid
/// out as one (vertex and triangle indices global, each cloth's after the one before it), with what they
/// promise: every pair of the rule (see the header) that is closer than its thickness while each of its
/// masses is within `margin` of `gathered` is in the lists.
struct ClothCandidates {
    std::vector<Triangle> triangles;
    std::vector<Vec3> gathered; ///< m, where each mass was when its pairs were last gathered
    std::vector<double> margin; ///< m, how far from there the promise holds
    std::vector<double> thickness;
    std::vector<std::array<std::uint32_t, 2>> vertexTriangle; ///< (vertex, triangle)
    std::vector<std::array<std::uint32_t, 4>> edgeEdge;       ///< (a0, a1, b0, b1)
};
/// Empty when no self-colliding cloth has stepped yet.
ClothCandidates clothCandidates(World& world);

/// Exact test: do the two triangles share a point? (CGAL's exact predicates;
/// systems/triangle_intersection.cpp)
bool trianglesIntersect(const Vec3& a0, const Vec3& a1, const Vec3& a2, const Vec3& b0, const Vec3& b1,
                        const Vec3& b2);

/// Distance from p to the triangle abc (and the barycentric weights of the closest point).
double pointTriangleDistance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, double w[3]);

/// Distance between segments p0-p1 and q0-q1, and the parameters s, t of the closest points.
double segmentDistance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1, double& s, double& t);

} // namespace tumble
