#pragma once
// One double, or two side by side on an SSE2 register, behind the same operators: a kernel written once as
// a template over its number type runs one item at a time (double) or two at once (Double2) with exactly
// the same bits in every lane. +, -, *, / and sqrt round each lane as they round a lone double (IEEE 754),
// the build contracts no multiply-add (-ffp-contract=off), and a kernel's operations run in the order it
// writes them whatever the type. A comparison gives a mask (bool, or Mask2); select(mask, a, b) picks a
// where the mask holds, b elsewhere; lane and setLane read and write one lane.

#include <emmintrin.h>

namespace tumble {

/// Per lane: true or false (all bits set or clear).
struct Mask2 {
    __m128d bits;

    friend Mask2 operator&(Mask2 a, Mask2 b) { return {_mm_and_pd(a.bits, b.bits)}; }
    friend Mask2 operator|(Mask2 a, Mask2 b) { return {_mm_or_pd(a.bits, b.bits)}; }
    friend Mask2 operator!(Mask2 a) { return {_mm_xor_pd(a.bits, _mm_castsi128_pd(_mm_set1_epi32(-1)))}; }
};

/// Two doubles.
struct Double2 {
    __m128d v;

    Double2() : v(_mm_setzero_pd()) {}
    Double2(double s) : v(_mm_set1_pd(s)) {} // NOLINT: implicit, for constants in kernels
    explicit Double2(__m128d x) : v(x) {}

    friend Double2 operator+(Double2 a, Double2 b) { return Double2(_mm_add_pd(a.v, b.v)); }
    friend Double2 operator-(Double2 a, Double2 b) { return Double2(_mm_sub_pd(a.v, b.v)); }
    friend Double2 operator*(Double2 a, Double2 b) { return Double2(_mm_mul_pd(a.v, b.v)); }
    friend Double2 operator/(Double2 a, Double2 b) { return Double2(_mm_div_pd(a.v, b.v)); }
    friend Double2 operator-(Double2 a) { return Double2(_mm_xor_pd(a.v, _mm_set1_pd(-0.0))); }
    Double2& operator+=(Double2 b) { return *this = *this + b; }
    Double2& operator-=(Double2 b) { return *this = *this - b; }
    Double2& operator*=(Double2 b) { return *this = *this * b; }

    friend Mask2 operator<(Double2 a, Double2 b) { return {_mm_cmplt_pd(a.v, b.v)}; }
    friend Mask2 operator>(Double2 a, Double2 b) { return {_mm_cmpgt_pd(a.v, b.v)}; }
};

inline Double2 sqrt(Double2 a) {
    return Double2(_mm_sqrt_pd(a.v));
}
inline Double2 select(Mask2 m, Double2 a, Double2 b) {
    return Double2(_mm_or_pd(_mm_and_pd(m.bits, a.v), _mm_andnot_pd(m.bits, b.v)));
}
inline double select(bool m, double a, double b) {
    return m ? a : b;
}

/// How many items a number type holds side by side.
template <class T>
inline constexpr int kLanes = 1;
template <>
inline constexpr int kLanes<Double2> = 2;

inline double lane(double x, int) {
    return x;
}
inline bool lane(bool m, int) {
    return m;
}
inline double lane(Double2 x, int i) {
    return i == 0 ? _mm_cvtsd_f64(x.v) : _mm_cvtsd_f64(_mm_unpackhi_pd(x.v, x.v));
}
inline bool lane(Mask2 m, int i) {
    return ((_mm_movemask_pd(m.bits) >> i) & 1) != 0;
}
inline void setLane(double& x, int, double s) {
    x = s;
}
inline void setLane(Double2& x, int i, double s) {
    x.v = i == 0 ? _mm_move_sd(x.v, _mm_set_sd(s)) : _mm_unpacklo_pd(x.v, _mm_set_sd(s));
}

} // namespace tumble
