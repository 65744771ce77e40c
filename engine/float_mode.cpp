#include "engine/float_mode.h"

#if defined(__x86_64__) || defined(_M_X64)
#include <xmmintrin.h>
#endif

namespace tumble {

#if defined(__x86_64__) || defined(_M_X64)
namespace {
constexpr unsigned kFlushToZero = 0x8000;      // MXCSR.FTZ: denormal results become zero
constexpr unsigned kDenormalsAreZero = 0x0040; // MXCSR.DAZ: denormal inputs read as zero
} // namespace

FlushDenormals::FlushDenormals() : m_saved(_mm_getcsr()) {
    _mm_setcsr(static_cast<unsigned>(m_saved) | kFlushToZero | kDenormalsAreZero);
}
FlushDenormals::~FlushDenormals() {
    _mm_setcsr(static_cast<unsigned>(m_saved));
}
std::uint64_t floatMode() {
    return _mm_getcsr();
}
void setFloatMode(std::uint64_t mode) {
    _mm_setcsr(static_cast<unsigned>(mode));
}
#elif defined(__aarch64__)
FlushDenormals::FlushDenormals() : m_saved(__builtin_aarch64_get_fpcr64()) {
    __builtin_aarch64_set_fpcr64(m_saved | (std::uint64_t{1} << 24)); // FPCR.FZ
}
FlushDenormals::~FlushDenormals() {
    __builtin_aarch64_set_fpcr64(m_saved);
}
std::uint64_t floatMode() {
    return __builtin_aarch64_get_fpcr64();
}
void setFloatMode(std::uint64_t mode) {
    __builtin_aarch64_set_fpcr64(mode);
}
#else
FlushDenormals::FlushDenormals() = default;
FlushDenormals::~FlushDenormals() = default;
std::uint64_t floatMode() {
    return 0;
}
void setFloatMode(std::uint64_t) {}
#endif

} // namespace tumble
