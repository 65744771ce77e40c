#include "engine/simd.h"

#include <atomic>
#include <cstdlib>
#include <cstring>

namespace tumble {

namespace {

Simd fromEnvironment() {
    const char* env = std::getenv("TUMBLE_SIMD");
    if (env && std::strcmp(env, "sse2") == 0) {
        return Simd::Sse2;
    }
    return avx2Available() ? Simd::Avx2 : Simd::Sse2;
}

std::atomic<Simd>& active() {
    static std::atomic<Simd> simd{fromEnvironment()};
    return simd;
}

} // namespace

const char* simdEnvironmentError() {
    const char* env = std::getenv("TUMBLE_SIMD");
    if (!env || !*env || std::strcmp(env, "sse2") == 0 || std::strcmp(env, "avx2") == 0) {
        return "";
    }
    return "TUMBLE_SIMD must be sse2 or avx2 (or unset: the widest the processor has)";
}

bool avx2Available() {
#if defined(__x86_64__) || defined(_M_X64)
    return __builtin_cpu_supports("avx2");
#else
    return false;
#endif
}

Simd activeSimd() {
    return active().load(std::memory_order_relaxed);
}

void forceSimd(Simd simd) {
    active().store(simd == Simd::Avx2 && !avx2Available() ? Simd::Sse2 : simd, std::memory_order_relaxed);
}

} // namespace tumble
