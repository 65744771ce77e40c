#include "systems/spring_forces.h"

#include "engine/parallel.h"
#include "systems/block_sparse.h"
#include "systems/field_forces.h"

#include <cmath>

namespace tumble {

void externalForces(const SpringNetwork& net, const Environment& env, const std::vector<Vec3>& x,
                    const std::vector<Vec3>& v, std::vector<Vec3>& f) {
    const std::size_t n = x.size();
    f.resize(n);
    // per mass: gravity, drag, fields (wind on cloth goes through the triangles below)
    const bool surfaceWind = net.kind == NetworkKind::Cloth && !net.triangles.empty();
    bool pointFields = false; // any field that acts on each mass (wind on cloth acts on its triangles)
    if (env.fields) {
        for (const ForceField& field : *env.fields) {
            pointFields = pointFields || !(surfaceWind && field.kind == FieldKind::Wind);
        }
    }
    poolOr(env.pool).forEach(n, 2048, [&](std::size_t i) {
        const double m = 1.0 / net.invMass[i];
        Vec3 fi = env.gravity * m - v[i] * net.drag;
        if (pointFields) {
            for (const ForceField& field : *env.fields) {
                if (!(surfaceWind && field.kind == FieldKind::Wind)) {
                    fi += fieldForce(field, x[i], v[i], m);
                }
            }
        }
        f[i] = fi;
    });
    // wind on cloth: per triangle, along its normal, shared by its corners
    if (surfaceWind && env.fields) {
        for (const ForceField& field : *env.fields) {
            if (field.kind != FieldKind::Wind) {
                continue;
            }
            // with A the area-weighted normal (|A| = area), area ((w - v) . n) n = ((w - v) . A) A / |A|
            const double perCorner = field.coefficient / 3.0;
            for (const auto& t : net.triangles) {
                const Vec3 areaNormal = cross(x[t[1]] - x[t[0]], x[t[2]] - x[t[0]]) * 0.5;
                const double area = length(areaNormal);
                if (area <= 1e-15) {
                    continue;
                }
                const Vec3 relative = field.current - (v[t[0]] + v[t[1]] + v[t[2]]) * (1.0 / 3.0);
                const Vec3 ft = areaNormal * (perCorner * dot(relative, areaNormal) / area);
                f[t[0]] += ft;
                f[t[1]] += ft;
                f[t[2]] += ft;
            }
        }
    }
}

void springForces(const SpringNetwork& net, const Environment& env, const std::vector<Vec3>& x,
                  const std::vector<Vec3>& v, std::vector<Vec3>& f) {
    externalForces(net, env, x, v, f);
    for (const SpringLink& s : net.links) {
        const Vec3 d = x[s.b] - x[s.a];
        const double len = length(d);
        if (len <= 1e-12) {
            continue; // coincident masses: no direction to push along
        }
        const Vec3 u = d * (1.0 / len);
        const Vec3 fa = u * (s.k * (len - s.rest) + s.kd * dot(v[s.b] - v[s.a], u));
        f[s.a] += fa;
        f[s.b] -= fa;
    }
}

bool springStiffness(const SpringLink& s, const Vec3& xa, const Vec3& xb, Mat3& k, Vec3& u, double& len) {
    const Vec3 d = xb - xa;
    len = length(d);
    if (len <= 1e-12) {
        return false;
    }
    u = d * (1.0 / len);
    const double transverse = std::max(0.0, 1.0 - s.rest / len);
    // k [ (1 - t) u u^T + t I ]
    k = Mat3::outer(u, s.k * (1.0 - transverse));
    k.m[0] += s.k * transverse;
    k.m[4] += s.k * transverse;
    k.m[8] += s.k * transverse;
    return true;
}

double massDamping(const SpringNetwork& net, const Environment& env, const Vec3& x) {
    double c = net.drag;
    if (env.fields) {
        const bool surfaceWind = net.kind == NetworkKind::Cloth && !net.triangles.empty();
        for (const ForceField& field : *env.fields) {
            if (!(surfaceWind && field.kind == FieldKind::Wind)) {
                c += fieldDamping(field, x);
            }
        }
    }
    return c;
}

} // namespace tumble
