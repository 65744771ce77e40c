#include "engine/hash.h"

#include <gtest/gtest.h>

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

} // namespace
} // namespace tumble
