// The implicit Euler system against finite differences of the forces, and the assembly's corner cases:
// duplicate links, a free stiff body in float, wind on a triangle of known area.

#include "components/force_field.h"
#include "engine/parallel.h"
#include "engine/random.h"
#include "systems/spring_builders.h"
#include "systems/spring_forces.h"
#include "systems/spring_integrators.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace tumble {
namespace {

/// A small cloth, crumpled at random, stretched along x and squeezed along y, so that its springs point in
/// different 3D directions, some longer and some shorter than their rest length; damped, and moving.
SpringNetwork crumpledCloth() {
    ClothDef def;
    def.rows = 4;
    def.cols = 4;
    def.damping = 0.4;
    SpringNetwork net = buildCloth(def);
    Rng rng(3);
    for (Vec3& x : net.x) {
        x = Vec3{x.x * 1.3, x.y * 0.8, x.z} +
            Vec3{rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05)};
    }
    for (Vec3& v : net.v) {
        v = {rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
    }
    net.integrator = Integrator::ImplicitEuler;
    net.doublePrecisionSolve = true;
    net.drag = 0.3;
    return net;
}

TEST(SpringJacobian, AssembledSystemMatchesFiniteDifferencesOfTheForces) {
    const SpringNetwork before = crumpledCloth();
    int stretched = 0, compressed = 0;
    for (const SpringLink& s : before.links) {
        (length(before.x[s.b] - before.x[s.a]) > s.rest ? stretched : compressed) += 1;
        ASSERT_GT(s.kd, 0.0) << "the test wants damped springs";
    }
    ASSERT_GT(stretched, 5);
    ASSERT_GT(compressed, 5);
    const Environment env{{0.0, -9.81, 0.0}, nullptr};
    const double h = 0.01;
    SpringNetwork net = before;
    SpringWorkspace work;
    stepNetwork(net, work, env, h); // assembles A at the state before the step
    const BlockMatrix<double>& a = work.precise.system;

    // A = M - h dF/dv - h^2 dF/dx, column by column from central differences; except that for a compressed
    // spring the assembly drops the transverse stiffness T = k (1 - R/l) (I - u u^T), which is negative
    // (Choi & Ko 2002): h^2 T is taken out of the differences here, on the blocks of its two masses (+ on
    // the diagonal blocks, - on the two others, as the differences have it)
    const std::size_t n = before.x.size();
    std::vector<std::vector<Mat3>> dropped(n, std::vector<Mat3>(n));
    for (const SpringLink& s : before.links) {
        const Vec3 d = before.x[s.b] - before.x[s.a];
        const double l = length(d);
        if (l >= s.rest) {
            continue;
        }
        const Vec3 u = d * (1.0 / l);
        Mat3 t;
        const double c[3] = {u.x, u.y, u.z};
        for (std::size_t r = 0; r < 3; ++r) {
            for (std::size_t q = 0; q < 3; ++q) {
                t.m[3 * r + q] = h * h * s.k * (1.0 - s.rest / l) * ((r == q ? 1.0 : 0.0) - c[r] * c[q]);
            }
        }
        dropped[s.a][s.a] += t;
        dropped[s.b][s.b] += t;
        dropped[s.a][s.b] -= t;
        dropped[s.b][s.a] -= t;
    }
    const double eps = 1e-6;
    std::vector<Vec3> fp, fm;
    const std::vector<Vec3> still(n);
    double worst = 0.0, scale = 0.0;
    for (std::size_t j = 0; j < n; ++j) {
        for (int c = 0; c < 3; ++c) {
            auto component = [c](Vec3& v) -> double& { return c == 0 ? v.x : c == 1 ? v.y : v.z; };
            SpringNetwork px = before, mx = before, pv = before, mv = before;
            component(px.x[j]) += eps;
            component(mx.x[j]) -= eps;
            component(pv.v[j]) += eps;
            component(mv.v[j]) -= eps;
            std::vector<Vec3> dfdx(n), dfdv(n);
            // dF/dx at rest: the damping force's change with position is left out of the system (Baraff &
            // Witkin: it is not symmetric), its change with velocity is in
            springForces(px, env, px.x, still, fp);
            springForces(mx, env, mx.x, still, fm);
            for (std::size_t i = 0; i < n; ++i) {
                dfdx[i] = (fp[i] - fm[i]) * (0.5 / eps);
            }
            springForces(pv, env, pv.x, pv.v, fp);
            springForces(mv, env, mv.x, mv.v, fm);
            for (std::size_t i = 0; i < n; ++i) {
                dfdv[i] = (fp[i] - fm[i]) * (0.5 / eps);
            }
            for (std::size_t i = 0; i < n; ++i) {
                Vec3 expected = (dfdv[i] * -h) - dfdx[i] * (h * h);
                if (i == j) {
                    component(expected) += 1.0 / before.invMass[i];
                }
                const Mat3& t = dropped[i][j];
                expected -= Vec3{t.m[std::size_t(c)], t.m[std::size_t(3 + c)], t.m[std::size_t(6 + c)]};
                // the stored block (i, j), column c; absent blocks are zero
                Vec3 got;
                const auto first = a.col.begin() + a.rowStart[i], last = a.col.begin() + a.rowStart[i + 1];
                const auto it = std::lower_bound(first, last, static_cast<std::uint32_t>(j));
                if (it != last && *it == j) {
                    const Mat3& block = a.val[std::size_t(it - a.col.begin())];
                    got = {block.m[std::size_t(c)], block.m[std::size_t(3 + c)], block.m[std::size_t(6 + c)]};
                }
                worst = std::max(worst, length(got - expected));
                scale = std::max(scale, length(expected));
            }
        }
    }
    EXPECT_LT(worst, 1e-6 * scale) << "largest entry " << scale;
}

TEST(SpringJacobian, DuplicateLinksAddUp) {
    const Environment env{{0.0, 0.0, 0.0}, nullptr};
    auto pair = [](std::vector<SpringLink> links) {
        SpringNetwork net;
        net.x = {{0, 0, 0}, {1.5, 0, 0}};
        net.v = {{0, 0, 0}, {0, 0, 0}};
        net.invMass = {1.0, 1.0};
        net.pinned = {1, 0};
        net.links = std::move(links);
        net.integrator = Integrator::ImplicitEuler;
        net.doublePrecisionSolve = true;
        net.cgTolerance = 1e-12;
        return net;
    };
    SpringNetwork twice = pair({{0, 1, 1.0, 1000.0, 0.0}, {1, 0, 1.0, 1000.0, 0.0}});
    SpringNetwork once = pair({{0, 1, 1.0, 2000.0, 0.0}});
    SpringWorkspace w1, w2;
    stepNetwork(twice, w1, env, 1.0 / 60.0);
    stepNetwork(once, w2, env, 1.0 / 60.0);
    EXPECT_NEAR(twice.v[1].x, once.v[1].x, 1e-9 * std::abs(once.v[1].x));
}

TEST(SpringJacobian, StiffFreeBodySolvesInFloat) {
    // no pins: the springs' terms cancel in every coarse sum and only the masses are left of the diagonal
    SoftBodyDef def;
    def.resolution = {10, 10, 10};
    def.mass = 2.0;
    def.stiffness = 1e7;
    def.shear = 1e7;
    def.bend = 1e6;
    SpringNetwork net = buildSoftBody(def);
    net.integrator = Integrator::ImplicitEuler;
    net.x[0] += Vec3{0.05, 0.0, 0.0}; // something to push against
    SpringWorkspace work;
    const Environment env{{0.0, -9.81, 0.0}, nullptr};
    for (int i = 0; i < 10; ++i) {
        ASSERT_NO_THROW(stepNetwork(net, work, env, 1.0 / 60.0));
    }
    for (const Vec3& x : net.x) {
        ASSERT_TRUE(isFinite(x));
    }
}

// The share of a spring's stiffness that acts across it, max(0, 1 - rest / len), taken without a branch:
// the same bits as std::max(0.0, .) for stretched springs, springs at their rest length and compressed
// ones, and +0 where 1 - rest / len is NaN (a NaN rest length: the one input where maxsd's operands, the
// other way round, would differ; 1 - rest / len is never -0 in round-to-nearest).
TEST(SpringForces, TheTransverseShareIsStdMaxToTheBit) {
    auto bits = [](double v) {
        std::uint64_t b = 0;
        std::memcpy(&b, &v, sizeof b);
        return b;
    };
    const Vec3 a{0.25, -1.0, 2.0};
    for (double rest : {0.0, 0.5, 1.0, 1.5, 3.0, 1e300, std::nan("")}) {
        for (double len : {1e-6, 0.75, 1.0, 2.0, 1e6}) {
            SpringLink s;
            s.rest = rest;
            Vec3 u;
            double got = 0.0, gotLen = 0.0;
            ASSERT_TRUE(springAxis(s, a, a + Vec3{0.0, 0.0, len}, u, gotLen, got));
            const double want = std::max(0.0, 1.0 - s.rest / gotLen);
            EXPECT_EQ(bits(got), bits(want)) << "rest " << rest << ", length " << len;
        }
    }
    // at its rest length exactly: +0
    SpringLink s;
    s.rest = 2.0;
    Vec3 u;
    double len = 0.0, t = -1.0;
    ASSERT_TRUE(springAxis(s, a, a + Vec3{2.0, 0.0, 0.0}, u, len, t));
    EXPECT_EQ(bits(t), bits(0.0));
    // coincident masses: no direction
    EXPECT_FALSE(springAxis(s, a, a, u, len, t));
}

TEST(SpringForces, WindOnAClothPushesWithItsAreaAlongTheNormal) {
    ClothDef def;
    def.rows = 2;
    def.cols = 2;
    def.size = {2.0, 1.5};
    SpringNetwork net = buildCloth(def);
    std::vector<ForceField> fields(1);
    fields[0].kind = FieldKind::Wind;
    fields[0].current = {1.0, 2.0, 4.0};
    fields[0].coefficient = 0.5;
    const Environment env{{0.0, 0.0, 0.0}, &fields};
    std::vector<Vec3> f;
    springForces(net, env, net.x, net.v, f);
    Vec3 total;
    for (const Vec3& fi : f) {
        total += fi;
    }
    // the cloth faces +z: only the normal part of the air speed pushes, over 3 m^2, at 0.5 N s/m^3
    EXPECT_NEAR(total.z, 0.5 * 3.0 * 4.0, 1e-12);
    EXPECT_NEAR(total.x, 0.0, 1e-12);
    EXPECT_NEAR(total.y, 0.0, 1e-12);
}

TEST(SpringForces, SharedOutOverThreadsTheyAreAPlainScatterBitForBit) {
    // a 120 x 120 cloth (several chunks of links, triangles and masses), crumpled, moving, in two winds and
    // a drag field: the forces gathered per mass over 1, 2 and 5 threads against a scatter written here,
    // link after link and triangle after triangle, as the first round computed them
    ClothDef def;
    def.rows = def.cols = 120;
    def.damping = 0.3;
    SpringNetwork net = buildCloth(def);
    Rng rng(9);
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        net.x[i] += Vec3{rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01)};
        net.v[i] = {rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
    }
    net.x[5] = net.x[6]; // a coincident pair: its link adds nothing
    std::vector<ForceField> fields(3);
    fields[0].kind = fields[1].kind = FieldKind::Wind;
    fields[0].current = {1.0, 2.0, 4.0};
    fields[0].coefficient = 0.5;
    fields[1].current = {-3.0, 0.0, 1.0};
    fields[1].coefficient = 0.2;
    fields[2].kind = FieldKind::Drag;
    fields[2].coefficient = 0.1;
    std::vector<Vec3> expected;
    {
        // per mass first: gravity, drag and the drag field (a network without links or triangles)
        SpringNetwork bare = net;
        bare.links.clear();
        bare.triangles.clear();
        bare.kind = NetworkKind::Springs;
        std::vector<ForceField> notWind(fields.begin() + 2, fields.end());
        const Environment plain{{0.0, -9.81, 0.0}, &notWind};
        springForces(bare, plain, bare.x, bare.v, expected);
        for (const ForceField& field : fields) {
            if (field.kind != FieldKind::Wind) {
                continue;
            }
            for (const auto& t : net.triangles) {
                const Vec3 an = cross(net.x[t[1]] - net.x[t[0]], net.x[t[2]] - net.x[t[0]]) * 0.5;
                const double area = length(an);
                if (area <= 1e-15) {
                    continue;
                }
                const Vec3 rel = field.current - (net.v[t[0]] + net.v[t[1]] + net.v[t[2]]) * (1.0 / 3.0);
                const Vec3 ft = an * (field.coefficient / 3.0 * dot(rel, an) / area);
                for (int c = 0; c < 3; ++c) {
                    expected[t[std::size_t(c)]] += ft;
                }
            }
        }
        for (const SpringLink& l : net.links) {
            const Vec3 d = net.x[l.b] - net.x[l.a];
            const double len = length(d);
            if (len <= 1e-12) {
                continue;
            }
            const Vec3 u = d * (1.0 / len);
            const Vec3 fa = u * (l.k * (len - l.rest) + l.kd * dot(net.v[l.b] - net.v[l.a], u));
            expected[l.a] += fa;
            expected[l.b] -= fa;
        }
    }
    for (int threads : {1, 2, 5}) {
        WorkerPool pool(threads);
        const Environment env{{0.0, -9.81, 0.0}, &fields, nullptr, &pool};
        std::vector<Vec3> f;
        springForces(net, env, net.x, net.v, f);
        ASSERT_EQ(f.size(), expected.size());
        EXPECT_EQ(std::memcmp(f.data(), expected.data(), f.size() * sizeof(Vec3)), 0)
            << threads << " threads";
    }
}

TEST(ClothBuilder, FlatClothFacesUp) {
    ClothDef def;
    def.rows = 3;
    def.cols = 4;
    def.vertical = false;
    const SpringNetwork net = buildCloth(def);
    for (const auto& t : net.triangles) {
        EXPECT_GT(cross(net.x[t[1]] - net.x[t[0]], net.x[t[2]] - net.x[t[0]]).y, 0.0);
    }
}

TEST(ClothBuilder, TubeClosesAroundItsAxisAndFacesOut) {
    ClothDef def;
    def.rows = 5;
    def.cols = 8;
    def.size = {2.0, 1.5};
    def.tube = true;
    def.centre = {1.0, 2.0, 3.0};
    const SpringNetwork net = buildCloth(def);
    const double pi = 3.14159265358979323846, radius = 2.0 / (2.0 * pi);
    ASSERT_EQ(net.x.size(), 40u);
    for (const Vec3& p : net.x) {
        EXPECT_NEAR(std::hypot(p.x - 1.0, p.z - 3.0), radius, 1e-12); // on the cylinder about y
    }
    // a quad for every pair of neighbouring columns, the last with the first included
    EXPECT_EQ(net.triangles.size(), 2u * 4u * 8u);
    double area = 0.0;
    for (const auto& t : net.triangles) {
        const Vec3 n = cross(net.x[t[1]] - net.x[t[0]], net.x[t[2]] - net.x[t[0]]);
        const Vec3 c = (net.x[t[0]] + net.x[t[1]] + net.x[t[2]]) * (1.0 / 3.0);
        EXPECT_GT(dot(n, Vec3{c.x - 1.0, 0.0, c.z - 3.0}), 0.0) << "faces out";
        area += 0.5 * length(n);
    }
    // the prism of 8 chords: 8 * chord * length
    EXPECT_NEAR(area, 8.0 * 2.0 * radius * std::sin(pi / 8.0) * 1.5, 1e-9);
    // the seam is linked like any other column: every mass has its two neighbours around, at the chord
    int seam = 0;
    for (const SpringLink& l : net.links) {
        const bool around = l.a / 8 == l.b / 8 && (l.b % 8 == (l.a + 1) % 8 || l.a % 8 == (l.b + 1) % 8);
        if (around) {
            EXPECT_NEAR(l.rest, 2.0 * radius * std::sin(pi / 8.0), 1e-12);
            seam += (l.a % 8 == 7 && l.b % 8 == 0) || (l.a % 8 == 0 && l.b % 8 == 7);
        }
    }
    EXPECT_EQ(seam, 5); // one per row
}

} // namespace
} // namespace tumble

namespace tumble {
namespace {

TEST(SoftBodyBuilder, SurfaceTrianglesCoverTheOutsideFacingOut) {
    SoftBodyDef def;
    def.resolution = {3, 4, 5};
    def.size = {1.0, 2.0, 3.0};
    const SpringNetwork net = buildSoftBody(def);
    // two triangles per surface quad: 2 (2*3 + 3*4 + 2*4) quads on the six faces
    EXPECT_EQ(net.triangles.size(), 2u * 2u * (2u * 3u + 3u * 4u + 2u * 4u));
    double area = 0.0;
    for (const auto& t : net.triangles) {
        const Vec3 n = cross(net.x[t[1]] - net.x[t[0]], net.x[t[2]] - net.x[t[0]]);
        const Vec3 centroid = (net.x[t[0]] + net.x[t[1]] + net.x[t[2]]) * (1.0 / 3.0);
        EXPECT_GT(dot(n, centroid - def.centre), 0.0) << "faces outwards";
        area += 0.5 * length(n);
    }
    EXPECT_NEAR(area, 2.0 * (1.0 * 2.0 + 2.0 * 3.0 + 1.0 * 3.0), 1e-9) << "the whole outside, once";
}

} // namespace
} // namespace tumble
