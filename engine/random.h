#pragma once
// Random streams. Every random choice in a scene comes from a stream seeded from the scene seed and a name
// for its purpose, so adding a stream for one thing never shifts the numbers another thing sees.
// PCG32 (O'Neill 2014): small state, good statistics, and its state is plain bytes to hash and save.

#include <cstdint>
#include <string_view>

namespace tumble {

/// Seed for the stream that serves one purpose (e.g. "emitter:fountain") of a scene with the given seed.
constexpr std::uint64_t streamSeed(std::uint64_t sceneSeed, std::string_view purpose) {
    // FNV-1a over the purpose, then mixed with the scene seed by splitmix64's finaliser
    std::uint64_t h = 0xcbf29ce484222325ull;
    for (char c : purpose) {
        h = (h ^ static_cast<unsigned char>(c)) * 0x100000001b3ull;
    }
    std::uint64_t z = h ^ (sceneSeed + 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

/// PCG32 random stream (XSH RR output).
struct Rng {
    std::uint64_t state = 0; ///< the generator's whole state
    std::uint64_t inc = 1;   ///< stream selector, always odd

    Rng() = default;
    explicit Rng(std::uint64_t seed, std::uint64_t stream = 0x14057b7ef767814full) {
        inc = (stream << 1u) | 1u;
        next();
        state += seed;
        next();
    }
    std::uint32_t next() {
        const std::uint64_t old = state;
        state = old * 6364136223846793005ull + inc;
        const auto xorshifted = static_cast<std::uint32_t>(((old >> 18u) ^ old) >> 27u);
        const auto rot = static_cast<std::uint32_t>(old >> 59u);
        return (xorshifted >> rot) | (xorshifted << ((32u - rot) & 31u));
    }
    /// Uniform in [0, 1), 53 bits.
    double uniform() {
        const std::uint64_t hi = next() >> 5, lo = next() >> 6;
        return static_cast<double>((hi << 26) | lo) * (1.0 / 9007199254740992.0);
    }
    /// Uniform in [lo, hi).
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
};

} // namespace tumble
