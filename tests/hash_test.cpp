#include "engine/hash.h"

#include "engine/parallel.h"

#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <set>

namespace tumble {
namespace {

std::uint64_t hashOf(const std::vector<double>& v) {
    Hasher h;
    h.add(v);
    return h.digest();
}

TEST(Hasher, EqualInputsEqualHashes) {
    EXPECT_EQ(hashOf({1.0, 2.0, 3.0}), hashOf({1.0, 2.0, 3.0}));
}

TEST(Hasher, OrderLengthAndEveryBitMatter) {
    EXPECT_NE(hashOf({1.0, 2.0}), hashOf({2.0, 1.0}));
    EXPECT_NE(hashOf({0.0}), hashOf({0.0, 0.0})) << "lengths are hashed";
    EXPECT_NE(hashOf({0.0}), hashOf({-0.0})) << "bits, not values";
    // every single-bit change of a 64-byte input gives a distinct hash
    std::vector<unsigned char> bytes(64, 0);
    std::set<std::uint64_t> seen;
    Hasher base;
    base.bytes(bytes.data(), bytes.size());
    seen.insert(base.digest());
    for (std::size_t bit = 0; bit < bytes.size() * 8; ++bit) {
        bytes[bit / 8] ^= static_cast<unsigned char>(1u << (bit % 8));
        Hasher h;
        h.bytes(bytes.data(), bytes.size());
        seen.insert(h.digest());
        bytes[bit / 8] ^= static_cast<unsigned char>(1u << (bit % 8));
    }
    EXPECT_EQ(seen.size(), 64u * 8u + 1u);
}

TEST(Hasher, TailBytesCount) {
    const unsigned char a[3] = {1, 2, 3}, b[3] = {1, 2, 4};
    Hasher ha, hb, hc;
    ha.bytes(a, 3);
    hb.bytes(b, 3);
    hc.bytes(a, 2);
    EXPECT_NE(ha.digest(), hb.digest());
    EXPECT_NE(ha.digest(), hc.digest());
}

// XXH3-64 with seed 0 of inputs of 1 to 3 bytes, written from the algorithm's definition (the first eight
// bytes of its default secret, XXH64's avalanche), independent of the library the Hasher calls
std::uint64_t xxh3Short(const unsigned char* in, std::size_t len) {
    const std::uint32_t combined = (std::uint32_t(in[0]) << 16) | (std::uint32_t(in[len >> 1]) << 24) |
                                   std::uint32_t(in[len - 1]) | (std::uint32_t(len) << 8);
    const std::uint64_t bitflip =
        std::uint64_t(0x396cfeb8u ^ 0xbe4ba423u); // LE32 of b8 fe 6c 39, 23 a4 4b be
    std::uint64_t h = combined ^ bitflip;
    h ^= h >> 33;
    h *= 0xC2B2AE3D27D4EB4Full;
    h ^= h >> 29;
    h *= 0x165667B19E3779F9ull;
    h ^= h >> 32;
    return h;
}

TEST(Hasher, IsXxh3Of64BitsWithSeedZero) {
    // the published digest of no input, and short inputs against the algorithm's definition: the state
    // hash is XXH3-64 as CONTRACT.md says, the same bits on any machine and any vector unit
    EXPECT_EQ(Hasher().digest(), 0x2D06800538D394C2ull);
    for (unsigned a = 0; a < 256; ++a) {
        for (std::size_t len = 1; len <= 3; ++len) {
            const unsigned char in[3] = {static_cast<unsigned char>(a), static_cast<unsigned char>(a * 7 + 1),
                                         static_cast<unsigned char>(255 - a)};
            Hasher h;
            h.bytes(in, len);
            ASSERT_EQ(h.digest(), xxh3Short(in, len)) << "byte " << a << ", length " << len;
        }
    }
}

TEST(Hasher, PiecesHashAsTheirConcatenation) {
    // a stream fed in pieces of every awkward size (inside the internal buffer, across it, across a stripe
    // block, a whole large block) digests to the one-shot hash of the same bytes: what lets a codec feed an
    // entity's arrays one after another
    std::vector<unsigned char> data(300'000);
    std::mt19937 rng(7);
    for (unsigned char& c : data) {
        c = static_cast<unsigned char>(rng());
    }
    for (const std::size_t piece : {1u, 3u, 8u, 63u, 257u, 1024u, 4093u, 100'000u}) {
        Hasher h;
        for (std::size_t at = 0; at < data.size(); at += piece) {
            h.bytes(data.data() + at, std::min(piece, data.size() - at));
        }
        EXPECT_EQ(h.digest(), Hasher::of(data.data(), data.size())) << "pieces of " << piece;
    }
    // a copy taken mid-stream carries on as the original does
    Hasher a;
    a.bytes(data.data(), 1000);
    Hasher b = a;
    a.bytes(data.data() + 1000, 5000);
    b.bytes(data.data() + 1000, 5000);
    EXPECT_EQ(a.digest(), b.digest());
    EXPECT_EQ(a.digest(), Hasher::of(data.data(), 6000));
}

TEST(Hasher, LongRunsAreTheirBlocksDigestsWhateverThePool) {
    // a run of kBlockBytes or more is its length and its blocks' one-shot digests, in order: the same bits
    // without a pool and on pools of 1 to 8 threads (a block digest stored at the wrong place, a batch
    // boundary lost or the last partial block cut would each change it)
    const std::size_t n = Hasher::kBlockBytes * 70 + 12'345; // more blocks than a batch, a partial last one
    std::vector<unsigned char> data(n);
    std::mt19937 rng(11);
    for (unsigned char& c : data) {
        c = static_cast<unsigned char>(rng());
    }
    std::vector<std::uint64_t> expected;
    for (std::size_t at = 0; at < n; at += Hasher::kBlockBytes) {
        expected.push_back(Hasher::of(data.data() + at, std::min(Hasher::kBlockBytes, n - at)));
    }
    Hasher reference;
    reference.add(std::uint8_t(1));
    reference.add(std::uint64_t(n));
    reference.bytes(expected.data(), expected.size() * sizeof(std::uint64_t));
    const auto hashWith = [&](WorkerPool* pool) {
        Hasher h(pool);
        h.add(std::uint8_t(1));
        h.bytes(data.data(), n);
        return h.digest();
    };
    EXPECT_EQ(hashWith(nullptr), reference.digest());
    for (const int threads : {1, 2, 3, 8}) {
        WorkerPool pool(threads);
        EXPECT_EQ(hashWith(&pool), reference.digest()) << threads << " threads";
    }
    data[n - 1] ^= 1;
    EXPECT_NE(hashWith(nullptr), reference.digest()) << "the last partial block counts";
    // the shortest long run, one block, and the longest short one, plain XXH3
    const std::uint64_t one[2] = {Hasher::kBlockBytes, Hasher::of(data.data(), Hasher::kBlockBytes)};
    Hasher exact, oneBlock, shorter;
    exact.bytes(data.data(), Hasher::kBlockBytes);
    oneBlock.bytes(one, sizeof one);
    shorter.bytes(data.data(), Hasher::kBlockBytes - 1);
    EXPECT_EQ(exact.digest(), oneBlock.digest());
    EXPECT_EQ(shorter.digest(), Hasher::of(data.data(), Hasher::kBlockBytes - 1));
}

} // namespace
} // namespace tumble
