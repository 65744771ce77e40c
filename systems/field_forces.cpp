#include "systems/field_forces.h"

#include <cmath>

namespace tumble {

namespace {

bool within(const ForceField& f, const Vec3& d) {
    return f.radius <= 0.0 || dot(d, d) <= f.radius * f.radius;
}

} // namespace

Vec3 fieldForce(const ForceField& f, const Vec3& x, const Vec3& v, double mass) {
    switch (f.kind) {
    case FieldKind::Wind:
        return (f.current - v) * f.coefficient;
    case FieldKind::Drag:
        return v * -f.strength.x;
    case FieldKind::Vortex: {
        const Vec3 d = x - f.origin;
        const Vec3 radial = d - f.axis * dot(d, f.axis);
        if (!within(f, radial)) {
            return {};
        }
        // the pull towards the axis that keeps a body turning at omega on its circle, plus the air's drag
        // towards turning at omega (coefficient 0: a pure central force, which conserves the radius)
        const double omega = f.strength.x;
        const Vec3 air = cross(f.axis, radial) * omega;
        return radial * (-omega * omega * mass) + (air - v) * f.coefficient;
    }
    case FieldKind::Point: {
        const Vec3 d = f.origin - x;
        if (!within(f, d)) {
            return {};
        }
        const double r2 = dot(d, d) + 0.01; // softened within 0.1 m
        return d * (f.strength.x * mass / (r2 * std::sqrt(r2)));
    }
    }
    return {};
}

double fieldDamping(const ForceField& f, const Vec3& x) {
    switch (f.kind) {
    case FieldKind::Wind:
        return f.coefficient;
    case FieldKind::Drag:
        return f.strength.x;
    case FieldKind::Vortex: {
        const Vec3 d = x - f.origin;
        return within(f, d - f.axis * dot(d, f.axis)) ? f.coefficient : 0.0;
    }
    case FieldKind::Point:
        return 0.0;
    }
    return 0.0;
}

} // namespace tumble
