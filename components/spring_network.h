#pragma once
// A mass-spring network: point masses joined by Hooke springs with damping. One entity holds the whole
// network as arrays, one entry per mass (a rope, a cloth or a jelly is one entity, not one per mass). The
// builders (springs, rope, cloth, softbody) differ only in how they lay out masses and links; one set of
// integrators advances them all.

#include "engine/entity.h"
#include "engine/math.h"

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

namespace tumble {

/// How a spring network is advanced in time (see systems/spring_integrators.h for each one's order,
/// stability and cost).
enum class Integrator : std::uint8_t { ExplicitEuler, Midpoint, Rk4, SymplecticEuler, ImplicitEuler };

/// The integrators' names in scenarios and dumps, in the enum's order.
inline constexpr std::string_view kIntegratorNames[] = {"explicit_euler", "midpoint", "rk4",
                                                        "symplectic_euler", "implicit_euler"};
inline constexpr int kIntegratorCount = 5;

inline std::string_view integratorName(Integrator i) {
    return kIntegratorNames[static_cast<std::size_t>(i)];
}

/// What built the network; it decides the dump's kind and how the renderer draws it.
enum class NetworkKind : std::uint8_t { Springs, Rope, Cloth, SoftBody, Fem };

/// One spring between masses a and b.
struct SpringLink {
    std::uint32_t a = 0; ///< first mass
    std::uint32_t b = 0; ///< second mass
    double rest = 0.0;   ///< m, rest length
    double k = 0.0;      ///< N/m, stiffness
    double kd = 0.0;     ///< N s/m, damping along the spring on the relative velocity
};

/// The elements of a finite-element body (kind Fem; systems/fem.h): linear tetrahedra whose nodes are the
/// network's masses, with corotational linear elasticity. Empty for every other kind.
struct FemElements {
    std::vector<std::array<std::uint32_t, 4>> tets; ///< node indices, positively oriented at rest
    std::vector<std::array<Vec3, 4>> gradients;     ///< 1/m, of each corner's shape function at rest
    std::vector<double> volume;                     ///< m^3, at rest
    /// Each element's rotation at the last step: state, where the next step's search for it starts
    std::vector<Quat> rotation;
    double lambda = 0.0;           ///< Pa, first Lame parameter
    double mu = 0.0;               ///< Pa, shear modulus
    double stiffnessDamping = 0.0; ///< s, Rayleigh: damping force -beta K v
    double massDamping = 0.0;      ///< 1/s, Rayleigh: damping force -alpha M v
    /// m/s and rad/s: the body's motion at the start (`linear_velocity`, `angular_velocity`), kept so that
    /// a set event of either gives the body that motion again; not state (the nodes' v are)
    Vec3 startLinear, startAngular;
};

/// A mass held by a rigid body ([[joint]] type "anchor"): it moves with the body's point, and the body
/// feels what the springs and gravity pull on the mass with.
struct SpringAnchor {
    std::uint32_t mass = 0; ///< the held mass (pinned while held)
    Entity body;            ///< a rigid_body (3D) or a rigid_body_2d
    Vec3 local;             ///< the point that holds it, in the body's frame (2D: x, y; z off its plane)
};

/// A node of an fem body the last collision pass pushed out of a static body: that surface's outward normal
/// there and the friction of the pair (systems/collision_system.h). Implicit Euler holds the node's motion
/// into the surface inside its solve (systems/resting_contacts.h).
struct RestingContact {
    std::uint32_t mass = 0;
    Vec3 normal;
    double friction = 0.0;
};

/// The state and model of a spring network; every per-mass array has one entry per mass.
struct SpringNetwork {
    // state, advanced by the spring system
    std::vector<Vec3> x; ///< m, world positions
    std::vector<Vec3> v; ///< m/s

    // model: set by the builder, changed only by events (pin, unpin)
    std::vector<double> invMass;      ///< 1/kg (a pinned mass keeps its mass for when it is unpinned)
    std::vector<std::uint8_t> pinned; ///< 1 if the mass is held in place
    std::vector<SpringLink> links;
    std::vector<SpringAnchor> anchors; ///< masses held by rigid bodies (set by [[joint]] type "anchor")
    double drag = 0.0;                 ///< N s/m, global -drag v on every mass
    double volumePerKg = 0.0; ///< m^3 of the body a kg of its masses stands for (water's lift); 0: points
    Integrator integrator = Integrator::SymplecticEuler;
    double thickness = 0.0;            ///< m, kept between masses and collider surfaces
    double friction = 0.5;             ///< Coulomb coefficient against colliders (and itself)
    bool selfCollision = false;        ///< cloth: collides with itself and other such cloths
    double cgTolerance = 1e-3;         ///< implicit Euler: relative residual the solve stops at
    int cgMaxIterations = 200;         ///< implicit Euler: iterations at most per step
    bool doublePrecisionSolve = false; ///< implicit Euler: solve in double rather than float
    bool implicitCharged = false;      ///< the load charged the memory of implicit Euler's solver

    // shape, for wind on surfaces, the dump and the renderer
    NetworkKind kind = NetworkKind::Springs;
    std::array<std::uint32_t, 3> grid{0, 0, 0};          ///< cloth: rows, cols; softbody: nx, ny, nz
    std::vector<std::array<std::uint32_t, 3>> triangles; ///< surface triangles (cloth), counter-clockwise
    FemElements fem;                                     ///< kind Fem: the elements

    // set by the collision pass with bodies, read by implicit Euler's next step (derived from x and v: not
    // hashed, the same on every run that reaches the same state)
    std::vector<RestingContact> resting;

    // N, set by the water at the end of a step (systems/water_system.h): its push on each mass through the
    // next step, which externalForces adds to the others (empty when no mass is in water). A force rather
    // than a change of velocity made at once, so that the velocities a step ends with are the motion (a
    // mass floating at rest shows none) and a contact holding a mass holds the water's push with its weight
    std::vector<Vec3> waterForce;

    // set when the network blew up: it is no longer advanced
    bool frozen = false;
    bool blowUpFails = true; ///< false (on_blow_up = "freeze"): a blow-up is expected, noted, not a failure
};

} // namespace tumble
