#include "systems/spring_forces.h"

#include "engine/parallel.h"
#include "systems/air_solver.h"
#include "systems/block_sparse.h"
#include "systems/field_forces.h"

#include <cmath>

namespace tumble {

namespace {

/// Lists in compressed-row form: list `of[k]` gets entry `entry(k)`, in k order.
template <class Of, class Entry>
void buildLists(std::size_t lists, std::size_t items, std::size_t perItem, Of&& of, Entry&& entry,
                std::vector<std::uint32_t>& start, std::vector<std::uint32_t>& out) {
    start.assign(lists + 1, 0);
    for (std::size_t k = 0; k < items * perItem; ++k) {
        ++start[of(k) + 1];
    }
    for (std::size_t l = 0; l < lists; ++l) {
        start[l + 1] += start[l];
    }
    out.resize(items * perItem);
    std::vector<std::uint32_t> next(start.begin(), start.end() - 1);
    for (std::size_t k = 0; k < items * perItem; ++k) {
        out[next[of(k)]++] = entry(k);
    }
}

/// Whether a loop over `items` shares out: computed per item and gathered per mass, which gives exactly
/// the bits of the plain scatter and pays only when it runs on several threads.
bool shareOut(const WorkerPool& pool, std::size_t items, std::size_t grain) {
    return pool.threads() > 1 && items > grain;
}

/// Moving air acting on cloth and masses: a wind field (the same everywhere) or an air grid (its velocity
/// where asked, inside its box).
struct MovingAir {
    const ForceField* field = nullptr;
    const Air* air = nullptr;
    double coefficient = 0.0; ///< N s/m per mass, N s/m^3 per area on cloth

    /// The air's velocity at a point; false where this air is not.
    bool at(const Vec3& p, Vec3& velocity) const {
        if (field != nullptr) {
            velocity = field->current;
            return true;
        }
        if (!airContains(*air, p)) {
            return false;
        }
        velocity = airVelocityAt(*air, p);
        return true;
    }
};

/// Calls fn for each moving air that acts on a network through its triangles (a cloth's) or on each mass:
/// the wind fields first, in the scene's order, then the air grids (no list is built: this runs at every
/// force evaluation).
template <class F>
void forEachMovingAir(const Environment& env, F&& fn) {
    if (env.fields) {
        for (const ForceField& field : *env.fields) {
            if (field.kind == FieldKind::Wind) {
                fn(MovingAir{&field, nullptr, field.coefficient});
            }
        }
    }
    if (env.air) {
        for (const Air* air : *env.air) {
            fn(MovingAir{nullptr, air, air->coefficient});
        }
    }
}

bool surfaceWind(const SpringNetwork& net) {
    return net.kind == NetworkKind::Cloth && !net.triangles.empty();
}

} // namespace

void ForceIncidence::update(const SpringNetwork& net) {
    const std::size_t n = net.x.size();
    if (linkStart.size() == n + 1 && links.size() == 2 * net.links.size() &&
        triangles.size() == 3 * net.triangles.size()) {
        return;
    }
    buildLists(
        n, net.links.size(), 2,
        [&](std::size_t k) { return k % 2 == 0 ? net.links[k / 2].a : net.links[k / 2].b; },
        [](std::size_t k) { return std::uint32_t(k); }, linkStart, links);
    buildLists(
        n, net.triangles.size(), 3, [&](std::size_t k) { return net.triangles[k / 3][k % 3]; },
        [](std::size_t k) { return std::uint32_t(k / 3); }, triangleStart, triangles);
    perLink.resize(net.links.size());
    linkActive.resize(net.links.size());
    perTriangle.resize(net.triangles.size());
    perTriangleBlock.resize(net.triangles.size());
    triangleActive.resize(net.triangles.size());
}

void externalForces(const SpringNetwork& net, const Environment& env, const std::vector<Vec3>& x,
                    const std::vector<Vec3>& v, std::vector<Vec3>& f, ForceIncidence& inc) {
    const std::size_t n = x.size();
    f.resize(n);
    inc.update(net);
    WorkerPool& pool = poolOr(env.pool);
    // per mass: gravity, drag, fields and air grids (wind and air on cloth go through the triangles below)
    const bool surface = surfaceWind(net);
    bool pointFields = false; // any field that acts on each mass
    if (env.fields) {
        for (const ForceField& field : *env.fields) {
            pointFields = pointFields || !(surface && field.kind == FieldKind::Wind);
        }
    }
    const bool pointAir = !surface && env.air && !env.air->empty();
    pool.forEach(n, kMassGrain, [&](std::size_t i) {
        const double m = 1.0 / net.invMass[i];
        Vec3 fi = env.gravity * m - v[i] * net.drag;
        if (!net.waterForce.empty()) {
            fi += net.waterForce[i];
        }
        if (pointFields) {
            for (const ForceField& field : *env.fields) {
                if (!(surface && field.kind == FieldKind::Wind)) {
                    fi += fieldForce(field, x[i], v[i], m);
                }
            }
        }
        if (pointAir) {
            for (const Air* air : *env.air) {
                if (airContains(*air, x[i])) {
                    fi += (airVelocityAt(*air, x[i]) - v[i]) * air->coefficient;
                }
            }
        }
        f[i] = fi;
    });
    if (!surface) {
        return;
    }
    // wind on cloth: per triangle, along its normal, shared by its corners
    const bool gather = shareOut(pool, net.triangles.size(), kTriangleGrain);
    forEachMovingAir(env, [&](const MovingAir& wind) {
        // with A the area-weighted normal (|A| = area), area ((w - v) . n) n = ((w - v) . A) A / |A|
        const double perCorner = wind.coefficient / 3.0;
        auto windOn = [&](std::size_t k, Vec3& ft) {
            const auto& t = net.triangles[k];
            const Vec3 areaNormal = cross(x[t[1]] - x[t[0]], x[t[2]] - x[t[0]]) * 0.5;
            const double area = length(areaNormal);
            Vec3 air;
            if (area <= 1e-15 || !wind.at((x[t[0]] + x[t[1]] + x[t[2]]) * (1.0 / 3.0), air)) {
                return false;
            }
            const Vec3 relative = air - (v[t[0]] + v[t[1]] + v[t[2]]) * (1.0 / 3.0);
            ft = areaNormal * (perCorner * dot(relative, areaNormal) / area);
            return true;
        };
        if (!gather) {
            Vec3 ft;
            for (std::size_t k = 0; k < net.triangles.size(); ++k) {
                if (windOn(k, ft)) {
                    for (std::uint32_t corner : net.triangles[k]) {
                        f[corner] += ft;
                    }
                }
            }
            return;
        }
        pool.forEach(net.triangles.size(), kTriangleGrain,
                     [&](std::size_t k) { inc.triangleActive[k] = windOn(k, inc.perTriangle[k]); });
        pool.forEach(n, kMassGrain, [&](std::size_t i) {
            for (std::uint32_t e = inc.triangleStart[i]; e < inc.triangleStart[i + 1]; ++e) {
                if (inc.triangleActive[inc.triangles[e]]) {
                    f[i] += inc.perTriangle[inc.triangles[e]];
                }
            }
        });
    });
}

void springForces(const SpringNetwork& net, const Environment& env, const std::vector<Vec3>& x,
                  const std::vector<Vec3>& v, std::vector<Vec3>& f, ForceIncidence& inc) {
    externalForces(net, env, x, v, f, inc);
    WorkerPool& pool = poolOr(env.pool);
    auto linkForce = [&](std::size_t k, Vec3& fa) {
        const SpringLink& s = net.links[k];
        const Vec3 d = x[s.b] - x[s.a];
        const double len = length(d);
        if (len <= 1e-12) {
            return false; // coincident masses: no direction to push along
        }
        const Vec3 u = d * (1.0 / len);
        fa = u * (s.k * (len - s.rest) + s.kd * dot(v[s.b] - v[s.a], u));
        return true;
    };
    if (!shareOut(pool, net.links.size(), kLinkGrain)) {
        Vec3 fa;
        for (std::size_t k = 0; k < net.links.size(); ++k) {
            if (linkForce(k, fa)) {
                f[net.links[k].a] += fa;
                f[net.links[k].b] -= fa;
            }
        }
        return;
    }
    pool.forEach(net.links.size(), kLinkGrain,
                 [&](std::size_t k) { inc.linkActive[k] = linkForce(k, inc.perLink[k]); });
    // each mass its links' forces in link order: + on a link's a, - on its b
    pool.forEach(x.size(), kMassGrain, [&](std::size_t i) {
        for (std::uint32_t e = inc.linkStart[i]; e < inc.linkStart[i + 1]; ++e) {
            const std::uint32_t k = inc.links[e] / 2;
            if (!inc.linkActive[k]) {
                continue;
            }
            if (inc.links[e] % 2 == 0) {
                f[i] += inc.perLink[k];
            } else {
                f[i] -= inc.perLink[k];
            }
        }
    });
}

void springForces(const SpringNetwork& net, const Environment& env, const std::vector<Vec3>& x,
                  const std::vector<Vec3>& v, std::vector<Vec3>& f) {
    ForceIncidence incidence;
    springForces(net, env, x, v, f, incidence);
}

void addWindDamping(const SpringNetwork& net, const Environment& env, double h, ForceIncidence& inc,
                    std::vector<Mat3>& diagonal) {
    if (net.kind != NetworkKind::Cloth) {
        return;
    }
    inc.update(net);
    WorkerPool& pool = poolOr(env.pool);
    const bool gather = shareOut(pool, net.triangles.size(), kTriangleGrain);
    forEachMovingAir(env, [&](const MovingAir& wind) {
        if (wind.coefficient == 0.0) {
            return;
        }
        auto blockOf = [&](std::size_t k, Mat3& block) {
            const auto& t = net.triangles[k];
            const Vec3 areaNormal = cross(net.x[t[1]] - net.x[t[0]], net.x[t[2]] - net.x[t[0]]) * 0.5;
            const double area = length(areaNormal);
            Vec3 air;
            if (area <= 1e-15 || !wind.at((net.x[t[0]] + net.x[t[1]] + net.x[t[2]]) * (1.0 / 3.0), air)) {
                return false;
            }
            // c A/3 n n^T = c/3 (A n)(A n)^T / A
            block = Mat3::outer(areaNormal, h * wind.coefficient / (3.0 * area));
            return true;
        };
        if (!gather) {
            Mat3 block;
            for (std::size_t k = 0; k < net.triangles.size(); ++k) {
                if (blockOf(k, block)) {
                    for (std::uint32_t corner : net.triangles[k]) {
                        diagonal[corner] += block;
                    }
                }
            }
            return;
        }
        pool.forEach(net.triangles.size(), kTriangleGrain,
                     [&](std::size_t k) { inc.triangleActive[k] = blockOf(k, inc.perTriangleBlock[k]); });
        pool.forEach(net.x.size(), kMassGrain, [&](std::size_t i) {
            for (std::uint32_t e = inc.triangleStart[i]; e < inc.triangleStart[i + 1]; ++e) {
                if (inc.triangleActive[inc.triangles[e]]) {
                    diagonal[i] += inc.perTriangleBlock[inc.triangles[e]];
                }
            }
        });
    });
}

bool springStiffness(const SpringLink& s, const Vec3& xa, const Vec3& xb, Mat3& k, Vec3& u, double& len) {
    double transverse = 0.0;
    if (!springAxis(s, xa, xb, u, len, transverse)) {
        return false;
    }
    // k [ (1 - t) u u^T + t I ]
    k = Mat3::outer(u, s.k * (1.0 - transverse));
    k.m[0] += s.k * transverse;
    k.m[4] += s.k * transverse;
    k.m[8] += s.k * transverse;
    return true;
}

double massDamping(const SpringNetwork& net, const Environment& env, const Vec3& x) {
    double c = net.drag;
    const bool surface = surfaceWind(net);
    if (env.fields) {
        for (const ForceField& field : *env.fields) {
            if (!(surface && field.kind == FieldKind::Wind)) {
                c += fieldDamping(field, x);
            }
        }
    }
    if (env.air && !surface) {
        for (const Air* air : *env.air) {
            if (airContains(*air, x)) {
                c += air->coefficient;
            }
        }
    }
    return c;
}

} // namespace tumble
