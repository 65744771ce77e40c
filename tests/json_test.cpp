#include "engine/json.h"

#include "engine/random.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstring>
#include <limits>

namespace tumble {
namespace {

TEST(Json, DoublesRoundTripBitForBit) {
    Rng rng(7);
    for (int i = 0; i < 20000; ++i) {
        // random bit patterns cover every exponent; skip the non-finite ones
        std::uint64_t bits = (std::uint64_t(rng.next()) << 32) | rng.next();
        double v;
        std::memcpy(&v, &bits, sizeof v);
        if (!std::isfinite(v)) {
            continue;
        }
        std::string s;
        appendNumber(s, v);
        const double back = std::strtod(s.c_str(), nullptr);
        std::uint64_t backBits;
        std::memcpy(&backBits, &back, sizeof back);
        ASSERT_EQ(backBits, bits) << s;
    }
}

TEST(Json, NonFiniteNumbersAreSpelledOut) {
    std::string s;
    appendNumber(s, std::numeric_limits<double>::quiet_NaN());
    s += ' ';
    appendNumber(s, std::numeric_limits<double>::infinity());
    s += ' ';
    appendNumber(s, -std::numeric_limits<double>::infinity());
    EXPECT_EQ(s, "NaN Infinity -Infinity");
}

TEST(Json, WriterProducesValidNestedJson) {
    std::string out;
    JsonWriter w(out);
    w.beginObject().key("a").value(1).key("b").beginArray().value(0.5).value("x\"y\n").value(true).endArray();
    w.key("c").beginObject().endObject().key("d").numbers({1.0, 2.0, 3.0}).endObject();
    const auto j = nlohmann::json::parse(out);
    EXPECT_EQ(j["a"], 1);
    EXPECT_EQ(j["b"][1], "x\"y\n");
    EXPECT_EQ(j["d"][2], 3.0);
    EXPECT_TRUE(j["c"].empty());
}

TEST(Json, ControlCharactersAreEscaped) {
    std::string out;
    appendJsonString(out, std::string("a\x01z", 3));
    EXPECT_EQ(out, "\"a\\u0001z\"");
}

} // namespace
} // namespace tumble
