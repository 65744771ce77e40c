#pragma once
// Reading one TOML table against its schema. The schema is the sequence of typed reads a loader makes
// (number with a range, integer, choice among names, fixed-size vector, ...): every read names a key as
// known, checks the value's type, range and finiteness, and finish() rejects any key that no read named,
// suggesting the nearest known one. Every failure throws ScenarioError carrying file:line:col of the value
// (or of the --set override that supplied it), so the first problem is what the user sees.

#include "tumble/errors.h"

#include <toml++/toml.h>

#include <array>
#include <cstdint>
#include <initializer_list>
#include <map>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace tumble {

/// The memory cap a scenario is loaded under (README "Resource limits"): 4 GiB unless --memory-cap says.
inline constexpr std::uint64_t kDefaultMemoryCap = 4ull << 30;

/// What the readers of one scenario share: its path, which nodes came from --set overrides, and the memory
/// the scene's components will take, which loaders tally before they allocate.
struct LoadContext {
    std::string file;                                    ///< shown in every message
    std::map<const toml::node*, std::string> overrideOf; ///< node -> the "--set KEY=VALUE" that made it
    std::uint64_t memoryCap = kDefaultMemoryCap;         ///< bytes the whole scene may ask for
    mutable std::uint64_t memoryCharged = 0;             ///< bytes asked for so far

    /// Adds `bytes` (what: "cloth 'curtain' (1225 masses, ...)") to the scene's tally; throws ScenarioError
    /// located at the node, saying how much was asked for, when the tally passes the cap.
    void charge(const toml::node* at, std::uint64_t bytes, const std::string& what) const;

    /// Throws ScenarioError located at the node (or at its override).
    [[noreturn]] void fail(const toml::node* at, const std::string& message) const;
    [[noreturn]] void fail(const toml::source_region& at, const std::string& message) const;
};

/// Limits every scenario obeys, so that no input can exhaust memory or time.
struct Limits {
    static constexpr std::size_t kMaxFileBytes = 16u << 20;   ///< scenario file size
    static constexpr std::size_t kMaxArray = 1u << 20;        ///< elements of any one array
    static constexpr std::size_t kMaxString = 4096;           ///< characters of any one string
    static constexpr std::int64_t kMaxEntities = 100000;      ///< entities after repeat/scatter
    static constexpr std::size_t kMaxLoadedNodes = 50u << 20; ///< component values read, copies included
    static constexpr std::size_t kMaxSetEvents = 256;         ///< set events (each loads the scene twice)
};

/// A size for a message: "1.5 GiB", "320 MiB", "12 KiB".
std::string formatBytes(std::uint64_t bytes);

/// A TOML value on one line, as --set reads it back: numbers to the last bit, strings quoted, arrays and
/// inline tables bracketed (toml++'s own printer breaks long arrays over lines).
std::string oneLineToml(const toml::node& n);

/// Typed reads of one table; see the header comment.
class TableReader {
public:
    /// where: how messages name the table, e.g. "[scene]" or "entity 'bob' [springs]".
    TableReader(const toml::table& table, std::string where, const LoadContext& ctx);

    const toml::table& table() const { return m_table; }
    const std::string& where() const { return m_where; }
    const LoadContext& context() const { return m_ctx; }

    /// True if the key is present (and names it as known).
    bool has(std::string_view key);
    /// The raw node, or nullptr (names the key as known).
    const toml::node* node(std::string_view key);

    /// A finite number in [lo, hi]; integers are accepted.
    double number(std::string_view key, double fallback, double lo, double hi);
    double requiredNumber(std::string_view key, double lo, double hi);
    std::int64_t integer(std::string_view key, std::int64_t fallback, std::int64_t lo, std::int64_t hi);
    bool boolean(std::string_view key, bool fallback);
    std::string string(std::string_view key, std::string fallback);
    std::string requiredString(std::string_view key);
    /// One of the given names.
    std::string choice(std::string_view key, std::string fallback,
                       std::initializer_list<std::string_view> names) {
        return choice(key, std::move(fallback),
                      std::span<const std::string_view>(names.begin(), names.size()));
    }
    std::string choice(std::string_view key, std::string fallback, std::span<const std::string_view> names);
    /// An array of exactly N finite numbers, each in [lo, hi].
    template <std::size_t N>
    std::array<double, N> vector(std::string_view key, std::array<double, N> fallback, double lo, double hi) {
        const toml::node* n = node(key);
        if (!n) {
            return fallback;
        }
        std::array<double, N> out{};
        readNumbers(*n, key, out.data(), N, lo, hi);
        return out;
    }
    /// [min, max] with min <= max, each in [lo, hi]; a single number means min = max.
    std::pair<double, double> range(std::string_view key, std::pair<double, double> fallback, double lo,
                                    double hi);
    /// An array of at most maxLen elements, or nullptr when absent.
    const toml::array* array(std::string_view key, std::size_t maxLen);
    /// A sub-table, or nullptr when absent.
    const toml::table* subtable(std::string_view key);

    /// Fail at a key's value (or at the table when the key is absent).
    [[noreturn]] void fail(std::string_view key, const std::string& message) const;
    /// fail(key, message) for a key checked against others of its table (an air grid's size against its
    /// cells): those of `others` an override gave are named at the end, "(with --set ...)", so that a
    /// message at a line the user did not change says what did.
    [[noreturn]] void failAgainst(std::string_view key, std::initializer_list<std::string_view> others,
                                  const std::string& message) const;
    /// LoadContext::charge, located at the key (or at the table when it is absent).
    void charge(std::string_view key, std::uint64_t bytes, const std::string& what) const;
    /// Fail at a node inside this table.
    [[noreturn]] void failAt(const toml::node& at, const std::string& message) const {
        m_ctx.fail(&at, message);
    }
    /// Reject every key that no read has named.
    void finish() const;

    /// Reads N finite numbers in [lo, hi] from an array node (used for nested arrays, too).
    void readNumbers(const toml::node& n, std::string_view key, double* out, std::size_t count, double lo,
                     double hi) const;

private:
    std::string label(std::string_view key) const;
    void noteKnown(std::string_view key);
    double toNumber(const toml::node& n, std::string_view key, double lo, double hi) const;

    const toml::table& m_table;
    std::string m_where;
    const LoadContext& m_ctx;
    std::vector<std::string> m_known;
};

/// The known name closest to a typo (edit distance at most 2), or "" when none is close.
std::string nearestName(std::string_view typo, const std::vector<std::string>& known);

/// The TOML type of a node, for messages ("a string", "an array", ...).
std::string describeType(const toml::node& n);

} // namespace tumble
