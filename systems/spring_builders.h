#pragma once
// Builders that lay out masses and links for ropes, cloth and soft bodies. The scenario loaders, the tests
// and the benchmarks all build their networks here, so they simulate the same thing.

#include "components/spring_network.h"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace tumble {

/// A rope: segments + 1 masses in a straight line from `origin` along `direction`.
struct RopeDef {
    Vec3 origin;                     ///< m, the first mass
    Vec3 direction{1.0, 0.0, 0.0};   ///< unit
    int segments = 10;               ///< links between neighbours (masses: segments + 1)
    double length = 1.0;             ///< m
    double mass = 1.0;               ///< kg, total
    double stiffness = 1000.0;       ///< N/m, between neighbours
    double bend = 0.0;               ///< N/m, between masses two apart (0 = none)
    double damping = 0.0;            ///< N s/m, on every spring
    std::vector<std::uint32_t> pins; ///< masses held in place
};

/// A rectangular cloth: rows x cols masses, row-major, row 0 at the top ("xy") or the back ("xz").
struct ClothDef {
    Vec3 centre; ///< m, the middle of the grid
    int rows = 10;
    int cols = 10;
    std::array<double, 2> size{1.0, 1.0}; ///< m, width (along cols) and height (along rows)
    bool vertical = true;                 ///< "xy" hangs; false: "xz" lies flat
    double mass = 1.0;                    ///< kg, total
    double stretch = 5000.0;              ///< N/m, structural springs
    double shear = 500.0;                 ///< N/m, diagonals
    double bend = 50.0;                   ///< N/m, two apart along rows and columns
    double damping = 0.02;                ///< N s/m, on every spring
    /// The columns close around into a tube of circumference size[0] (its axis along the rows: y for
    /// "xy", z for "xz"); column c at angle 2 pi c / cols, the last column linked to the first.
    bool tube = false;
    std::vector<std::uint32_t> pins;
};

/// A box-shaped lattice of nx x ny x nz masses (x fastest), with structural, shear and bend springs.
struct SoftBodyDef {
    Vec3 centre;                               ///< m, the middle of the lattice
    std::array<double, 3> size{1.0, 1.0, 1.0}; ///< m, along x, y, z
    std::array<int, 3> resolution{4, 4, 4};    ///< masses along x, y, z (at least 2 each)
    double mass = 1.0;                         ///< kg, total
    double stiffness = 1000.0;                 ///< N/m, structural
    double shear = 1000.0;                     ///< N/m, face and body diagonals
    double bend = 100.0;                       ///< N/m, two apart along an axis
    double damping = 0.5;                      ///< N s/m, on every spring
    std::vector<std::uint32_t> pins;
};

/// The masses, links and pins of a rope (links in order along it, bend links after).
SpringNetwork buildRope(const RopeDef& def);
/// The masses, links (stretch, shear, bend), triangles and pins of a cloth.
SpringNetwork buildCloth(const ClothDef& def);
/// The masses, links (structural, shear, bend) and pins of a soft-body lattice.
SpringNetwork buildSoftBody(const SoftBodyDef& def);

/// Indices of a cloth pin preset: "top-corners", "top-row", "left-edge", "corners" or "none".
/// Returns false for an unknown preset.
bool clothPinPreset(const std::string& preset, int rows, int cols, std::vector<std::uint32_t>& out);

/// Marks the given masses pinned (indices must be in range).
void pinMasses(SpringNetwork& net, const std::vector<std::uint32_t>& pins);

} // namespace tumble
