#pragma once
// Air on a grid: velocity, smoke and heat in a box of cubic cells centred on the entity (README, "Air").
// The grid is staggered (a MAC grid, Harlow and Welch 1965): smoke and heat at the cells' centres, each
// velocity component on the faces across it (u on the faces across x, v across y, w across z), so that a
// cell's divergence is the difference of its faces' flows and the projection leaves it zero to within the
// solver's tolerance.

#include "engine/entity.h"
#include "engine/math.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace tumble {

/// What a side of the box is: a wall (no flow through it) or open (air leaves and enters freely, at the
/// pressure of the world outside).
enum class AirBorder : std::uint8_t { Closed, Open };

/// A face held at a solid's velocity (it touches a cell inside a body or a driving source): which
/// component's faces, which face, and the velocity across it.
struct AirFixedFace {
    std::uint32_t axis;
    std::uint32_t index;
    float velocity;
};

/// One level of the projection's multigrid: a grid of cells padded by a layer of zeros on every side (so
/// that a neighbour past a wall or an open side reads as zero and the stencil needs no branch), and each
/// cell's diagonal (weight times its neighbours in the box plus its open sides).
struct AirLevel {
    std::array<int, 3> n{};
    float weight = 1.0f; ///< the stencil's weight on this level (2.2 on the one below the finest, 2.2^2, ...)
    std::vector<float> diagonal, inverse, x, b, scratch; ///< inverse: 1 / diagonal (0 for a solid cell)
    std::vector<float> inAir;                            ///< per cell: 1 in the pressure problem, 0 solid
    std::vector<std::uint8_t> solid;                     ///< per cell (unpadded): all its fine cells solid
};

/// What the projection keeps between steps: its levels and work vectors (padded, as AirLevel).
struct AirScratch {
    std::vector<AirLevel> levels;
    std::vector<float> r, p, q;
    std::vector<float> u, v, w, smoke, heat;           ///< the advection's outputs, swapped with the fields
    std::vector<float> back, back2;                    ///< MacCormack's step back (empty without it)
    std::vector<float> cellVelocity, curl, curlLength; ///< the vorticity confinement's, 3 n, 3 n, n
    std::vector<std::int32_t> owner; ///< the voxeliser's: per cell, the body or source it is in
    std::vector<std::uint8_t> solid; ///< the voxeliser's: this step's solid cells
    /// with driving sources: the cells as marked before any was let go, the sources' velocities then, the
    /// marks let go (systems/air_system.cpp, releaseUnbalanced), and the air's regions (empty without)
    std::vector<std::int32_t> marked, released, region;
    std::vector<std::uint32_t> freed; ///< the projection's: cells a body let go this step (padded indices)
    std::vector<double> markedVelocities;
    std::vector<std::array<std::int32_t, 4>> regionStack; ///< the flood fill's: a cell and its i, j, k
};

/// Air::solid's values: a cell out of the pressure problem, inside a body (it holds no smoke or heat) or a
/// driving source (it keeps its own).
constexpr std::uint8_t kBodyCell = 1, kSourceCell = 2;

/// The grid, its parameters and its fields (README, "Air").
struct Air {
    std::array<int, 3> cells{32, 32, 32}; ///< along x, y, z
    double cell = 0.125;                  ///< m, the side of a (cubic) cell
    Vec3 centre;                          ///< m, the box's centre
    /// per side: -x, +x, -y, +y, -z, +z
    std::array<AirBorder, 6> border{AirBorder::Closed, AirBorder::Closed, AirBorder::Closed,
                                    AirBorder::Closed, AirBorder::Closed, AirBorder::Closed};
    double vorticity = 0.0;   ///< confinement strength epsilon (Fedkiw, Stam and Jensen 2001), 0 = off
    double smokeWeight = 0.0; ///< m/s^2 per unit of smoke density: smoke sinks
    double heatLift = 0.0;    ///< m/s^2 per degree above the grid's mean: heat rises
    double dissipation = 0.0; ///< 1/s, smoke's decay
    double viscosity = 0.0;   ///< m^2/s
    bool maccormack = false;  ///< advection with MacCormack's correction (else plain semi-Lagrangian)
    double tolerance = 1e-3;  ///< 1/s: the largest divergence a cell keeps after the projection
    double coefficient = 1.0; ///< how cloth and masses feel it, as a wind field's: N s/m per mass, N s/m^3
                              ///< per area on cloth
    bool dumpFields = false;  ///< dump the whole fields, not only their summary
    // how it is drawn
    std::array<float, 3> smokeColour{0.92f, 0.92f, 0.94f};
    double smokeOpacity = 20.0; ///< 1/m per unit of density: 1 m of smoke of density 0.05 lets e^-1 through
    int velocitySlice = -1; ///< the axis across the drawn slice of velocity arrows (0 x, 1 y, 2 z); -1 none

    // the fields, x fastest, then y, then z
    std::vector<float> u, v, w;         ///< m/s, on the faces: (nx + 1) ny nz, nx (ny + 1) nz, nx ny (nz + 1)
    std::vector<float> smoke, heat;     ///< density (1 = thick), degrees above ambient; nx ny nz each
    std::vector<float> pressure;        ///< the last projection's (scaled: p dt / rho), the next one's guess
    std::vector<float> earlierPressure; ///< the projection's before it (for the guess; padded as pressure)
    /// projections since the grid was made, counted to 2 (2: both pressures are solutions and the guess
    /// carries them on); 1 again after a projection that did not converge
    std::uint32_t projections = 0;
    /// per cell: kBodyCell inside a rigid body (voxelised each step), which the air flows round,
    /// kSourceCell in a driving source (systems/air_system.h), 0 air; empty: none
    std::vector<std::uint8_t> solid;
    std::vector<AirFixedFace> fixedFaces; ///< the faces of the solid cells, at their owners' velocities
    bool solidChanged = false;            ///< the solver's levels must be made again for the new cells
    double divergenceMax = 0.0;           ///< 1/s, the largest cell divergence after the last projection
    std::uint32_t lastIterations = 0;     ///< the last projection's CG iterations
    bool frozen = false;                  ///< blew up: no longer stepped, its velocity zero
    AirScratch scratch;

    std::size_t cellCount() const {
        return std::size_t(cells[0]) * std::size_t(cells[1]) * std::size_t(cells[2]);
    }
    /// World position of the box's lowest corner.
    Vec3 origin() const { return centre - Vec3{cells[0] * cell, cells[1] * cell, cells[2] * cell} * 0.5; }
    /// Index of cell (i, j, k).
    std::size_t at(int i, int j, int k) const {
        return std::size_t(i) +
               std::size_t(cells[0]) * (std::size_t(j) + std::size_t(cells[1]) * std::size_t(k));
    }
};

/// What feeds an air grid (`air_source`): smoke and heat added every second in a sphere or box about the
/// entity, and, if given, a velocity imposed on the faces inside it (a fan, a chimney's draught).
struct AirSource {
    Entity air;                         ///< the air entity it feeds (resolved at load)
    bool sphere = true;                 ///< else a box
    double radius = 0.25;               ///< m, a sphere's
    Vec3 halfExtents{0.25, 0.25, 0.25}; ///< m, a box's
    double smoke = 1.0;                 ///< density added a second
    double heat = 0.0;                  ///< degrees added a second
    bool drives = false;                ///< whether it imposes `velocity`
    Vec3 velocity;                      ///< m/s
};

} // namespace tumble
