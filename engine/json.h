#pragma once
// A small streaming JSON writer for the dump, profile and trace files. Doubles are written in their
// shortest form that reads back to the same bits (std::to_chars); non-finite numbers as NaN, Infinity and
// -Infinity, which the dump format asks for (README, "Using it") so that a blow-up is visible in a dump
// rather than a broken file.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace tumble {

/// Appends the shortest round-tripping text of a double (or NaN / Infinity / -Infinity) to out.
void appendNumber(std::string& out, double v);
/// Appends a JSON string literal, escaped.
void appendJsonString(std::string& out, std::string_view s);

/// Writes JSON into a string, inserting commas itself. Keys and values alternate inside objects.
class JsonWriter {
public:
    explicit JsonWriter(std::string& out) : m_out(out) {}

    JsonWriter& beginObject();
    JsonWriter& endObject();
    JsonWriter& beginArray();
    JsonWriter& endArray();
    JsonWriter& key(std::string_view k);
    JsonWriter& value(double v);
    JsonWriter& value(std::int64_t v);
    JsonWriter& value(std::uint64_t v);
    JsonWriter& value(int v) { return value(static_cast<std::int64_t>(v)); }
    JsonWriter& value(bool v);
    JsonWriter& value(std::string_view s);
    JsonWriter& value(const char* s) { return value(std::string_view(s)); }
    /// An array of numbers.
    JsonWriter& numbers(const double* v, std::size_t n);
    template <std::size_t N>
    JsonWriter& numbers(const double (&v)[N]) {
        return numbers(v, N);
    }

private:
    void separate();

    std::string& m_out;
    std::vector<bool> m_first; ///< per open container: nothing written in it yet
    bool m_afterKey = false;
};

} // namespace tumble
