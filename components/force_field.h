#pragma once
// A force field: wind, drag, a vortex or a point attractor, acting on spring networks and particles alike.
// It sits at its entity's transform. The force field system updates `current` once per fixed step (wind
// gusts), so every system that reads the field sees the same wind for the whole step.

#include "engine/math.h"

#include <array>
#include <cstdint>

namespace tumble {

/// The kinds of force field (README, "Spring networks": `kind`).
enum class FieldKind : std::uint8_t { Wind, Drag, Vortex, Point };

/// Definition and per-step state of a force field.
struct ForceField {
    FieldKind kind = FieldKind::Wind;
    Vec3 strength; ///< wind: air velocity, m/s; vortex: (angular speed rad/s, 0, 0); point: (N/kg at 1 m, 0,
                   ///< 0); drag: (N s/m, 0, 0)
    double gust = 0.0; ///< wind: relative amplitude of gusts, 0..1
    double coefficient =
        1.0; ///< wind and vortex: N s/m per mass (N s/m^3 per area on cloth) coupling to the air
    Vec3 axis{0.0, 1.0, 0.0}; ///< vortex: unit axis through the entity's position
    double radius = 0.0;      ///< vortex and point: m, no effect beyond it (0 = unbounded)
    Vec3 origin;              ///< m, the entity's position
    std::array<double, 3> gustPhase{0.0, 0.0, 0.0}; ///< rad, from the scene seed

    Vec3 current; ///< wind: the air velocity this step, gusts included (written by the force field system)
};

} // namespace tumble
