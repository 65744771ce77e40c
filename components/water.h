#pragma once
// A water surface as a height field: heights above the rest level at the nodes of a regular grid in the
// xz plane, centred on the entity's position (whose y is the rest level), and their rates of change.

#include "engine/math.h"

#include <cstdint>
#include <vector>

namespace tumble {

/// What happens to a wave at the edge of the grid.
enum class WaterBorder : std::uint8_t { Reflect, Absorb };

/// A wave maker: one edge of the grid driven up and down, A sin(2 pi t / T), eased in over the first period.
struct WaveMaker {
    int edge =
        -1; ///< none (-1), or the grid's edge at x's start (0), x's end (1), z's start (2), z's end (3)
    double amplitude = 0.0; ///< m
    double period = 2.0;    ///< s
};

/// The height field and its parameters (README, "Water").
struct Water {
    int nx = 64, nz = 64;    ///< nodes along x and z (rows run along x, one per z)
    double sizeX = 10.0;     ///< m, from the first node to the last along x
    double sizeZ = 10.0;     ///< m, along z
    double depth = 1.0;      ///< m, still water's depth (the floor of the pool, for rendering)
    double waveSpeed = 2.0;  ///< m/s, c in u_tt = c^2 (u_xx + u_zz)
    double damping = 0.0;    ///< 1/s, -damping u_t
    double density = 1000.0; ///< kg/m^3, for buoyancy
    double bodyDrag = 0.5;   ///< how strongly water slows what moves through it, 1/s per unit of
                             ///< submerged fraction
    WaterBorder border = WaterBorder::Reflect;
    WaveMaker maker;
    Vec3 centre; ///< m; y: the rest level

    std::vector<double> h; ///< m, height above the rest level, nx * nz, row (fixed z) by row
    std::vector<double> v; ///< m/s, dh/dt
    /// The waves bodies did not make (the maker's, disturbances, the start's): the same wave equation without
    /// the bodies' displacement, the surface bodies float on. Empty until a body first reaches the water
    /// (until then it is `h`); bodies read it so that their own dent never lifts or sinks them.
    std::vector<double> ambient;
    std::vector<double> ambientV; ///< m/s, d ambient/dt
    bool ambientStill = false;    ///< the ambient surface is flat and stays so (no maker, no disturbance yet)
    std::vector<double> occupied; ///< m, per node: the submerged length of bodies there, last step
    std::vector<double> occupying; ///< scratch: the same this step (kept to spare an allocation a step)
    std::vector<double> hNext;     ///< scratch: the heights a wave step writes, then swapped with h
    std::vector<std::vector<std::uint32_t>> drops; ///< scratch: particles found falling in, per chunk
    std::vector<double> massDisplaced; ///< scratch: m^3, the water each mass of a network displaces
    bool anyOccupied = false;          ///< scratch: whether `occupied` holds a body's share anywhere
    bool occupyingZero = false;        ///< scratch: whether `occupying` is all zeros (no clearing needed)
    std::uint32_t substeps = 1;        ///< wave steps per fixed step (more when dt breaks the CFL limit)

    double dx() const { return sizeX / double(nx - 1); }
    double dz() const { return sizeZ / double(nz - 1); }
    /// World x, z of node (i, k).
    double nodeX(int i) const { return centre.x - 0.5 * sizeX + dx() * i; }
    double nodeZ(int k) const { return centre.z - 0.5 * sizeZ + dz() * k; }
};

} // namespace tumble
