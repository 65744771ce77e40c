#pragma once
// Which vector instructions the hot loops use: SSE2 (in every x86-64 processor) or AVX2 (eight floats at
// a time), chosen once at run time. Both give exactly the same bits: the kernels do the same operations
// on each lane in the same order (no fused multiply-add: the build has -ffp-contract=off and the kernels
// call separate multiply and add), so a replay recorded on an AVX2 machine verifies on one without.
// TUMBLE_SIMD=sse2 or TUMBLE_SIMD=avx2 forces either (avx2 where the processor has it).

namespace tumble {

enum class Simd { Sse2, Avx2 };

/// True if this processor runs AVX2.
bool avx2Available();
/// The instructions the kernels use now: TUMBLE_SIMD if set (avx2 only where available), else the
/// widest available.
Simd activeSimd();
/// An error message if TUMBLE_SIMD is set to something other than sse2 or avx2, else empty.
const char* simdEnvironmentError();
/// Use these from now on (Avx2 falls back to Sse2 where the processor lacks it); for tests.
void forceSimd(Simd simd);

} // namespace tumble
