#include "systems/fem_element.h"

#include "engine/lanes.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace tumble {

namespace {

using Matrix3 = Eigen::Matrix3d;

Matrix3 toEigen(const Mat3& m) {
    Matrix3 r;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            r(i, j) = m.m[std::size_t(3 * i + j)];
        }
    }
    return r;
}

Mat3 fromEigen(const Matrix3& m) {
    Mat3 r;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            r.m[std::size_t(3 * i + j)] = m(i, j);
        }
    }
    return r;
}

Eigen::Vector3d toEigen(const Vec3& v) {
    return {v.x, v.y, v.z};
}

/// The rotation of F from its SVD, with a reflection moved onto the smallest singular value (Irving et al.
/// 2004), so that it is a proper rotation however F is turned or inverted.
Eigen::Quaterniond svdRotation(const Matrix3& f) {
    Eigen::JacobiSVD<Matrix3> svd(f, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Matrix3 u = svd.matrixU();
    Matrix3 v = svd.matrixV();
    if (u.determinant() < 0.0) {
        u.col(2) = -u.col(2);
    }
    if (v.determinant() < 0.0) {
        v.col(2) = -v.col(2);
    }
    return Eigen::Quaterniond(Matrix3(u * v.transpose()));
}

/// Solves G t = w for a symmetric 3x3 G by its adjugate; false unless G is clearly positive definite: its
/// leading minors (Sylvester's test) above least, least^2 and least^3.
bool solvePositive(const Matrix3& g, const Eigen::Vector3d& w, double least, Eigen::Vector3d& t) {
    const double c00 = g(1, 1) * g(2, 2) - g(1, 2) * g(2, 1);
    const double c01 = g(1, 2) * g(2, 0) - g(1, 0) * g(2, 2);
    const double c02 = g(1, 0) * g(2, 1) - g(1, 1) * g(2, 0);
    const double minor2 = g(0, 0) * g(1, 1) - g(0, 1) * g(1, 0);
    const double det = g(0, 0) * c00 + g(0, 1) * c01 + g(0, 2) * c02;
    if (!(g(0, 0) > least) || !(minor2 > least * least) || !(det > least * least * least)) {
        return false;
    }
    const double c11 = g(0, 0) * g(2, 2) - g(0, 2) * g(2, 0);
    const double c12 = g(0, 1) * g(2, 0) - g(0, 0) * g(2, 1);
    const double c22 = minor2;
    const double inv = 1.0 / det;
    // G is symmetric, so is its adjugate
    t.x() = (c00 * w.x() + c01 * w.y() + c02 * w.z()) * inv;
    t.y() = (c01 * w.x() + c11 * w.y() + c12 * w.z()) * inv;
    t.z() = (c02 * w.x() + c12 * w.y() + c22 * w.z()) * inv;
    return true;
}

/// A quaternion of a turn (axis times angle), not unit: under 0.1 rad (1, t / 2), whose angle is off by
/// under 1e-4 of itself (which the next iteration, or step, takes out); larger turns exactly, at most 1 rad
/// (Newton's step is only trusted that far).
Eigen::Quaterniond turnQuaternion(const Eigen::Vector3d& t) {
    if (t.squaredNorm() < 0.01) {
        return Eigen::Quaterniond(1.0, 0.5 * t.x(), 0.5 * t.y(), 0.5 * t.z());
    }
    const double angle = t.norm();
    return Eigen::Quaterniond(Eigen::AngleAxisd(std::min(angle, 1.0), t / angle));
}

/// The rotation of a quaternion that need not be unit (its length divides out): one division, where
/// normalising first would take a square root as well.
Matrix3 rotationMatrix(const Eigen::Quaterniond& q) {
    const double s = 2.0 / q.squaredNorm();
    const double x = q.x(), y = q.y(), z = q.z(), w = q.w();
    Matrix3 r;
    r << 1.0 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y), //
        s * (x * y + w * z), 1.0 - s * (x * x + z * z), s * (y * z - w * x),  //
        s * (x * z - w * y), s * (y * z + w * x), 1.0 - s * (x * x + y * y);
    return r;
}

} // namespace

Mat3 rotationOf(const Mat3& fm, Quat& q, bool fromScratch, const Vec3& turn) {
    const Matrix3 f = toEigen(fm);
    // Newton's method on the condition that R^T F be symmetric, from last step's R turned by the turn
    // expected since (the elements' spin times the step): with M = R^T F and S = sym(M), the turn t that
    // symmetrises R exp([t])'s M to first order solves (tr(S) I - S) t = axial(M - M^T); quadratic, so
    // about one iteration a step once the expected turn is taken. The SVD instead on the first step, for
    // an inverted element, where tr(S) I - S is not clearly positive definite (an element nearly flat, or
    // R more than a quarter turn off, where Newton could settle on R turned half round) and where Newton
    // does not settle in 8 iterations. The quaternion is normalised once, at the end: its length grows
    // by under 1e-3 an iteration
    bool newton = !fromScratch && f.determinant() > 0.0;
    Eigen::Quaterniond r(q.w, q.x, q.y, q.z);
    if (newton) {
        r = turnQuaternion(toEigen(turn)) * r;
    }
    Matrix3 rm = rotationMatrix(r);
    for (int it = 0; newton; ++it) {
        const Matrix3 m = rm.transpose() * f;
        const Eigen::Vector3d w(m(2, 1) - m(1, 2), m(0, 2) - m(2, 0), m(1, 0) - m(0, 1));
        const Matrix3 sym = 0.5 * (m + m.transpose());
        Eigen::Vector3d t;
        if (!solvePositive(sym.trace() * Matrix3::Identity() - sym, w, 1e-6 * sym.trace(), t) || it == 8) {
            newton = false;
            break;
        }
        const double squared = t.squaredNorm();
        if (!(squared > 1e-24)) {
            break;
        }
        r = r * turnQuaternion(t);
        rm = rotationMatrix(r);
        if (squared < 1e-6) {
            break; // what is left is of the order of this turn squared (under 1e-3 rad): about 1e-6 rad
        }
    }
    if (!newton) {
        r = svdRotation(f);
        rm = rotationMatrix(r);
    }
    r.normalize();
    q = {r.x(), r.y(), r.z(), r.w()};
    return fromEigen(rm);
}

namespace {

// ---- elements side by side in the lanes of T (double: one; Double2: two) ----
// Matrices are 9 numbers, row by row.

template <class T>
struct Elements {
    T f[9], rate[9]; ///< the deformation gradient F and its rate dF/dt
    T g[4][3];       ///< the corners' rest gradients
    T volume;
    T q[4];    ///< the rotation's quaternion (x, y, z, w): last step's in, this step's out
    T turn[3]; ///< the spin times the time since q was found
    T r[9];    ///< the rotation
};

/// The rotation of a quaternion that need not be unit (its length divides out).
template <class T>
void rotationMatrix(const T* q, T* r) {
    const T x = q[0], y = q[1], z = q[2], w = q[3];
    const T s = T(2.0) / (x * x + y * y + z * z + w * w);
    r[0] = T(1.0) - s * (y * y + z * z);
    r[1] = s * (x * y - w * z);
    r[2] = s * (x * z + w * y);
    r[3] = s * (x * y + w * z);
    r[4] = T(1.0) - s * (x * x + z * z);
    r[5] = s * (y * z - w * x);
    r[6] = s * (x * z - w * y);
    r[7] = s * (y * z + w * x);
    r[8] = T(1.0) - s * (x * x + y * y);
}

/// q turned by a small turn t (axis times angle) first (before: (1, t / 2) q) or after (q (1, t / 2)):
/// the quaternion of a turn under 0.1 rad to within 1e-4 of its angle, as turnQuaternion takes it.
template <class T>
void turnQuaternion(T* q, const T* t, bool before) {
    const T hx = T(0.5) * t[0], hy = T(0.5) * t[1], hz = T(0.5) * t[2];
    const T x = q[0], y = q[1], z = q[2], w = q[3];
    const T s = before ? T(1.0) : T(-1.0); // the cross product's sign: h x q before, q x h after
    q[3] = w - (hx * x + hy * y + hz * z);
    q[0] = x + w * hx + s * (hy * z - hz * y);
    q[1] = y + w * hy + s * (hz * x - hx * z);
    q[2] = z + w * hz + s * (hx * y - hy * x);
}

/// F and dF/dt of elements e, e + 1, ... (one a lane): F = sum_a x_a g_a^T.
template <class T>
void load(const FemElements& fem, const std::vector<Vec3>& x, const std::vector<Vec3>& v, std::size_t e,
          const Quat* rotation, Elements<T>& el) {
    T xs[4][3], vs[4][3];
    for (int l = 0; l < kLanes<T>; ++l) {
        const auto& t = fem.tets[e + std::size_t(l)];
        const auto& g = fem.gradients[e + std::size_t(l)];
        for (std::size_t a = 0; a < 4; ++a) {
            const Vec3 &xa = x[t[a]], &va = v[t[a]];
            setLane(xs[a][0], l, xa.x), setLane(xs[a][1], l, xa.y), setLane(xs[a][2], l, xa.z);
            setLane(vs[a][0], l, va.x), setLane(vs[a][1], l, va.y), setLane(vs[a][2], l, va.z);
            setLane(el.g[a][0], l, g[a].x), setLane(el.g[a][1], l, g[a].y), setLane(el.g[a][2], l, g[a].z);
        }
        setLane(el.volume, l, fem.volume[e + std::size_t(l)]);
        const Quat& q = rotation[l];
        setLane(el.q[0], l, q.x), setLane(el.q[1], l, q.y), setLane(el.q[2], l, q.z),
            setLane(el.q[3], l, q.w);
    }
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            el.f[3 * i + j] =
                xs[0][i] * el.g[0][j] + xs[1][i] * el.g[1][j] + xs[2][i] * el.g[2][j] + xs[3][i] * el.g[3][j];
            el.rate[3 * i + j] =
                vs[0][i] * el.g[0][j] + vs[1][i] * el.g[1][j] + vs[2][i] * el.g[2][j] + vs[3][i] * el.g[3][j];
        }
    }
}

/// The rotation by rotationOf's common case: last step's rotation turned by the spin over `since`, then
/// one Newton iteration (rotationOf explains it). The mask of the lanes where that is what rotationOf
/// does: an element found before, not inverted, turning under 0.1 rad, whose iteration leaves under 1e-3
/// rad; el.q and el.r are only right there.
template <class T>
auto settleRotation(Elements<T>& el, double since) {
    const T* f = el.f;
    T r[9];
    rotationMatrix(el.q, r);
    // the spin: the axial vector of the skew part of dF/dt R^T (with R for F: small strain)
    auto b = [&](int i, int j) {
        return el.rate[3 * i] * r[3 * j] + el.rate[3 * i + 1] * r[3 * j + 1] +
               el.rate[3 * i + 2] * r[3 * j + 2];
    };
    const T half = T(0.5 * since);
    el.turn[0] = (b(2, 1) - b(1, 2)) * half;
    el.turn[1] = (b(0, 2) - b(2, 0)) * half;
    el.turn[2] = (b(1, 0) - b(0, 1)) * half;
    const T found = el.q[0] * el.q[0] + el.q[1] * el.q[1] + el.q[2] * el.q[2] + el.q[3] * el.q[3];
    const T turned = el.turn[0] * el.turn[0] + el.turn[1] * el.turn[1] + el.turn[2] * el.turn[2];
    const T detF = f[0] * (f[4] * f[8] - f[5] * f[7]) - f[1] * (f[3] * f[8] - f[5] * f[6]) +
                   f[2] * (f[3] * f[7] - f[4] * f[6]);
    using Mask = decltype(T() < T());
    Mask settled = (found > T(0.5)) & (turned < T(0.01)) & (detF > T(0.0));
    turnQuaternion(el.q, el.turn, true);
    rotationMatrix(el.q, r);
    // Newton: M = R^T F, G = tr(S) I - S with S = sym(M), G t = axial(M - M^T) by G's adjugate
    T m[9];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            m[3 * i + j] = r[i] * f[j] + r[3 + i] * f[3 + j] + r[6 + i] * f[6 + j];
        }
    }
    const T w[3] = {m[7] - m[5], m[2] - m[6], m[3] - m[1]};
    const T trace = m[0] + m[4] + m[8];
    const T g00 = trace - m[0], g11 = trace - m[4], g22 = trace - m[8];
    const T g01 = T(-0.5) * (m[1] + m[3]), g02 = T(-0.5) * (m[2] + m[6]), g12 = T(-0.5) * (m[5] + m[7]);
    const T c00 = g11 * g22 - g12 * g12, c01 = g12 * g02 - g01 * g22, c02 = g01 * g12 - g11 * g02;
    const T minor2 = g00 * g11 - g01 * g01;
    const T det = g00 * c00 + g01 * c01 + g02 * c02;
    const T least = T(1e-6) * trace;
    settled = Mask(settled & (g00 > least) & (minor2 > least * least) & (det > least * least * least));
    const T c11 = g00 * g22 - g02 * g02, c12 = g01 * g02 - g00 * g12;
    const T inv = T(1.0) / det;
    T t[3];
    t[0] = (c00 * w[0] + c01 * w[1] + c02 * w[2]) * inv;
    t[1] = (c01 * w[0] + c11 * w[1] + c12 * w[2]) * inv;
    t[2] = (c02 * w[0] + c12 * w[1] + minor2 * w[2]) * inv;
    const T squared = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
    settled = Mask(settled & (squared < T(1e-6))); // else more iterations: rotationOf
    T q[4] = {el.q[0], el.q[1], el.q[2], el.q[3]};
    turnQuaternion(q, t, false);
    const auto turns = squared > T(1e-24); // a smaller turn is not taken
    for (int k = 0; k < 4; ++k) {
        el.q[k] = select(turns, q[k], el.q[k]);
    }
    rotationMatrix(el.q, el.r);
    using std::sqrt;
    const T length = sqrt(el.q[0] * el.q[0] + el.q[1] * el.q[1] + el.q[2] * el.q[2] + el.q[3] * el.q[3]);
    for (T& c : el.q) {
        c = c / length;
    }
    return settled;
}

/// Element forces on the corners from the rotation: with A = R^T (F + damping dF/dt), the stress of the
/// strain sym(A) - I, S = lambda tr I + 2 mu (sym(A) - I), and f_a = -V R S g_a.
template <class T>
void cornerForces(const Elements<T>& el, double damping, double lambda, double mu, T (&force)[4][3]) {
    T sum[9], a[9];
    for (int k = 0; k < 9; ++k) {
        sum[k] = el.f[k] + T(damping) * el.rate[k];
    }
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            a[3 * i + j] = el.r[i] * sum[j] + el.r[3 + i] * sum[3 + j] + el.r[6 + i] * sum[6 + j];
        }
    }
    const T twoMu = T(2.0 * mu), strained = T(lambda) * ((a[0] - T(1.0)) + (a[4] - T(1.0)) + (a[8] - T(1.0)));
    T s[9];
    for (int i = 0; i < 3; ++i) {
        s[4 * i] = twoMu * (a[4 * i] - T(1.0)) + strained;
    }
    s[1] = s[3] = T(mu) * (a[1] + a[3]);
    s[2] = s[6] = T(mu) * (a[2] + a[6]);
    s[5] = s[7] = T(mu) * (a[5] + a[7]);
    T p[9];
    const T scale = -el.volume;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            p[3 * i + j] =
                scale * (el.r[3 * i] * s[j] + el.r[3 * i + 1] * s[3 + j] + el.r[3 * i + 2] * s[6 + j]);
        }
    }
    for (int c = 0; c < 4; ++c) {
        for (int i = 0; i < 3; ++i) {
            force[c][i] = p[3 * i] * el.g[c][0] + p[3 * i + 1] * el.g[c][1] + p[3 * i + 2] * el.g[c][2];
        }
    }
}

/// Elements e, e + 1, ... (one a lane; rotation, out's arrays at the first of them).
template <class T>
void elementsAt(const FemElements& fem, const std::vector<Vec3>& x, const std::vector<Vec3>& v, std::size_t e,
                Quat* rotation, double damping, double since, const ElementOutput& out, std::size_t slot) {
    Elements<T> el;
    load(fem, x, v, e, rotation, el);
    const auto settled = settleRotation(el, since);
    for (int l = 0; l < kLanes<T>; ++l) {
        if (!lane(settled, l)) {
            // the rest by rotationOf alone, from the element's rotation of before (still in `rotation`)
            Mat3 f;
            for (std::size_t k = 0; k < 9; ++k) {
                f.m[k] = lane(el.f[k], l);
            }
            Quat q = rotation[l];
            const bool fresh = q == kNoRotation;
            const Vec3 turn = fresh || !(since > 0.0)
                                  ? Vec3{}
                                  : Vec3{lane(el.turn[0], l), lane(el.turn[1], l), lane(el.turn[2], l)};
            const Mat3 r = rotationOf(f, q, fresh, turn);
            for (std::size_t k = 0; k < 9; ++k) {
                setLane(el.r[k], l, r.m[k]);
            }
            setLane(el.q[0], l, q.x), setLane(el.q[1], l, q.y), setLane(el.q[2], l, q.z);
            setLane(el.q[3], l, q.w);
            if (out.searched != nullptr) {
                ++*out.searched;
            }
        }
    }
    T force[4][3];
    cornerForces(el, damping, fem.lambda, fem.mu, force);
    for (int l = 0; l < kLanes<T>; ++l) {
        rotation[l] = {lane(el.q[0], l), lane(el.q[1], l), lane(el.q[2], l), lane(el.q[3], l)};
        for (std::size_t c = 0; c < 4; ++c) {
            out.force[slot + std::size_t(l)][c] = {lane(force[c][0], l), lane(force[c][1], l),
                                                   lane(force[c][2], l)};
        }
    }
    if (out.turned != nullptr) {
        // sqrt(weight V mu) R g_a
        using std::sqrt;
        const T scale = sqrt(T(out.weight * fem.mu) * el.volume);
        for (std::size_t c = 0; c < 4; ++c) {
            T turned[3];
            for (int i = 0; i < 3; ++i) {
                turned[i] = scale * (el.r[3 * i] * el.g[c][0] + el.r[3 * i + 1] * el.g[c][1] +
                                     el.r[3 * i + 2] * el.g[c][2]);
            }
            for (int l = 0; l < kLanes<T>; ++l) {
                out.turned[slot + std::size_t(l)][c] = {float(lane(turned[0], l)), float(lane(turned[1], l)),
                                                        float(lane(turned[2], l))};
            }
        }
    }
}

} // namespace

void elementForces(const FemElements& fem, const std::vector<Vec3>& x, const std::vector<Vec3>& v,
                   std::size_t first, std::size_t end, Quat* rotation, double damping, double since,
                   const ElementOutput& out) {
    std::size_t e = first;
    for (; e + 2 <= end; e += 2) {
        elementsAt<Double2>(fem, x, v, e, rotation + (e - first), damping, since, out, e - first);
    }
    for (; e < end; ++e) {
        elementsAt<double>(fem, x, v, e, rotation + (e - first), damping, since, out, e - first);
    }
}

} // namespace tumble
