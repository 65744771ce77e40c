#include "engine/hash.h"

#include "engine/parallel.h"

#include <array>
#include <new>

#define XXH_STATIC_LINKING_ONLY // XXH3_state_t's layout, to keep it inside the Hasher
#include <xxhash.h>
#if defined(__x86_64__) || defined(_M_X64)
// the library's entry points that pick SSE2, AVX2 or AVX-512 at run time; the same result from each
#include <xxh_x86dispatch.h>
#define TUMBLE_XXH3_UPDATE XXH3_64bits_update_dispatch
#define TUMBLE_XXH3_ONESHOT XXH3_64bits_dispatch
#else
#define TUMBLE_XXH3_UPDATE XXH3_64bits_update
#define TUMBLE_XXH3_ONESHOT XXH3_64bits
#endif

namespace tumble {

namespace {

static_assert(sizeof(XXH3_state_t) <= 576 && alignof(XXH3_state_t) <= 64,
              "Hasher::m_state must hold an XXH3_state_t");

XXH3_state_t* state(unsigned char* storage) {
    return std::launder(reinterpret_cast<XXH3_state_t*>(storage));
}

const XXH3_state_t* state(const unsigned char* storage) {
    return std::launder(reinterpret_cast<const XXH3_state_t*>(storage));
}

} // namespace

Hasher::Hasher(WorkerPool* pool) : m_pool(pool) {
    new (m_state) XXH3_state_t; // a plain C struct: its bytes are set by the reset
    XXH3_64bits_reset(state(m_state));
}

void Hasher::bytes(const void* data, std::size_t n) {
    if (n >= kBlockBytes) {
        blocks(static_cast<const unsigned char*>(data), n);
    } else if (n > 0) {
        TUMBLE_XXH3_UPDATE(state(m_state), data, n);
    }
}

void Hasher::blocks(const unsigned char* data, std::size_t n) {
    const std::size_t count = WorkerPool::chunkCount(n, kBlockBytes);
    // a million particles' arrays are 16 blocks each; longer runs take their digests a batch at a time
    constexpr std::size_t kBatch = 64;
    std::array<std::uint64_t, kBatch> digests;
    const std::uint64_t length = n;
    TUMBLE_XXH3_UPDATE(state(m_state), &length, sizeof length);
    for (std::size_t first = 0; first < count; first += kBatch) {
        const std::size_t batch = std::min(kBatch, count - first);
        const auto one = [&](std::size_t i) {
            const std::size_t at = (first + i) * kBlockBytes;
            digests[i] = TUMBLE_XXH3_ONESHOT(data + at, std::min(kBlockBytes, n - at));
        };
        if (m_pool) {
            m_pool->forEach(batch, 1, one);
        } else {
            for (std::size_t i = 0; i < batch; ++i) {
                one(i);
            }
        }
        TUMBLE_XXH3_UPDATE(state(m_state), digests.data(), batch * sizeof(std::uint64_t));
    }
}

std::uint64_t Hasher::digest() const {
    return XXH3_64bits_digest(state(m_state));
}

std::uint64_t Hasher::of(const void* data, std::size_t n) {
    return TUMBLE_XXH3_ONESHOT(data, n);
}

} // namespace tumble
