#pragma once
// A particle emitter and the particles it has born. One entity holds the emitter's settings, the key of
// its random draws and its pool; the pool is structure-of-arrays (one float array per quantity), so the
// update loop streams through packed floats, and the dead leave holes that the survivors past the new end
// fill, in order.
//
// Particles are light: float state, no mass of their own (forces act on them as on a 1 kg body), colour
// and size derived from the fraction of its life lived, so the pool holds nothing the renderer cannot
// compute.

#include "engine/entity.h"
#include "engine/math.h"
#include "engine/random.h"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace tumble {

/// Where an emitter places new particles (README, "Particles": `shape`).
enum class EmitterShape : std::uint8_t { Point, Sphere, Disc, Box };

/// The live particles of one emitter, as parallel arrays; entry i of every array is particle i.
struct ParticlePool {
    std::vector<float> px, py, pz; ///< m, positions
    std::vector<float> vx, vy, vz; ///< m/s, velocities
    // Ages are counted in the pool's own steps, not summed in float: a particle is born at `birthStep`
    // (the number of its first update) and dies in the update numbered `deathStep` (without moving), when
    // its age, steps times dt, first reaches its lifetime (or the next update, when water takes it in). Step
    // numbers wrap at 2^32 (compared as differences), and a life is at most 2^31 - 1 steps. The update reads
    // `deathStep` alone and writes no age: the pool's streaming update moves 13 arrays' worth of bytes a
    // particle, not 15.
    std::vector<std::uint32_t> birthStep; ///< the pool's step at birth
    std::vector<std::uint32_t> deathStep; ///< the pool's step in whose update the particle dies
    std::uint32_t count = 0;              ///< live particles (the arrays are sized to the emitter's capacity)
    std::uint32_t clock = 0;              ///< updates done (mod 2^32): the number of the next one
    // scratch of the update (not state)
    std::vector<std::uint32_t> deadGroups; ///< groups of four with a death, each chunk's in its own stretch
    std::vector<std::uint32_t> deadCounts; ///< per chunk: how many groups it listed
    std::vector<std::uint32_t> deaths;     ///< per chunk: how many of its particles died
    std::vector<std::uint32_t> fillers;    ///< the survivors past the new end, which move into the holes
};

/// Settings of an emitter (read from the scenario; events may change `rate`).
struct EmitterDef {
    EmitterShape shape = EmitterShape::Point;
    double radius = 0.0;                      ///< m, sphere and disc
    Vec3 halfExtents;                         ///< m, box
    Vec3 direction{0.0, 1.0, 0.0};            ///< unit, the cone's axis (and the disc's normal)
    double spreadDeg = 15.0;                  ///< half-angle of the cone of directions
    double rate = 0.0;                        ///< particles per second
    std::uint32_t burst = 0;                  ///< particles at t = 0 (and the default of a burst event)
    std::array<double, 2> lifetime{2.0, 3.0}; ///< s, uniform in range
    std::array<double, 2> speed{4.0, 6.0};    ///< m/s, uniform in range
    std::uint32_t maxParticles = 100000;      ///< capacity; births beyond it are dropped and counted
    double drag = 0.0;                        ///< 1/s, acceleration -drag (v - the air's velocity)
    std::string airName;      ///< the air grid the particles ride (drag pulls them to its velocity), or none
    bool collide = true;      ///< against static colliders
    double restitution = 0.4; ///< of the normal speed, on collision
    double friction = 0.3;    ///< Coulomb coefficient, on collision
    std::array<float, 4> colorStart{1.0f, 1.0f, 1.0f, 1.0f}; ///< RGBA at birth
    std::array<float, 4> colorEnd{1.0f, 1.0f, 1.0f, 0.0f};   ///< RGBA at death
    std::array<float, 2> size{0.05f, 0.05f};                 ///< m, at birth and at death
};

/// An emitter with its particles. Its random draws are keyed, not drawn from one stream: particle n (the
/// n-th born) takes its draws from a stream of its own, seeded from `seed` and n, so births can be made on
/// any number of threads with the same bits.
struct ParticleEmitter {
    EmitterDef def;
    Entity air;  ///< the air grid named by def.airName (resolved at load), or none
    Vec3 origin; ///< m, the entity's position
    ParticlePool pool;
    std::uint64_t seed = 0;         ///< the key of this emitter's draws, from the scene seed and its name
    std::uint64_t rateSteps = 0;    ///< fixed steps emitted at the current rate
    double rateCarry = 0.0;         ///< the fraction of a birth owed when the rate was last set
    std::uint64_t rateBorn = 0;     ///< particles born by the rate since the rate was last set
    std::uint64_t pendingBurst = 0; ///< particles to burst at the start of the next step
    std::uint64_t born = 0;         ///< all particles born so far
    std::uint64_t dropped = 0;      ///< births refused because the pool was full
};

/// Linear interpolation of the start and end colour at life fraction t in [0, 1].
inline std::array<float, 4> particleColor(const EmitterDef& def, float t) {
    std::array<float, 4> c{};
    for (std::size_t i = 0; i < 4; ++i) {
        c[i] = def.colorStart[i] + (def.colorEnd[i] - def.colorStart[i]) * t;
    }
    return c;
}

/// Size (m) at life fraction t in [0, 1].
inline float particleSize(const EmitterDef& def, float t) {
    return def.size[0] + (def.size[1] - def.size[0]) * t;
}

} // namespace tumble
