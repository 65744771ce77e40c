#pragma once
// What a force field does to a body: the formulas of the force_field component (force_field_system.h
// describes each kind), shared by every system that moves things through the fields (springs, particles).

#include "components/force_field.h"

namespace tumble {

/// Force of a field on a body of the given mass at x moving at v, N.
Vec3 fieldForce(const ForceField& field, const Vec3& x, const Vec3& v, double mass);

/// The damping a field adds around x: the c in dF/dv = -c I (for implicit integration), N s/m.
double fieldDamping(const ForceField& field, const Vec3& x);

} // namespace tumble
