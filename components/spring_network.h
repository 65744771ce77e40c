#pragma once
// A mass-spring network: point masses joined by Hooke springs with damping. One entity holds the whole
// network as structure-of-arrays (a rope, a cloth or a jelly is one entity, not one per mass).

#include "engine/math.h"

#include <cstdint>
#include <vector>

namespace tumble {

/// How a spring network is advanced in time.
enum class Integrator : std::uint8_t { ExplicitEuler, Midpoint, Rk4, SymplecticEuler, ImplicitEuler };

/// One spring between masses a and b.
struct SpringLink {
    std::uint32_t a = 0;
    std::uint32_t b = 0;
    double rest = 0.0; ///< m, rest length
    double k = 0.0;    ///< N/m, stiffness
    double kd = 0.0;   ///< N s/m, damping along the spring on the relative velocity
};

/// The state of a spring network (all arrays have one entry per mass).
struct SpringNetwork {
    std::vector<Vec3> x;              ///< m, world positions
    std::vector<Vec3> v;              ///< m/s
    std::vector<double> invMass;      ///< 1/kg (a pinned mass keeps its mass for when it is unpinned)
    std::vector<std::uint8_t> pinned; ///< 1 if the mass is held in place
    std::vector<SpringLink> links;
    double drag = 0.0; ///< N s/m, global -drag * v on every mass
    Integrator integrator = Integrator::SymplecticEuler;
    std::vector<Vec3> force; ///< N, scratch for the step (not state)
};

} // namespace tumble
