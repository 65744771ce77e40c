#pragma once
// The state hash: XXH3-64 (Debian's libxxhash) over the simulated bytes of a world, fed in a fixed order.
// It only has to tell states apart (replays compare it frame by frame), not resist attack, and it runs
// every frame over everything simulated, a million particles' 32 MB among them. XXH3 with the library's
// run-time choice of vector unit (AVX2 where there is one) gives the same bits on every machine, whatever
// unit computed it. A long run of bytes (kBlockBytes or more) is hashed as the XXH3 digests of its blocks
// of kBlockBytes, in order, after its length: the blocks are hashed on the workers of a pool when the
// Hasher has one, and the result depends on the bytes alone, never on the pool or its thread count.

#include <cstddef>
#include <cstdint>
#include <string_view>
#include <type_traits>
#include <vector>

namespace tumble {

class WorkerPool;

/// Streaming XXH3-64 of bytes: the digest of everything added, in order, as one run of bytes (a run of
/// kBlockBytes or more counting as its length and its blocks' digests; see the header comment).
class Hasher {
public:
    static constexpr std::size_t kBlockBytes = std::size_t(1) << 18;

    /// `pool` (optional) hashes the blocks of long runs side by side; it changes no bit of the digest.
    explicit Hasher(WorkerPool* pool = nullptr);

    void bytes(const void* data, std::size_t n);
    /// A trivially copyable value, by its bytes.
    template <class T>
    void add(const T& v) {
        static_assert(std::is_trivially_copyable_v<T>);
        bytes(&v, sizeof v);
    }
    /// The elements of a vector of trivially copyable values, after its length.
    template <class T>
    void add(const std::vector<T>& v) {
        static_assert(std::is_trivially_copyable_v<T>);
        add(std::uint64_t(v.size()));
        bytes(v.data(), v.size() * sizeof(T));
    }
    /// A string, after its length.
    void add(std::string_view s) {
        add(std::uint64_t(s.size()));
        bytes(s.data(), s.size());
    }

    std::uint64_t digest() const;

    /// The XXH3-64 of one run of bytes (what a Hasher given them alone digests to, for a short run).
    static std::uint64_t of(const void* data, std::size_t n);

private:
    void blocks(const unsigned char* data, std::size_t n);

    WorkerPool* m_pool;
    // XXH3_state_t, kept out of this header so that the engine's headers need no xxhash.h (hash.cpp checks
    // the size and alignment)
    alignas(64) unsigned char m_state[576];
};

} // namespace tumble
