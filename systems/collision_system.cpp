#include "systems/collision_system.h"

#include "components/particles.h"
#include "components/rigid_body_2d.h"
#include "components/spring_network.h"
#include "engine/parallel.h"
#include "engine/scene.h"
#include "engine/transform.h"
#include "systems/bvh.h"

#include <algorithm>
#include <cmath>

namespace tumble {

namespace {

// projections per step: a point wedged between two bodies converges towards their corner by the square of
// the cosine of the wedge angle each pass; eight passes bring a 60 degree wedge within 1e-6 of it
constexpr int kContactPasses = 8;

/// Distance and normal of a point relative to an axis-aligned box of half extents h centred at 0.
double boxDistance(const Vec3& d, const Vec3& h, Vec3& normal) {
    const double q[3] = {std::abs(d.x) - h.x, std::abs(d.y) - h.y, std::abs(d.z) - h.z};
    const double sign[3] = {d.x < 0 ? -1.0 : 1.0, d.y < 0 ? -1.0 : 1.0, d.z < 0 ? -1.0 : 1.0};
    const Vec3 outside{std::max(q[0], 0.0) * sign[0], std::max(q[1], 0.0) * sign[1],
                       std::max(q[2], 0.0) * sign[2]};
    const double out = length(outside);
    if (out > 0.0) {
        normal = outside * (1.0 / out);
        return out;
    }
    // inside: out through the nearest face
    const int axis = q[0] >= q[1] && q[0] >= q[2] ? 0 : q[1] >= q[2] ? 1 : 2;
    normal = Vec3{axis == 0 ? sign[0] : 0.0, axis == 1 ? sign[1] : 0.0, axis == 2 ? sign[2] : 0.0};
    return q[axis];
}

/// Closest point to p on the triangle abc (Ericson, Real-Time Collision Detection, 5.1.5).
Vec3 closestOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) {
        return a;
    }
    const Vec3 bp = p - b;
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) {
        return b;
    }
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        return a + ab * (d1 / (d1 - d3));
    }
    const Vec3 cp = p - c;
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) {
        return c;
    }
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        return a + ac * (d2 / (d2 - d6));
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    const double denom = 1.0 / (va + vb + vc);
    return a + ab * (vb * denom) + ac * (vc * denom);
}

/// Distance from p to the box [lo, hi] (0 inside).
double boundsDistance(const Vec3& p, const Vec3& lo, const Vec3& hi) {
    const Vec3 out{std::max({lo.x - p.x, 0.0, p.x - hi.x}), std::max({lo.y - p.y, 0.0, p.y - hi.y}),
                   std::max({lo.z - p.z, 0.0, p.z - hi.z})};
    return length(out);
}

/// Beyond this distance from a mesh's bounds, the distance to the bounds stands in for the distance to the
/// mesh (a lower bound, so no contact is missed by a network thinner than this).
constexpr double kMeshNear = 1.0;

} // namespace

namespace {

/// Inside a 2D body's slab, the way out in its plane: the nearest of its sides, never the slab's faces (a
/// rope mass a fast box ran into went out through the face and the rope left the plane for good).
double inPlaneDistance(const RigidBody& slab, const Vec3& d, Vec3& normal) {
    switch (slab.shape) {
    case ShapeKind::Box: {
        const double qx = std::abs(d.x) - slab.halfExtents.x, qy = std::abs(d.y) - slab.halfExtents.y;
        normal = qx > qy ? Vec3{d.x < 0.0 ? -1.0 : 1.0, 0.0, 0.0} : Vec3{0.0, d.y < 0.0 ? -1.0 : 1.0, 0.0};
        return std::max(qx, qy);
    }
    case ShapeKind::Cylinder: { // a circle: its axis, the body's y, lies along the world's z
        const double radial = std::sqrt(d.x * d.x + d.z * d.z);
        normal = radial > 1e-12 ? Vec3{d.x / radial, 0.0, d.z / radial} : Vec3{1.0, 0.0, 0.0};
        return radial - slab.radius;
    }
    case ShapeKind::Convex: { // a prism: its side faces
        const ShapeMesh& m = *slab.mesh;
        double best = -1e300;
        for (std::size_t t = 0; t < m.triangles.size(); ++t) {
            if (std::abs(m.faceNormals[t].z) > 0.5) {
                continue;
            }
            const double dist = dot(d - m.vertices[m.triangles[t][0]], m.faceNormals[t]);
            if (dist > best) {
                best = dist;
                normal = m.faceNormals[t];
            }
        }
        return best;
    }
    default:
        return localSignedDistance(slab, d, normal);
    }
}

} // namespace

double signedDistance(const RigidBody& body, const Vec3& p, Vec3& normal) {
    if (body.shape == ShapeKind::Plane) {
        normal = body.normal;
        return dot(p - body.position, body.normal);
    }
    const Vec3 local = body.toLocal(p);
    double d = localSignedDistance(body, local, normal);
    if (body.slab && d < 0.0) {
        d = inPlaneDistance(body, local, normal);
    }
    normal = rotate(body.orientation, normal);
    return d;
}

double localSignedDistance(const RigidBody& body, const Vec3& d, Vec3& normal) {
    switch (body.shape) {
    case ShapeKind::Plane:
        normal = body.normal;
        return dot(d, body.normal);
    case ShapeKind::Sphere: {
        const double len = length(d);
        normal = len > 1e-12 ? d * (1.0 / len) : Vec3{0.0, 1.0, 0.0};
        return len - body.radius;
    }
    case ShapeKind::Box:
        return boxDistance(d, body.halfExtents, normal);
    case ShapeKind::Capsule: {
        // closest point on the axis segment, then a sphere about it
        const double half = 0.5 * body.height;
        const Vec3 axisPoint{0.0, std::clamp(d.y, -half, half), 0.0};
        const Vec3 e = d - axisPoint;
        const double len = length(e);
        normal = len > 1e-12 ? e * (1.0 / len) : Vec3{1.0, 0.0, 0.0};
        return len - body.radius;
    }
    case ShapeKind::Cylinder: {
        // a rectangle in (radial, y): outside, the distance to its nearest point; inside, to the nearer of
        // the curved side and the flat end
        const double radial = std::sqrt(d.x * d.x + d.z * d.z);
        const Vec3 outward = radial > 1e-12 ? Vec3{d.x / radial, 0.0, d.z / radial} : Vec3{1.0, 0.0, 0.0};
        const Vec3 upward{0.0, d.y < 0.0 ? -1.0 : 1.0, 0.0};
        const double side = radial - body.radius, end = std::abs(d.y) - 0.5 * body.height;
        if (side > 0.0 || end > 0.0) {
            const double a = std::max(side, 0.0), b = std::max(end, 0.0);
            const double dist = std::sqrt(a * a + b * b);
            normal = (outward * a + upward * b) * (1.0 / dist);
            return dist;
        }
        normal = side > end ? outward : upward;
        return std::max(side, end);
    }
    case ShapeKind::Convex: {
        // the farthest face plane: exact inside and in front of a face, a slight underestimate off an
        // edge or a corner (the mesh is the hull's faces, as the rock generator writes them)
        const ShapeMesh& m = *body.mesh;
        double best = -1e300;
        for (std::size_t t = 0; t < m.triangles.size(); ++t) {
            const double dist = dot(d - m.vertices[m.triangles[t][0]], m.faceNormals[t]);
            if (dist > best) {
                best = dist;
                normal = m.faceNormals[t];
            }
        }
        return best;
    }
    case ShapeKind::Mesh: {
        // an open surface (a terrain): the distance to the nearest triangle, negative behind its face
        const ShapeMesh& m = *body.mesh;
        const double far = boundsDistance(d, m.lo, m.hi);
        if (far > kMeshNear) {
            normal = Vec3{0.0, 1.0, 0.0};
            return far;
        }
        double best = 1e300, sign = 1.0;
        for (std::size_t t = 0; t < m.triangles.size(); ++t) {
            const auto& tri = m.triangles[t];
            const Vec3 c = closestOnTriangle(d, m.vertices[tri[0]], m.vertices[tri[1]], m.vertices[tri[2]]);
            const Vec3 e = d - c;
            const double len = length(e);
            if (len < best) {
                best = len;
                sign = dot(e, m.faceNormals[t]) < 0.0 ? -1.0 : 1.0;
                normal = len > 1e-9 ? e * (sign / len) : m.faceNormals[t];
            }
        }
        return sign * best;
    }
    }
    return 1e300;
}

bool worldBox(const RigidBody& b, Aabb& box) {
    Vec3 centre, half;
    switch (b.shape) {
    case ShapeKind::Plane:
    case ShapeKind::Mesh:
        return false;
    case ShapeKind::Sphere:
        half = {b.radius, b.radius, b.radius};
        break;
    case ShapeKind::Box:
        half = b.halfExtents;
        break;
    case ShapeKind::Capsule:
        half = {b.radius, 0.5 * b.height + b.radius, b.radius};
        break;
    case ShapeKind::Cylinder:
        half = {b.radius, 0.5 * b.height, b.radius};
        break;
    case ShapeKind::Convex:
        centre = (b.mesh->lo + b.mesh->hi) * 0.5;
        half = (b.mesh->hi - b.mesh->lo) * 0.5;
        break;
    }
    // the box of the rotated box: along each world axis, the sum of the body axes' reaches
    const Vec3 ax = rotate(b.orientation, {1, 0, 0}), ay = rotate(b.orientation, {0, 1, 0}),
               az = rotate(b.orientation, {0, 0, 1});
    const Vec3 reach{std::abs(ax.x) * half.x + std::abs(ay.x) * half.y + std::abs(az.x) * half.z,
                     std::abs(ax.y) * half.x + std::abs(ay.y) * half.y + std::abs(az.y) * half.z,
                     std::abs(ax.z) * half.x + std::abs(ay.z) * half.y + std::abs(az.z) * half.z};
    const Vec3 at = b.toWorld(centre);
    box.lo = at - reach;
    box.hi = at + reach;
    // a hair larger than rounding could make it, so that a point the shape's own distance puts on or in its
    // surface is never outside the box
    box.inflate(1e-9 *
                (1.0 + std::abs(at.x) + std::abs(at.y) + std::abs(at.z) + reach.x + reach.y + reach.z));
    return true;
}

namespace {

/// Which bodies a point may touch this step: those whose world box, grown by the point's reach, holds it,
/// and the unbounded ones, in the pool's order. Testing only these, in that order, and finding them again
/// after each push, gives the pushes of testing every body one by one (a body whose box is out of reach
/// cannot push), without the cost: 150,000 particles over 11,000 spheres took 40 s a step, and 7 ms now.
/// Many bodies go in a hierarchy; a few are tried one by one.
class NearBodies {
public:
    explicit NearBodies(const std::vector<RigidBody>& bodies) {
        for (std::uint32_t k = 0; k < bodies.size(); ++k) {
            Aabb box;
            if (worldBox(bodies[k], box)) {
                m_bounded.push_back(k);
                m_boxes.push_back(box);
            } else {
                m_unbounded.push_back(k);
            }
        }
        if (m_boxes.size() > kFew) {
            m_tree.build(m_boxes);
        }
    }

    /// The bodies near p (within `reach` of their boxes), ascending, into `out`.
    void find(const Vec3& p, double reach, std::vector<std::uint32_t>& out) const {
        out = m_unbounded;
        Aabb query;
        query.add(p);
        query.inflate(reach);
        if (m_boxes.size() > kFew) {
            const std::size_t from = out.size();
            m_tree.overlapping(query, out);
            for (std::size_t i = from; i < out.size(); ++i) {
                out[i] = m_bounded[out[i]];
            }
        } else {
            for (std::size_t i = 0; i < m_boxes.size(); ++i) {
                if (m_boxes[i].overlaps(query)) {
                    out.push_back(m_bounded[i]);
                }
            }
        }
        std::sort(out.begin(), out.end());
    }

    /// After a push by body k, out[at] == k: the rest of `out` becomes the bodies after k near p, the point
    /// where the push left it, so that every body is still tested in pool order, as one by one.
    void findAfter(const Vec3& p, double reach, std::uint32_t k, std::vector<std::uint32_t>& out,
                   std::size_t at) const {
        std::vector<std::uint32_t> rest;
        find(p, reach, rest);
        out.resize(at + 1);
        for (std::uint32_t b : rest) {
            if (b > k) {
                out.push_back(b);
            }
        }
    }

private:
    static constexpr std::size_t kFew = 16;
    std::vector<std::uint32_t> m_unbounded, m_bounded;
    std::vector<Aabb> m_boxes;
    Bvh m_tree;
};

/// A point as the particle pool keeps it: each coordinate rounded to float. Out of line and not
/// SLP-vectorised: g++ 12's SLP vectoriser drops the rounding of a pair of double -> float -> double
/// conversions (`Vec3{float(p.x), float(p.y), float(p.z)}` came out as {p.x, p.y, float(p.z)} at -O2 and -O3,
/// inlined here), which left particles a hair inside bodies and gave other bits than clang. (clang, which
/// builds the fuzzers, has no such option and no such bug.)
#if defined(__clang__)
[[gnu::noinline]] Vec3 asStored(const Vec3& x) {
#else
[[gnu::noinline, gnu::optimize("no-tree-slp-vectorize")]] Vec3 asStored(const Vec3& x) {
#endif
    return {float(x.x), float(x.y), float(x.z)};
}

/// One particle against the bodies near it: pushed out, its normal speed relative to the surface reversed
/// by restitution, its sliding slowed by friction (it carries no mass, so no body feels it).
void collideParticle(ParticlePool& p, std::uint32_t i, const EmitterDef& def,
                     const std::vector<RigidBody>& bodies, const NearBodies& near,
                     std::vector<std::uint32_t>& candidates, bool respond) {
    Vec3 x{p.px[i], p.py[i], p.pz[i]};
    Vec3 v{p.vx[i], p.vy[i], p.vz[i]};
    // a few passes, so that a particle wedged between two bodies ends up outside both
    bool touched = false;
    for (int pass = 0; pass < kContactPasses; ++pass) {
        bool moved = false;
        near.find(x, 0.0, candidates);
        for (std::size_t c = 0; c < candidates.size(); ++c) {
            const std::uint32_t k = candidates[c];
            const RigidBody& body = bodies[k];
            Vec3 n;
            const double d = signedDistance(body, x, n);
            if (d >= 0.0) {
                continue;
            }
            moved = touched = true;
            x -= n * d;
            near.findAfter(x, 0.0, k, candidates, c); // pushed: the bodies after k near where it is now
            const Vec3 surface = body.dynamic() ? body.velocityAt(x) : Vec3{};
            const Vec3 relative = v - surface;
            const double vn = dot(relative, n);
            if (respond && vn < 0.0) {
                const double mu = std::sqrt(body.friction * def.friction);
                const double bounce = std::max(body.restitution, def.restitution); // as Box2D mixes it
                Vec3 vt = relative - n * vn;
                const double speed = length(vt);
                const double slowdown = mu * -vn * (1.0 + bounce);
                vt = speed <= slowdown ? Vec3{} : vt * (1.0 - slowdown / speed);
                v = surface + vt - n * (vn * bounce);
            }
        }
        if (!moved) {
            break;
        }
    }
    if (!touched) {
        return;
    }
    // stored in float, the point may round a hair inside a surface: nudge it out along the normals, by steps
    // that start near a float's resolution at that distance from the origin and double
    const double resolution = 1e-7 * std::max({1.0, std::abs(x.x), std::abs(x.y), std::abs(x.z)});
    for (int k = 0; k < 12; ++k) {
        bool inside = false;
        near.find(asStored(x), 0.0, candidates);
        for (std::size_t c = 0; c < candidates.size(); ++c) {
            Vec3 n;
            if (signedDistance(bodies[candidates[c]], asStored(x), n) < 0.0) {
                x += n * (resolution * double(2 << k));
                inside = true;
                near.findAfter(asStored(x), 0.0, candidates[c], candidates, c);
            }
        }
        if (!inside) {
            break;
        }
    }
    p.px[i] = float(x.x);
    p.py[i] = float(x.y);
    p.pz[i] = float(x.z);
    p.vx[i] = float(v.x);
    p.vy[i] = float(v.y);
    p.vz[i] = float(v.z);
}

/// A convex polygon (counter-clockwise) extruded to z in [-half, half], as a hull: the faces' first corners
/// and outward normals are what the hull's distance reads.
std::shared_ptr<const ShapeMesh> prismOf(const std::vector<Vec2>& polygon, double half) {
    auto m = std::make_shared<ShapeMesh>();
    const auto n = std::uint32_t(polygon.size());
    for (const double z : {-half, half}) {
        for (const Vec2& v : polygon) {
            m->vertices.push_back({v[0], v[1], z});
        }
    }
    for (std::uint32_t k = 1; k + 1 < n; ++k) {
        m->triangles.push_back({0, k + 1, k}); // the face at -half, seen from below
        m->faceNormals.push_back({0.0, 0.0, -1.0});
        m->triangles.push_back({n, n + k, n + k + 1}); // at +half
        m->faceNormals.push_back({0.0, 0.0, 1.0});
    }
    for (std::uint32_t i = 0; i < n; ++i) {
        const std::uint32_t j = (i + 1) % n;
        const Vec2 &a = polygon[i], &b = polygon[j];
        Vec3 out{b[1] - a[1], a[0] - b[0], 0.0}; // the right of a -> b: outside a counter-clockwise polygon
        out = out * (1.0 / length(out));
        m->triangles.push_back({i, j, n + j});
        m->faceNormals.push_back(out);
        m->triangles.push_back({i, n + j, n + i});
        m->faceNormals.push_back(out);
    }
    m->lo = m->hi = m->vertices[0];
    for (const Vec3& v : m->vertices) {
        m->lo = {std::min(m->lo.x, v.x), std::min(m->lo.y, v.y), std::min(m->lo.z, v.z)};
        m->hi = {std::max(m->hi.x, v.x), std::max(m->hi.y, v.y), std::max(m->hi.z, v.z)};
    }
    return m;
}

} // namespace

RigidBody slabOf(const RigidBody2D& b, double z, double dt) {
    RigidBody s;
    s.slab = true;
    s.mass = b.mass;
    s.friction = b.friction;
    s.restitution = b.restitution;
    // where the body will be when Box2D has stepped, at its present velocity: points are put outside it
    // there (against its pose at the start, a turning plank swept drops 3.5 mm deep into itself a step)
    s.position = {b.position[0] + b.velocity[0] * dt, b.position[1] + b.velocity[1] * dt, z};
    s.orientation = aboutZ(b.angle + b.angularVelocity * dt);
    s.linearVelocity = {b.velocity[0], b.velocity[1], 0.0};
    s.angularVelocity = {0.0, 0.0, b.angularVelocity};
    switch (b.shape) {
    case Shape2DKind::Box:
        s.shape = ShapeKind::Box;
        s.halfExtents = {b.halfExtents[0], b.halfExtents[1], kSlabHalfDepth};
        break;
    case Shape2DKind::Circle:
        s.shape = ShapeKind::Cylinder; // its axis, the body's y, laid along z
        s.radius = b.radius;
        s.height = 2.0 * kSlabHalfDepth;
        s.orientation = {std::sqrt(0.5), 0.0, 0.0, std::sqrt(0.5)};
        break;
    case Shape2DKind::Polygon: {
        // about its centre of mass, which Box2D's velocities and turns are about: the polygon's centroid,
        // where its vertices need not be centred (the body's position is the origin they are given from)
        const Vec2 centroid = b.localCentre();
        std::vector<Vec2> around = b.vertices;
        for (Vec2& v : around) {
            v = {v[0] - centroid[0], v[1] - centroid[1]};
        }
        s.shape = ShapeKind::Convex;
        s.mesh = prismOf(around, kSlabHalfDepth);
        s.position += rotate(s.orientation, {centroid[0], centroid[1], 0.0});
        break;
    }
    case Shape2DKind::Edge: {
        const Vec3 from = rotate(s.orientation, {b.from[0], b.from[1], 0.0});
        const Vec3 to = rotate(s.orientation, {b.to[0], b.to[1], 0.0});
        const Vec3 mid = (from + to) * 0.5;
        s.shape = ShapeKind::Box;
        s.halfExtents = {0.5 * length(to - from), kEdgeHalfWidth, kSlabHalfDepth};
        s.orientation = aboutZ(std::atan2(to.y - from.y, to.x - from.x));
        s.position += mid;
        s.linearVelocity += cross(s.angularVelocity, mid);
        break;
    }
    }
    return s;
}

namespace {

/// The bodies springs and particles meet: the 3D bodies in their pool's order, then the 2D bodies' slabs in
/// theirs. Without 2D bodies, the 3D pool itself; with them, copies, whose pushes handBack() gives to the
/// bodies (a 2D body takes the push in its plane and the turn about z).
class Colliders {
public:
    Colliders(World& world, double dt)
        : m_pool3(world.findPool<RigidBody>()), m_pool2(world.findPool<RigidBody2D>()) {
        if (!m_pool2 || m_pool2->size() == 0) {
            m_bodies = m_pool3 ? &m_pool3->values() : nullptr;
            return;
        }
        if (m_pool3) {
            m_all = m_pool3->values();
        }
        m_first2 = m_all.size();
        for (std::size_t k = 0; k < m_pool2->size(); ++k) {
            const Transform* t = world.tryGet<Transform>(m_pool2->entities()[k]);
            m_all.push_back(slabOf(m_pool2->values()[k], t ? t->position.z : 0.0, dt));
        }
        m_bodies = &m_all;
    }

    bool empty() const { return !m_bodies || m_bodies->empty(); }
    std::vector<RigidBody>& bodies() { return *m_bodies; }

    void handBack() {
        if (m_bodies != &m_all) {
            return;
        }
        for (std::size_t k = 0; k < m_first2; ++k) {
            m_pool3->values()[k].impulse = m_all[k].impulse;
            m_pool3->values()[k].angularImpulse = m_all[k].angularImpulse;
        }
        for (std::size_t k = m_first2; k < m_all.size(); ++k) {
            const RigidBody& s = m_all[k];
            if (s.impulse == Vec3{} && s.angularImpulse == Vec3{}) {
                continue;
            }
            // (a slab turns about the body's centre of mass, as Box2D does: only a static edge's is
            // elsewhere)
            RigidBody2D& b = m_pool2->values()[k - m_first2];
            b.impulse[0] += s.impulse.x;
            b.impulse[1] += s.impulse.y;
            b.angularImpulse += s.angularImpulse.z;
        }
    }

private:
    Pool<RigidBody>* m_pool3;
    Pool<RigidBody2D>* m_pool2;
    std::vector<RigidBody> m_all;
    std::size_t m_first2 = 0;
    std::vector<RigidBody>* m_bodies = nullptr;
};

/// Every spring network's masses against the bodies; with `respond` false, only put back outside them.
void springsAgainst(World& world, std::vector<RigidBody>& bodies, bool respond) {
    const NearBodies near(bodies);
    std::vector<std::uint32_t> candidates;
    world.view<SpringNetwork>().each([&](Entity, SpringNetwork& net) {
        if (net.frozen) {
            return;
        }
        if (respond) {
            net.resting.clear();
        }
        for (std::size_t i = 0; i < net.x.size(); ++i) {
            if (net.pinned[i]) {
                continue;
            }
            // a few passes, so that a mass wedged between two bodies ends up outside both
            for (int pass = 0; pass < kContactPasses; ++pass) {
                bool moved = false;
                near.find(net.x[i], net.thickness, candidates);
                for (std::size_t c = 0; c < candidates.size(); ++c) {
                    const std::uint32_t k = candidates[c];
                    RigidBody& body = bodies[k];
                    Vec3 n;
                    const double d = signedDistance(body, net.x[i], n);
                    if (d >= net.thickness) {
                        continue;
                    }
                    moved = true;
                    net.x[i] += n * (net.thickness - d);
                    near.findAfter(net.x[i], net.thickness, k, candidates,
                                   c); // the bodies after k near it now
                    // the response acts on the velocity relative to the body's surface there
                    const Vec3 surface = body.dynamic() ? body.velocityAt(net.x[i]) : Vec3{};
                    const Vec3 relative = net.v[i] - surface;
                    const double vn = dot(relative, n);
                    const double mu =
                        std::sqrt(body.friction * net.friction); // combined as Box2D and our Bullet do
                    if (respond && !body.dynamic() && net.kind == NetworkKind::Fem && vn <= 0.0) {
                        net.resting.push_back({std::uint32_t(i), n, mu});
                    }
                    if (!respond || vn >= 0.0) {
                        continue; // already leaving the surface
                    }
                    // the velocity into the surface stops (or bounces by restitution); sliding loses to
                    // friction
                    Vec3 vt = relative - n * vn;
                    const double speed = length(vt);
                    const double slowdown = mu * -vn;
                    vt = speed <= slowdown ? Vec3{} : vt * (1.0 - slowdown / speed);
                    const Vec3 after = surface + vt - n * (vn * body.restitution);
                    if (body.dynamic()) {
                        // the body takes the momentum the mass lost: J on the body = -m dv of the mass
                        const Vec3 j = (net.v[i] - after) * (1.0 / net.invMass[i]);
                        body.impulse += j;
                        body.angularImpulse += cross(net.x[i] - body.position, j);
                    }
                    net.v[i] = after;
                }
                if (!moved) {
                    break;
                }
            }
        }
    });
}

/// Particles against the bodies: each particle alone (they carry no mass, so no body feels them), so
/// chunks of particles share out over the pool's threads with the same bits.
void particlesAgainst(World& world, const StepContext& ctx, const std::vector<RigidBody>& bodies,
                      bool respond) {
    const NearBodies near(bodies);
    world.view<ParticleEmitter>().each([&](Entity, ParticleEmitter& e) {
        if (!e.def.collide) {
            return;
        }
        ParticlePool& p = e.pool;
        poolOr(ctx.pool).forChunks(p.count, 4096, [&](std::size_t, std::size_t first, std::size_t end) {
            std::vector<std::uint32_t> candidates;
            for (std::size_t i = first; i < end; ++i) {
                collideParticle(p, std::uint32_t(i), e.def, bodies, near, candidates, respond);
            }
        });
    });
}

} // namespace

void collideSprings(World& world, const StepContext& ctx) {
    Colliders colliders(world, ctx.dt);
    if (colliders.empty()) {
        return;
    }
    springsAgainst(world, colliders.bodies(), true);
    colliders.handBack();
}

void collideParticles(World& world, const StepContext& ctx) {
    Colliders colliders(world, ctx.dt);
    if (!colliders.empty()) {
        particlesAgainst(world, ctx, colliders.bodies(), true);
    }
}

void collideWithBodies(World& world, const StepContext& ctx) {
    Colliders colliders(world, ctx.dt);
    if (colliders.empty()) {
        return;
    }
    springsAgainst(world, colliders.bodies(), true);
    colliders.handBack();
    particlesAgainst(world, ctx, colliders.bodies(), true); // (particles push nothing: no hand-back)
}

void settleOutside2DBodies(World& world, const StepContext& ctx) {
    const Pool<RigidBody2D>* pool = world.findPool<RigidBody2D>();
    if (!pool || pool->size() == 0) {
        return;
    }
    std::vector<RigidBody> slabs;
    for (std::size_t k = 0; k < pool->size(); ++k) {
        const Transform* t = world.tryGet<Transform>(pool->entities()[k]);
        slabs.push_back(slabOf(pool->values()[k], t ? t->position.z : 0.0, 0.0));
    }
    springsAgainst(world, slabs, false);
    particlesAgainst(world, ctx, slabs, false);
}

} // namespace tumble
