#pragma once
// The small vector and rotation types components use. Plain doubles with no padding, so a component's bytes
// are its state (the state hash reads them directly) and a std::vector<Vec3> is a packed array.

#include <cmath>

namespace tumble {

/// A 3-vector of doubles.
struct Vec3 {
    double x = 0.0;
    double y = 0.0;
    double z = 0.0;

    constexpr Vec3& operator+=(const Vec3& o) {
        x += o.x;
        y += o.y;
        z += o.z;
        return *this;
    }
    constexpr Vec3& operator-=(const Vec3& o) {
        x -= o.x;
        y -= o.y;
        z -= o.z;
        return *this;
    }
    constexpr Vec3& operator*=(double s) {
        x *= s;
        y *= s;
        z *= s;
        return *this;
    }
    friend constexpr Vec3 operator+(Vec3 a, const Vec3& b) { return a += b; }
    friend constexpr Vec3 operator-(Vec3 a, const Vec3& b) { return a -= b; }
    friend constexpr Vec3 operator-(const Vec3& a) { return {-a.x, -a.y, -a.z}; }
    friend constexpr Vec3 operator*(Vec3 a, double s) { return a *= s; }
    friend constexpr Vec3 operator*(double s, Vec3 a) { return a *= s; }
    friend constexpr bool operator==(const Vec3&, const Vec3&) = default;
};

constexpr double dot(const Vec3& a, const Vec3& b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
constexpr Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(const Vec3& a) {
    return std::sqrt(dot(a, a));
}
inline bool isFinite(const Vec3& a) {
    return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z);
}

static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 must have no padding: its bytes are hashed");

/// A rotation as a unit quaternion (x, y, z: the vector part; w: the scalar part), as the dump writes it.
struct Quat {
    double x = 0.0;
    double y = 0.0;
    double z = 0.0;
    double w = 1.0;
    friend constexpr bool operator==(const Quat&, const Quat&) = default;
};

/// v rotated by the unit quaternion q.
constexpr Vec3 rotate(const Quat& q, const Vec3& v) {
    // v + 2 u x (u x v + w v), with u the vector part
    const Vec3 u{q.x, q.y, q.z};
    const Vec3 t = cross(u, v) * 2.0;
    return v + t * q.w + cross(u, t);
}

/// The inverse rotation of a unit quaternion.
constexpr Quat conjugate(const Quat& q) {
    return {-q.x, -q.y, -q.z, q.w};
}

/// The rotation about the z axis by `angle` radians (a 2D body's orientation).
inline Quat aboutZ(double angle) {
    return {0.0, 0.0, std::sin(0.5 * angle), std::cos(0.5 * angle)};
}

static_assert(sizeof(Quat) == 4 * sizeof(double), "Quat must have no padding: its bytes are hashed");

} // namespace tumble
