#include "systems/particle_system.h"

#include "components/air.h"
#include "components/force_field.h"
#include "engine/name.h"
#include "engine/parallel.h"
#include "engine/retune.h"
#include "engine/scene.h"
#include "engine/simd.h"
#include "engine/transform.h"
#include "systems/air_solver.h"
#include "systems/field_forces.h"

#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace tumble {

namespace {

constexpr double kHuge = 1e9;
/// Particles per chunk of the parallel update: a multiple of four (a chunk's groups of four are whole), and
/// enough work (about 30 us) to dwarf handing the chunk to a thread.
constexpr std::uint32_t kParticleGrain = 1u << 14;

constexpr std::int64_t kMaxParticles = 5'000'000;        // 160 MB of state at most per emitter
constexpr std::uint64_t kMaxSceneParticles = 10'000'000; // and 320 MB for the whole scene
// the longest life in steps: ages are step numbers compared as 32-bit differences (components/particles.h)
constexpr std::uint32_t kMaxLifeSteps = 0x7fffffffu;

/// Load-time tally of the particles every emitter of the scene reserves.
struct ReservedParticles {
    std::uint64_t count = 0;
};

/// Two unit vectors completing `d` to an orthonormal basis (t1, t2, d).
void basis(const Vec3& d, Vec3& t1, Vec3& t2) {
    const Vec3 helper = std::abs(d.x) < 0.9 ? Vec3{1.0, 0.0, 0.0} : Vec3{0.0, 1.0, 0.0};
    t1 = cross(helper, d);
    t1 = t1 * (1.0 / length(t1));
    t2 = cross(d, t1);
}

/// The stream of the n-th particle an emitter gives birth to: a seed mixed from the emitter's key and n
/// (splitmix64's finaliser), so that every birth has its own draws whichever thread makes it.
Rng birthStream(std::uint64_t emitterSeed, std::uint64_t n) {
    std::uint64_t z = emitterSeed + (n + 1) * 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return Rng(z ^ (z >> 31));
}

/// A uniformly random point of the unit disc (rejection from the square: no trigonometry).
void unitDisc(Rng& rng, double& a, double& b) {
    do {
        a = 2.0 * rng.uniform() - 1.0;
        b = 2.0 * rng.uniform() - 1.0;
    } while (a * a + b * b > 1.0);
}

void loadEmitter(TableReader& r, World& world, Entity entity, const SceneDef& scene) {
    ParticleEmitter e;
    EmitterDef& d = e.def;
    d.rate = r.number("rate", 0.0, 0.0, 1e8);
    d.burst = static_cast<std::uint32_t>(r.integer("burst", 0, 0, kMaxParticles));
    const auto life = r.range("lifetime", {2.0, 3.0}, 1e-6, 1e6);
    d.lifetime = {life.first, life.second};
    if (life.second / scene.dt > double(kMaxLifeSteps)) {
        // ages are counted in 32-bit steps (components/particles.h)
        char text[200];
        std::snprintf(
            text, sizeof text,
            "a lifetime of %g s is %.3g steps at dt = %g s; a particle lives at most %u steps (%g s "
            "at this dt)",
            life.second, life.second / scene.dt, scene.dt, kMaxLifeSteps, kMaxLifeSteps * scene.dt);
        r.fail("lifetime", text);
    }
    const std::string shape = r.choice("shape", "point", {"point", "sphere", "disc", "box"});
    d.shape = shape == "point"    ? EmitterShape::Point
              : shape == "sphere" ? EmitterShape::Sphere
              : shape == "disc"   ? EmitterShape::Disc
                                  : EmitterShape::Box;
    if (d.shape == EmitterShape::Sphere || d.shape == EmitterShape::Disc) {
        d.radius = r.number("radius", 0.5, 0.0, kHuge);
    }
    if (d.shape == EmitterShape::Box) {
        const auto h = r.vector<3>("half_extents", {0.5, 0.5, 0.5}, 0.0, kHuge);
        d.halfExtents = {h[0], h[1], h[2]};
    }
    const auto dir = r.vector<3>("direction", {0.0, 1.0, 0.0}, -kHuge, kHuge);
    const Vec3 direction{dir[0], dir[1], dir[2]};
    if (length(direction) < 1e-12) {
        r.fail("direction", "'direction' in " + r.where() + " must not be zero");
    }
    d.direction = direction * (1.0 / length(direction));
    d.spreadDeg = r.number("spread_deg", 15.0, 0.0, 180.0);
    const auto speed = r.range("speed", {4.0, 6.0}, 0.0, 1e5);
    d.speed = {speed.first, speed.second};
    d.maxParticles = static_cast<std::uint32_t>(r.integer("max_particles", 100000, 1, kMaxParticles));
    // the pool (32 bytes of state each, measured 36 with the run's own) and what drawing it streams
    r.charge("max_particles", std::uint64_t(d.maxParticles) * 64u,
             r.where() + " (" + std::to_string(d.maxParticles) + " particles)");
    // every emitter reserves its whole pool at load (so a step never allocates): bound the scene's total
    auto* reserved = world.tryResource<ReservedParticles>();
    if (!reserved) {
        reserved = &world.setResource<ReservedParticles>();
    }
    reserved->count += d.maxParticles;
    if (reserved->count > kMaxSceneParticles) {
        r.fail("max_particles", "the scene's emitters reserve " + std::to_string(reserved->count) +
                                    " particles in all; at most " + std::to_string(kMaxSceneParticles) +
                                    " (320 MB) are allowed");
    }
    d.drag = r.number("drag", 0.0, 0.0, 1e3);
    if (r.has("air")) {
        d.airName = r.requiredString("air"); // resolved by linkEmitter, once every entity exists
    }
    d.collide = r.boolean("collide", true);
    d.restitution = r.number("restitution", 0.4, 0.0, 1.0);
    d.friction = r.number("friction", 0.3, 0.0, 100.0);
    if (const toml::node* color = r.node("color")) {
        const toml::array* pair = color->as_array();
        if (!pair || pair->size() != 2) {
            r.fail("color", "'color' in " + r.where() + " is [[r, g, b, a], [r, g, b, a]]: start and end");
        }
        double c[4];
        r.readNumbers(*pair->get(0), "color", c, 4, 0.0, 1.0);
        d.colorStart = {float(c[0]), float(c[1]), float(c[2]), float(c[3])};
        r.readNumbers(*pair->get(1), "color", c, 4, 0.0, 1.0);
        d.colorEnd = {float(c[0]), float(c[1]), float(c[2]), float(c[3])};
    }
    // [start, end] (it may shrink), or one number for both
    if (const toml::node* sizeNode = r.node("size")) {
        if (sizeNode->is_number()) {
            const auto s = static_cast<float>(r.number("size", 0.05, 0.0, 1e3));
            d.size = {s, s};
        } else {
            double s[2];
            r.readNumbers(*sizeNode, "size", s, 2, 0.0, 1e3);
            d.size = {float(s[0]), float(s[1])};
        }
    }
    e.origin = world.get<Transform>(entity).position;
    e.seed = streamSeed(scene.seed, "emitter:" + world.get<Name>(entity).value);
    reserveParticles(e.pool, d.maxParticles);
    e.pendingBurst = d.burst;
    world.emplace<ParticleEmitter>(entity, std::move(e));
}

void dumpEmitter(const ParticleEmitter& e, JsonWriter& w) {
    const ParticlePool& p = e.pool;
    w.key("count").value(static_cast<std::uint64_t>(p.count)).key("born").value(e.born);
    w.key("dropped").value(e.dropped);
    w.key("x").beginArray();
    for (std::uint32_t i = 0; i < p.count; ++i) {
        const double xyz[3] = {p.px[i], p.py[i], p.pz[i]};
        w.numbers(xyz);
    }
    w.endArray().key("v").beginArray();
    for (std::uint32_t i = 0; i < p.count; ++i) {
        const double xyz[3] = {p.vx[i], p.vy[i], p.vz[i]};
        w.numbers(xyz);
    }
    w.endArray();
}

bool emitterRows(const ParticleEmitter& e, std::string_view field, Catalog::Rows& rows) {
    const ParticlePool& p = e.pool;
    const bool x = field == "x";
    if (!x && field != "v") {
        return false;
    }
    const std::vector<float>& a = x ? p.px : p.vx;
    const std::vector<float>& b = x ? p.py : p.vy;
    const std::vector<float>& c = x ? p.pz : p.vz;
    rows.resize(p.count);
    for (std::uint32_t i = 0; i < p.count; ++i) {
        rows[i] = {a[i], b[i], c[i]};
    }
    return true;
}

void hashEmitter(const ParticleEmitter& e, Hasher& h) {
    const ParticlePool& p = e.pool;
    h.add(p.count);
    h.add(p.clock);
    for (const std::vector<float>* a : {&p.px, &p.py, &p.pz, &p.vx, &p.vy, &p.vz}) {
        h.bytes(a->data(), std::size_t(p.count) * sizeof(float));
    }
    for (const std::vector<std::uint32_t>* a : {&p.birthStep, &p.deathStep}) {
        h.bytes(a->data(), std::size_t(p.count) * sizeof(std::uint32_t));
    }
    h.add(e.seed);
    h.add(e.def.rate);
    h.add(e.rateSteps);
    h.add(e.rateCarry);
    h.add(e.rateBorn);
    h.add(e.pendingBurst);
    h.add(e.born);
    h.add(e.dropped);
}

bool hasEmitter(const World& w, Entity e) {
    return w.has<ParticleEmitter>(e);
}

/// Births owed by the rate so far in this rate segment: floor(carry + rate * simulated time), the time
/// counted in whole steps (no accumulated rounding), and a count within a relative 1e-9 of a whole number
/// taken as that number (so 100 a second for 2 s at dt = 0.01 gives 200, not 199).
std::uint64_t dueBirths(const ParticleEmitter& e, double dt) {
    const double owed = e.rateCarry + e.def.rate * (static_cast<double>(e.rateSteps) * dt);
    return static_cast<std::uint64_t>(std::floor(owed + 1e-9 * std::max(1.0, owed)));
}

/// The scene's fixed step, for events (which run outside the emitter system).
double ctxDt(World& w) {
    return w.resource<SceneDef>().dt;
}

/// The drag of an emitter that rides an air grid, exact over the step: with keep = e^(-drag dt), a
/// particle inside the air's box goes to u + (v - u) keep, u the air's velocity where it is; one outside
/// it to v keep (still air). The update then runs without drag of its own.
void applyAir(ParticlePool& p, const Air& air, float drag, float dt, WorkerPool& pool) {
    const float keep = std::exp(-drag * dt);
    pool.forEach(p.count, 4096, [&](std::size_t i) {
        const Vec3 x{p.px[i], p.py[i], p.pz[i]};
        Vec3 u;
        if (airContains(air, x)) {
            u = airVelocityAt(air, x);
        }
        p.vx[i] = float(u.x) + (p.vx[i] - float(u.x)) * keep;
        p.vy[i] = float(u.y) + (p.vy[i] - float(u.y)) * keep;
        p.vz[i] = float(u.z) + (p.vz[i] - float(u.z)) * keep;
    });
}

/// Velocity changes from the force fields, per particle (a 1 kg body).
void applyFields(ParticlePool& p, const std::vector<ForceField>& fields, float dt, WorkerPool& pool) {
    pool.forEach(p.count, 4096, [&](std::size_t i) {
        const Vec3 x{p.px[i], p.py[i], p.pz[i]};
        const Vec3 v{p.vx[i], p.vy[i], p.vz[i]};
        Vec3 a;
        for (const ForceField& f : fields) {
            a += fieldForce(f, x, v, 1.0);
        }
        p.vx[i] += float(a.x * dt);
        p.vy[i] += float(a.y * dt);
        p.vz[i] += float(a.z * dt);
    });
}

} // namespace

void reserveParticles(ParticlePool& p, std::uint32_t capacity) {
    for (std::vector<float>* a : {&p.px, &p.py, &p.pz, &p.vx, &p.vy, &p.vz}) {
        a->assign(capacity, 0.0f);
    }
    p.birthStep.assign(capacity, 0);
    p.deathStep.assign(capacity, 0);
    p.deadGroups.assign(capacity / 4 + 1, 0);
    const std::size_t chunks = std::max<std::size_t>(1, WorkerPool::chunkCount(capacity, kParticleGrain));
    p.deadCounts.assign(chunks, 0);
    p.deaths.assign(chunks, 0);
    // survivors past the new end: no more than the deaths, nor than what is left, so at most half
    p.fillers.assign(capacity / 2 + 1, 0);
}

namespace {

/// The updates a particle of this lifetime lives through: the first count of steps whose time reaches
/// it (a count within a relative 1e-9 of a whole number taken as that number, so 2 s at dt = 0.01 is 200
/// steps, not 201), at least one and at most kMaxLifeSteps (the loader refuses longer lives).
std::uint32_t lifeSteps(double life, double dt) {
    const double steps = life / dt;
    const double whole = std::ceil(steps - 1e-9 * std::max(1.0, steps));
    return static_cast<std::uint32_t>(std::clamp(whole, 1.0, double(kMaxLifeSteps)));
}

/// One birth: where on the emitter's shape, which way in its cone, how fast, how long it lives.
void bear(const ParticleEmitter& e, const Vec3& t1, const Vec3& t2, double cosSpread, double dt, Rng& rng,
          ParticlePool& p, std::uint32_t i) {
    const EmitterDef& d = e.def;
    Vec3 at = e.origin;
    double a = 0.0, b = 0.0;
    switch (d.shape) {
    case EmitterShape::Point:
        break;
    case EmitterShape::Sphere: {
        double c = 0.0;
        do {
            a = 2.0 * rng.uniform() - 1.0;
            b = 2.0 * rng.uniform() - 1.0;
            c = 2.0 * rng.uniform() - 1.0;
        } while (a * a + b * b + c * c > 1.0);
        at += Vec3{a, b, c} * d.radius;
        break;
    }
    case EmitterShape::Disc:
        unitDisc(rng, a, b);
        at += (t1 * a + t2 * b) * d.radius;
        break;
    case EmitterShape::Box:
        at +=
            Vec3{d.halfExtents.x * (2.0 * rng.uniform() - 1.0), d.halfExtents.y * (2.0 * rng.uniform() - 1.0),
                 d.halfExtents.z * (2.0 * rng.uniform() - 1.0)};
        break;
    }
    // which way: uniform over the spherical cap of the cone (cos theta uniform), azimuth from the disc
    const double z = 1.0 - rng.uniform() * (1.0 - cosSpread);
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    unitDisc(rng, a, b);
    const double s = std::sqrt(a * a + b * b);
    const double ca = s > 0.0 ? a / s : 1.0, sa = s > 0.0 ? b / s : 0.0;
    const Vec3 dir = t1 * (r * ca) + t2 * (r * sa) + d.direction * z;
    const double speed = rng.uniform(d.speed[0], d.speed[1]);
    const double life = rng.uniform(d.lifetime[0], d.lifetime[1]);
    p.px[i] = float(at.x);
    p.py[i] = float(at.y);
    p.pz[i] = float(at.z);
    p.vx[i] = float(dir.x * speed);
    p.vy[i] = float(dir.y * speed);
    p.vz[i] = float(dir.z * speed);
    p.birthStep[i] = p.clock;
    p.deathStep[i] = p.clock + lifeSteps(life, dt) - 1;
}

/// Births per chunk of the parallel births (each about 0.2 us).
constexpr std::size_t kBirthGrain = 1024;

} // namespace

void spawnParticles(ParticleEmitter& e, std::uint64_t n, double dt, WorkerPool& pool) {
    ParticlePool& p = e.pool;
    const auto room = static_cast<std::uint64_t>(p.px.size() - p.count);
    if (n > room) {
        e.dropped += n - room;
        n = room;
    }
    Vec3 t1, t2;
    basis(e.def.direction, t1, t2);
    const double cosSpread = std::cos(e.def.spreadDeg * std::numbers::pi / 180.0);
    const std::uint32_t first = p.count;
    pool.forEach(n, kBirthGrain, [&](std::size_t k) {
        Rng rng = birthStream(e.seed, e.born + k);
        bear(e, t1, t2, cosSpread, dt, rng, p, first + static_cast<std::uint32_t>(k));
    });
    p.count += static_cast<std::uint32_t>(n);
    e.born += n;
}

namespace {

/// Whether particle i dies in the pool's update now under way (number p.clock): its step of death has come,
/// compared as a 32-bit difference so that step numbers may wrap.
bool diesNow(const ParticlePool& p, std::uint32_t i) {
    return std::int32_t(p.deathStep[i] - p.clock) <= 0;
}

/// The update of advanceChunk eight particles at a time, for groups of eight in [begin, whole): the same
/// operations on each lane as the four-wide loop (so the same bits), and the groups of four with a death
/// listed as it lists them. Returns where it stopped (the last group of four, if any, is the caller's).
__attribute__((target("avx2"))) std::uint32_t advanceEights(ParticlePool& p, std::uint32_t begin,
                                                            std::uint32_t whole, const Vec3& gravity,
                                                            float keepScalar, float dt, std::uint32_t* dead,
                                                            std::uint32_t& listed, std::uint32_t& deaths) {
    const __m256i now = _mm256_set1_epi32(int(p.clock));
    const __m256 keep = _mm256_set1_ps(keepScalar);
    const __m256 gx = _mm256_set1_ps(float(gravity.x) * dt), gy = _mm256_set1_ps(float(gravity.y) * dt),
                 gz = _mm256_set1_ps(float(gravity.z) * dt);
    const __m256 step = _mm256_set1_ps(dt);
    std::uint32_t i = begin;
    for (; i + 8 <= whole; i += 8) {
        const __m256 vx = _mm256_add_ps(_mm256_mul_ps(_mm256_loadu_ps(&p.vx[i]), keep), gx);
        const __m256 vy = _mm256_add_ps(_mm256_mul_ps(_mm256_loadu_ps(&p.vy[i]), keep), gy);
        const __m256 vz = _mm256_add_ps(_mm256_mul_ps(_mm256_loadu_ps(&p.vz[i]), keep), gz);
        _mm256_storeu_ps(&p.vx[i], vx);
        _mm256_storeu_ps(&p.vy[i], vy);
        _mm256_storeu_ps(&p.vz[i], vz);
        _mm256_storeu_ps(&p.px[i], _mm256_add_ps(_mm256_loadu_ps(&p.px[i]), _mm256_mul_ps(vx, step)));
        _mm256_storeu_ps(&p.py[i], _mm256_add_ps(_mm256_loadu_ps(&p.py[i]), _mm256_mul_ps(vy, step)));
        _mm256_storeu_ps(&p.pz[i], _mm256_add_ps(_mm256_loadu_ps(&p.pz[i]), _mm256_mul_ps(vz, step)));
        // alive while deathStep - now > 0 as a 32-bit difference
        const __m256i left =
            _mm256_sub_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(&p.deathStep[i])), now);
        const int died =
            ~_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(left, _mm256_setzero_si256()))) & 0xff;
        if (died != 0) {
            deaths += std::uint32_t(__builtin_popcount(unsigned(died)));
            if (died & 0x0f) {
                dead[listed++] = i;
            }
            if (died & 0xf0) {
                dead[listed++] = i + 4;
            }
        }
    }
    return i;
}

/// The update of one chunk's particles: v' = v e^(-drag dt) + g dt, x' = x + v' dt, and those whose step
/// of death this is die; four particles per register. The drag factor is the exact decay over the step, so
/// any drag is stable (1 - drag dt would not be past 2/dt). Lists the first index of each group of four with
/// a death in `dead` (the group of the last few, past a multiple of four, too), in p.deadCounts[chunk] how
/// many it listed and in p.deaths[chunk] how many died.
void advanceChunk(ParticlePool& p, std::size_t chunk, std::uint32_t begin, std::uint32_t end,
                  const Vec3& gravity, float keepScalar, float dt, bool avx2) {
    std::uint32_t* dead = &p.deadGroups[begin / 4];
    const __m128i now = _mm_set1_epi32(int(p.clock));
    const __m128 keep = _mm_set1_ps(keepScalar);
    const __m128 gx = _mm_set1_ps(float(gravity.x) * dt), gy = _mm_set1_ps(float(gravity.y) * dt),
                 gz = _mm_set1_ps(float(gravity.z) * dt);
    const __m128 step = _mm_set1_ps(dt);
    std::uint32_t listed = 0, deaths = 0;
    const std::uint32_t whole = begin + ((end - begin) & ~3u);
    const std::uint32_t fours =
        avx2 ? advanceEights(p, begin, whole, gravity, keepScalar, dt, dead, listed, deaths) : begin;
    for (std::uint32_t i = fours; i < whole; i += 4) {
        const __m128 vx = _mm_add_ps(_mm_mul_ps(_mm_loadu_ps(&p.vx[i]), keep), gx);
        const __m128 vy = _mm_add_ps(_mm_mul_ps(_mm_loadu_ps(&p.vy[i]), keep), gy);
        const __m128 vz = _mm_add_ps(_mm_mul_ps(_mm_loadu_ps(&p.vz[i]), keep), gz);
        _mm_storeu_ps(&p.vx[i], vx);
        _mm_storeu_ps(&p.vy[i], vy);
        _mm_storeu_ps(&p.vz[i], vz);
        _mm_storeu_ps(&p.px[i], _mm_add_ps(_mm_loadu_ps(&p.px[i]), _mm_mul_ps(vx, step)));
        _mm_storeu_ps(&p.py[i], _mm_add_ps(_mm_loadu_ps(&p.py[i]), _mm_mul_ps(vy, step)));
        _mm_storeu_ps(&p.pz[i], _mm_add_ps(_mm_loadu_ps(&p.pz[i]), _mm_mul_ps(vz, step)));
        const __m128i left =
            _mm_sub_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(&p.deathStep[i])), now);
        const int died = ~_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(left, _mm_setzero_si128()))) & 0xf;
        if (died != 0) {
            deaths += std::uint32_t(__builtin_popcount(unsigned(died)));
            dead[listed++] = i;
        }
    }
    // the last few (only in the last chunk), one at a time, with exactly the same arithmetic
    const std::uint32_t before = deaths;
    for (std::uint32_t i = whole; i < end; ++i) {
        p.vx[i] = p.vx[i] * keepScalar + float(gravity.x) * dt;
        p.vy[i] = p.vy[i] * keepScalar + float(gravity.y) * dt;
        p.vz[i] = p.vz[i] * keepScalar + float(gravity.z) * dt;
        p.px[i] += p.vx[i] * dt;
        p.py[i] += p.vy[i] * dt;
        p.pz[i] += p.vz[i] * dt;
        deaths += diesNow(p, i) ? 1u : 0u;
    }
    if (deaths != before) {
        dead[listed++] = whole;
    }
    p.deadCounts[chunk] = listed;
    p.deaths[chunk] = deaths;
}

/// Fills the holes one chunk's dead leave below the new end with the survivors past it (p.fillers), the
/// chunk's first death taking filler `rank`: the k-th hole of the pool, counted from index 0, takes the
/// k-th survivor past the new end.
void fillHoles(ParticlePool& p, std::size_t chunk, std::uint32_t newCount, std::uint32_t rank) {
    const std::uint32_t* dead = &p.deadGroups[chunk * (kParticleGrain / 4)];
    for (std::uint32_t g = 0; g < p.deadCounts[chunk]; ++g) {
        for (std::uint32_t i = dead[g]; i < std::min(dead[g] + 4, p.count); ++i) {
            if (!diesNow(p, i)) {
                continue;
            }
            if (i >= newCount) {
                return; // this death and those after it are past the new end
            }
            const std::uint32_t from = p.fillers[rank++];
            for (std::vector<float>* a : {&p.px, &p.py, &p.pz, &p.vx, &p.vy, &p.vz}) {
                (*a)[i] = (*a)[from];
            }
            p.birthStep[i] = p.birthStep[from];
            p.deathStep[i] = p.deathStep[from];
        }
    }
}

} // namespace

std::uint32_t advanceParticles(ParticlePool& p, const Vec3& gravity, float drag, float dt, WorkerPool& pool) {
    const float keep = std::exp(-drag * dt);
    const bool avx2 = activeSimd() == Simd::Avx2;
    // every chunk lists its groups with a death in its own stretch of deadGroups (a group's slot is its
    // first index / 4), so no chunk waits on another
    const std::size_t chunks = WorkerPool::chunkCount(p.count, kParticleGrain);
    pool.forChunks(p.count, kParticleGrain, [&](std::size_t c, std::size_t b, std::size_t e) {
        advanceChunk(p, c, std::uint32_t(b), std::uint32_t(e), gravity, keep, dt, avx2);
    });
    // the dead leave holes; the survivors past the new end fill them, the k-th hole from the start taking
    // the k-th such survivor, each chunk its own holes: the same order at any thread count
    std::uint32_t died = 0;
    for (std::size_t c = 0; c < chunks; ++c) {
        const std::uint32_t d = p.deaths[c];
        p.deaths[c] = died; // from here on: the rank of the chunk's first death
        died += d;
    }
    if (died == 0) {
        ++p.clock;
        return 0;
    }
    const std::uint32_t newCount = p.count - died;
    std::uint32_t fillers = 0;
    for (std::uint32_t i = newCount; i < p.count; ++i) {
        if (!diesNow(p, i)) {
            p.fillers[fillers++] = i;
        }
    }
    pool.forChunks(newCount, kParticleGrain,
                   [&](std::size_t c, std::size_t, std::size_t) { fillHoles(p, c, newCount, p.deaths[c]); });
    p.count = newCount;
    ++p.clock;
    return died;
}

void emitParticles(World& world, const StepContext& ctx) {
    world.view<ParticleEmitter, const Transform>().each([&](Entity, ParticleEmitter& e, const Transform& t) {
        e.origin = t.position;
        std::uint64_t births = e.pendingBurst;
        e.pendingBurst = 0;
        if (e.def.rate > 0.0) {
            // count births, do not accumulate fractions: floor(rate * time) in all, exactly
            ++e.rateSteps;
            const std::uint64_t due = dueBirths(e, ctx.dt);
            births += due - e.rateBorn;
            e.rateBorn = due;
        }
        spawnParticles(e, births, ctx.dt, poolOr(ctx.pool));
    });
}

void updateParticles(World& world, const StepContext& ctx) {
    const auto& g = world.resource<SceneDef>().gravity;
    const Vec3 gravity{g[0], g[1], g[2]};
    const Pool<ForceField>* fields = world.findPool<ForceField>();
    const float dt = static_cast<float>(ctx.dt);
    WorkerPool& pool = poolOr(ctx.pool);
    world.view<ParticleEmitter>().each([&](Entity, ParticleEmitter& e) {
        if (fields && fields->size() > 0) {
            applyFields(e.pool, fields->values(), dt, pool);
        }
        const bool rides = e.air != kNullEntity && e.def.drag > 0.0;
        if (rides) {
            applyAir(e.pool, world.get<Air>(e.air), static_cast<float>(e.def.drag), dt, pool);
        }
        advanceParticles(e.pool, gravity, rides ? 0.0f : static_cast<float>(e.def.drag), dt, pool);
    });
}

namespace {

/// The fraction of a birth owed at the old rate carries over to the new one.
void setRate(ParticleEmitter& em, double rate, double dt) {
    em.rateCarry = em.rateCarry + em.def.rate * (double(em.rateSteps) * dt) - double(em.rateBorn);
    em.def.rate = rate;
    em.rateSteps = 0;
    em.rateBorn = 0;
}

/// A `set` event on an emitter's keys (engine/retune.h): every setting but the size of its pool.
Retune emitterRetune() {
    auto check = [](const World& bw, Entity b, const World& aw, Entity a) -> std::optional<std::string> {
        if (bw.get<ParticleEmitter>(b).def.maxParticles != aw.get<ParticleEmitter>(a).def.maxParticles) {
            return std::string(
                "emitter.max_particles cannot change during a run (the pool is reserved at load)");
        }
        if (bw.get<ParticleEmitter>(b).def.airName != aw.get<ParticleEmitter>(a).def.airName) {
            return std::string("emitter.air cannot change during a run");
        }
        return std::nullopt;
    };
    auto patch = [](World& w, Entity e, const World& bw, Entity b, const World& aw, Entity a) {
        ParticleEmitter& live = w.get<ParticleEmitter>(e);
        const EmitterDef &was = bw.get<ParticleEmitter>(b).def, &now = aw.get<ParticleEmitter>(a).def;
        EmitterDef& d = live.def;
        takeChanged(d.shape, was.shape, now.shape);
        takeChanged(d.radius, was.radius, now.radius);
        takeChanged(d.halfExtents, was.halfExtents, now.halfExtents);
        takeChanged(d.direction, was.direction, now.direction);
        takeChanged(d.spreadDeg, was.spreadDeg, now.spreadDeg);
        takeChanged(d.burst, was.burst, now.burst);
        takeChanged(d.lifetime, was.lifetime, now.lifetime);
        takeChanged(d.speed, was.speed, now.speed);
        takeChanged(d.drag, was.drag, now.drag);
        takeChanged(d.collide, was.collide, now.collide);
        takeChanged(d.restitution, was.restitution, now.restitution);
        takeChanged(d.friction, was.friction, now.friction);
        takeChanged(d.colorStart, was.colorStart, now.colorStart);
        takeChanged(d.colorEnd, was.colorEnd, now.colorEnd);
        takeChanged(d.size, was.size, now.size);
        if (was.rate != now.rate) {
            setRate(live, now.rate, ctxDt(w));
        }
    };
    return Retune{{"emitter"}, hasEmitter, check, patch};
}

} // namespace

namespace {

/// An emitter's `air`: the named entity must have an air grid.
void linkEmitter(TableReader& r, World& world, Entity entity, const EntityLookup& lookup) {
    ParticleEmitter& e = world.get<ParticleEmitter>(entity);
    if (e.def.airName.empty()) {
        return;
    }
    const Entity air = lookup(r, "air", true);
    if (!world.has<Air>(air)) {
        r.fail("air", "entity '" + e.def.airName + "' has no [entity.air] for these particles to ride");
    }
    e.air = air;
}

} // namespace

void registerParticleSystem(Catalog& catalog) {
    catalog.addComponent({"emitter", loadEmitter, linkEmitter});
    catalog.addState<ParticleEmitter>("particles", dumpEmitter, hashEmitter, emitterRows);
    catalog.addRetune(emitterRetune());
    // burst: value = [count], or the emitter's own burst size
    catalog.addEventAction({"burst",
                            "a particle emitter",
                            {"value"},
                            hasEmitter,
                            [](const World&, Entity, const EventDef& ev) -> std::optional<std::string> {
                                if (ev.value.size() > 1 || (ev.value.size() == 1 &&
                                                            (ev.value[0] < 0 || ev.value[0] > kMaxParticles ||
                                                             ev.value[0] != std::floor(ev.value[0])))) {
                                    return "takes value = [count], a whole number of particles (or no value: "
                                           "the emitter's burst)";
                                }
                                return std::nullopt;
                            },
                            [](World& w, Entity e, const EventDef& ev) {
                                auto& em = w.get<ParticleEmitter>(e);
                                em.pendingBurst +=
                                    ev.value.empty() ? em.def.burst : static_cast<std::uint64_t>(ev.value[0]);
                            }});
    // impulse: every live particle's velocity changes by value (each is a 1 kg body)
    catalog.addEventAction({"impulse",
                            "a particle emitter",
                            {"value"},
                            hasEmitter,
                            [](const World&, Entity, const EventDef& ev) -> std::optional<std::string> {
                                if (ev.value.size() != 3) {
                                    return "needs value = [x, y, z]";
                                }
                                return std::nullopt;
                            },
                            [](World& w, Entity e, const EventDef& ev) {
                                ParticlePool& p = w.get<ParticleEmitter>(e).pool;
                                for (std::uint32_t i = 0; i < p.count; ++i) {
                                    p.vx[i] += float(ev.value[0]);
                                    p.vy[i] += float(ev.value[1]);
                                    p.vz[i] += float(ev.value[2]);
                                }
                            }});
    // set_rate: value = [particles per second], from this step on
    catalog.addEventAction({"set_rate",
                            "a particle emitter",
                            {"value"},
                            hasEmitter,
                            [](const World&, Entity, const EventDef& ev) -> std::optional<std::string> {
                                if (ev.value.size() != 1 || ev.value[0] < 0 || ev.value[0] > 1e8) {
                                    return "needs value = [particles per second], in [0, 1e8]";
                                }
                                return std::nullopt;
                            },
                            [](World& w, Entity e, const EventDef& ev) {
                                setRate(w.get<ParticleEmitter>(e), ev.value[0], ctxDt(w));
                            }});
}

} // namespace tumble
