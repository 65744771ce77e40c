#pragma once
// The state hash: 64 bits over the simulated bytes of a world, fed in a fixed order. It only has to tell
// states apart (replays compare it frame by frame), not resist attack, and it has to be cheap enough to
// run every frame over a million particles: so 8 bytes at a time, a multiply-rotate mix per word and a
// splitmix64 finaliser. Our own, since no packaged library offers a small streaming 64-bit hash.

#include <cstdint>
#include <cstring>
#include <string_view>
#include <type_traits>
#include <vector>

namespace tumble {

/// Streaming 64-bit hash of bytes; see the header comment.
class Hasher {
public:
    explicit Hasher(std::uint64_t seed = 0x6a09e667f3bcc908ull) : m_h(seed) {}

    void bytes(const void* data, std::size_t n) {
        const auto* p = static_cast<const unsigned char*>(data);
        while (n >= 8) {
            std::uint64_t w;
            std::memcpy(&w, p, 8);
            word(w);
            p += 8;
            n -= 8;
        }
        if (n > 0) {
            std::uint64_t w = 0;
            std::memcpy(&w, p, n);
            word(w ^ (std::uint64_t(n) << 56));
        }
    }
    /// A trivially copyable value, by its bytes.
    template <class T>
    void add(const T& v) {
        static_assert(std::is_trivially_copyable_v<T>);
        bytes(&v, sizeof v);
    }
    /// The elements of a vector of trivially copyable values, and its length.
    template <class T>
    void add(const std::vector<T>& v) {
        static_assert(std::is_trivially_copyable_v<T>);
        word(v.size());
        bytes(v.data(), v.size() * sizeof(T));
    }
    void add(std::string_view s) {
        word(s.size());
        bytes(s.data(), s.size());
    }

    std::uint64_t digest() const {
        std::uint64_t z = m_h;
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        return z ^ (z >> 31);
    }

private:
    void word(std::uint64_t w) {
        m_h ^= w * 0x9e3779b97f4a7c15ull;
        m_h = ((m_h << 31) | (m_h >> 33)) * 0xff51afd7ed558ccdull;
    }

    std::uint64_t m_h;
};

} // namespace tumble
