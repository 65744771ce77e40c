#include "engine/table_reader.h"

#include "engine/json.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

namespace tumble {

namespace {

std::string formatLocation(const std::string& file, int line, int column) {
    std::string s = file;
    if (line > 0) {
        s += ":" + std::to_string(line);
        if (column > 0) {
            s += ":" + std::to_string(column);
        }
    }
    return s;
}

std::string formatNumber(double v) {
    std::ostringstream os;
    os << v;
    return os.str();
}

std::size_t editDistance(std::string_view a, std::string_view b) {
    std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j) {
        prev[j] = j;
    }
    for (std::size_t i = 1; i <= a.size(); ++i) {
        cur[0] = i;
        for (std::size_t j = 1; j <= b.size(); ++j) {
            const std::size_t subst = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
            cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, subst});
        }
        std::swap(prev, cur);
    }
    return prev[b.size()];
}

} // namespace

ScenarioError::ScenarioError(std::string file, int line, int column, const std::string& message)
    : std::runtime_error(formatLocation(file, line, column) + ": " + message), m_file(std::move(file)),
      m_line(line), m_column(column), m_message(message) {}

std::string formatBytes(std::uint64_t bytes) {
    char text[32];
    if (bytes >= (1ull << 30)) {
        std::snprintf(text, sizeof text, "%.1f GiB", double(bytes) / double(1ull << 30));
    } else if (bytes >= (1ull << 20)) {
        std::snprintf(text, sizeof text, "%.1f MiB", double(bytes) / double(1ull << 20));
    } else {
        std::snprintf(text, sizeof text, "%.1f KiB", double(bytes) / double(1ull << 10));
    }
    return text;
}

void LoadContext::charge(const toml::node* at, std::uint64_t bytes, const std::string& what) const {
    const std::uint64_t before = memoryCharged;
    memoryCharged = before + std::min(bytes, std::numeric_limits<std::uint64_t>::max() - before);
    if (memoryCharged > memoryCap) {
        fail(at, what + " needs about " + formatBytes(bytes) + ", so the scene would need about " +
                     formatBytes(memoryCharged) + ", above the memory cap of " + formatBytes(memoryCap) +
                     " (--memory-cap MiB raises it)");
    }
}

void LoadContext::fail(const toml::node* at, const std::string& message) const {
    if (at) {
        if (auto it = overrideOf.find(at); it != overrideOf.end()) {
            throw ScenarioError(file, 0, 0, it->second + ": " + message);
        }
        // a node parsed from an override carries the override as its source path
        const auto& src = at->source();
        if (src.path && *src.path != file) {
            throw ScenarioError(file, 0, 0, *src.path + ": " + message);
        }
        fail(src, message);
    }
    throw ScenarioError(file, 0, 0, message);
}

void LoadContext::fail(const toml::source_region& at, const std::string& message) const {
    throw ScenarioError(file, static_cast<int>(at.begin.line), static_cast<int>(at.begin.column), message);
}

std::string nearestName(std::string_view typo, const std::vector<std::string>& known) {
    std::string best;
    std::size_t bestDistance = 3;
    if (typo.size() > 64) {
        return best; // no name is that long: nothing to suggest, and no quadratic work on a huge string
    }
    // the same name in other capitals first ("+Y" is '+y', not '+x', one edit away too)
    for (const std::string& k : known) {
        if (k.size() == typo.size() && std::equal(k.begin(), k.end(), typo.begin(), [](char a, char b) {
                return std::tolower(static_cast<unsigned char>(a)) ==
                       std::tolower(static_cast<unsigned char>(b));
            })) {
            return k;
        }
    }
    for (const std::string& k : known) {
        if (k.size() > typo.size() + 2 || typo.size() > k.size() + 2) {
            continue; // more than two edits apart by length alone
        }
        const std::size_t d = editDistance(typo, k);
        if (d < bestDistance) {
            bestDistance = d;
            best = k;
        }
    }
    return best;
}

std::string describeType(const toml::node& n) {
    switch (n.type()) {
    case toml::node_type::table:
        return "a table";
    case toml::node_type::array:
        return "an array";
    case toml::node_type::string:
        return "a string";
    case toml::node_type::integer:
        return "an integer";
    case toml::node_type::floating_point:
        return "a number";
    case toml::node_type::boolean:
        return "a boolean";
    case toml::node_type::date:
        return "a date";
    case toml::node_type::time:
        return "a time";
    case toml::node_type::date_time:
        return "a date-time";
    default:
        return "nothing";
    }
}

TableReader::TableReader(const toml::table& table, std::string where, const LoadContext& ctx)
    : m_table(table), m_where(std::move(where)), m_ctx(ctx) {}

std::string TableReader::label(std::string_view key) const {
    return "'" + std::string(key) + "' in " + m_where;
}

void TableReader::noteKnown(std::string_view key) {
    if (std::find(m_known.begin(), m_known.end(), key) == m_known.end()) {
        m_known.emplace_back(key);
    }
}

bool TableReader::has(std::string_view key) {
    noteKnown(key);
    return m_table.contains(key);
}

const toml::node* TableReader::node(std::string_view key) {
    noteKnown(key);
    return m_table.get(key);
}

void TableReader::fail(std::string_view key, const std::string& message) const {
    const toml::node* n = m_table.get(key);
    m_ctx.fail(n ? n : &m_table, message);
}

void TableReader::failAgainst(std::string_view key, std::initializer_list<std::string_view> others,
                              const std::string& message) const {
    std::string with;
    for (std::string_view other : others) {
        if (auto it = m_ctx.overrideOf.find(m_table.get(other)); it != m_ctx.overrideOf.end()) {
            with += (with.empty() ? " (with " : ", ") + it->second;
        }
    }
    fail(key, with.empty() ? message : message + with + ")");
}

void TableReader::charge(std::string_view key, std::uint64_t bytes, const std::string& what) const {
    const toml::node* n = m_table.get(key);
    m_ctx.charge(n ? n : &m_table, bytes, what);
}

double TableReader::toNumber(const toml::node& n, std::string_view key, double lo, double hi) const {
    if (!n.is_number()) {
        m_ctx.fail(&n, label(key) + " must be a number, not " + describeType(n));
    }
    const double v = n.value<double>().value_or(0.0);
    if (!std::isfinite(v)) {
        m_ctx.fail(&n, label(key) + " must be a finite number");
    }
    if (v < lo || v > hi) {
        m_ctx.fail(&n, label(key) + " is " + formatNumber(v) + ", outside [" + formatNumber(lo) + ", " +
                           formatNumber(hi) + "]");
    }
    return v;
}

double TableReader::number(std::string_view key, double fallback, double lo, double hi) {
    const toml::node* n = node(key);
    return n ? toNumber(*n, key, lo, hi) : fallback;
}

double TableReader::requiredNumber(std::string_view key, double lo, double hi) {
    const toml::node* n = node(key);
    if (!n) {
        m_ctx.fail(&m_table, m_where + " needs '" + std::string(key) + "' (a number)");
    }
    return toNumber(*n, key, lo, hi);
}

std::int64_t TableReader::integer(std::string_view key, std::int64_t fallback, std::int64_t lo,
                                  std::int64_t hi) {
    const toml::node* n = node(key);
    if (!n) {
        return fallback;
    }
    if (!n->is_integer()) {
        m_ctx.fail(n, label(key) + " must be an integer, not " + describeType(*n));
    }
    const std::int64_t v = n->value<std::int64_t>().value_or(0);
    if (v < lo || v > hi) {
        m_ctx.fail(n, label(key) + " is " + std::to_string(v) + ", outside [" + std::to_string(lo) + ", " +
                          std::to_string(hi) + "]");
    }
    return v;
}

bool TableReader::boolean(std::string_view key, bool fallback) {
    const toml::node* n = node(key);
    if (!n) {
        return fallback;
    }
    if (!n->is_boolean()) {
        m_ctx.fail(n, label(key) + " must be true or false, not " + describeType(*n));
    }
    return n->value<bool>().value_or(fallback);
}

std::string TableReader::string(std::string_view key, std::string fallback) {
    const toml::node* n = node(key);
    if (!n) {
        return fallback;
    }
    if (!n->is_string()) {
        m_ctx.fail(n, label(key) + " must be a string, not " + describeType(*n));
    }
    std::string s = n->value<std::string>().value_or("");
    if (s.size() > Limits::kMaxString) {
        m_ctx.fail(n, label(key) + " is longer than " + std::to_string(Limits::kMaxString) + " characters");
    }
    return s;
}

std::string TableReader::requiredString(std::string_view key) {
    if (!m_table.contains(key)) {
        noteKnown(key);
        m_ctx.fail(&m_table, m_where + " needs '" + std::string(key) + "' (a string)");
    }
    return string(key, "");
}

std::string TableReader::choice(std::string_view key, std::string fallback,
                                std::span<const std::string_view> names) {
    const std::string s = string(key, fallback);
    for (std::string_view n : names) {
        if (s == n) {
            return s;
        }
    }
    std::string list;
    std::vector<std::string> known;
    for (std::string_view n : names) {
        list += (list.empty() ? "" : ", ") + std::string(n);
        known.emplace_back(n);
    }
    const std::string near = nearestName(s, known);
    fail(key, label(key) + " is '" + s + "'; expected one of: " + list +
                  (near.empty() ? "" : " (did you mean '" + near + "'?)"));
}

void TableReader::readNumbers(const toml::node& n, std::string_view key, double* out, std::size_t count,
                              double lo, double hi) const {
    const toml::array* a = n.as_array();
    if (!a || a->size() != count) {
        m_ctx.fail(&n, label(key) + " must be an array of " + std::to_string(count) + " numbers" +
                           (a ? ", not " + std::to_string(a->size()) : ", not " + describeType(n)));
    }
    for (std::size_t i = 0; i < count; ++i) {
        out[i] = toNumber(*a->get(i), key, lo, hi);
    }
}

std::pair<double, double> TableReader::range(std::string_view key, std::pair<double, double> fallback,
                                             double lo, double hi) {
    const toml::node* n = node(key);
    if (!n) {
        return fallback;
    }
    if (n->is_number()) {
        const double v = toNumber(*n, key, lo, hi);
        return {v, v};
    }
    double v[2];
    readNumbers(*n, key, v, 2, lo, hi);
    if (v[0] > v[1]) {
        m_ctx.fail(n, label(key) + " is a range [min, max] and its min " + formatNumber(v[0]) +
                          " is above its max " + formatNumber(v[1]));
    }
    return {v[0], v[1]};
}

const toml::array* TableReader::array(std::string_view key, std::size_t maxLen) {
    const toml::node* n = node(key);
    if (!n) {
        return nullptr;
    }
    const toml::array* a = n->as_array();
    if (!a) {
        m_ctx.fail(n, label(key) + " must be an array, not " + describeType(*n));
    }
    if (a->size() > maxLen) {
        m_ctx.fail(n, label(key) + " has " + std::to_string(a->size()) + " elements; at most " +
                          std::to_string(maxLen) + " are allowed");
    }
    return a;
}

const toml::table* TableReader::subtable(std::string_view key) {
    const toml::node* n = node(key);
    if (!n) {
        return nullptr;
    }
    const toml::table* t = n->as_table();
    if (!t) {
        m_ctx.fail(n, label(key) + " must be a table, not " + describeType(*n));
    }
    return t;
}

void TableReader::finish() const {
    for (auto&& [k, v] : m_table) {
        const std::string_view key = k.str();
        if (std::find(m_known.begin(), m_known.end(), key) != m_known.end()) {
            continue;
        }
        const std::string near = nearestName(key, m_known);
        std::string msg = "unknown key '" + std::string(key) + "' in " + m_where;
        if (!near.empty()) {
            msg += " (did you mean '" + near + "'?)";
        } else if (!m_known.empty()) {
            std::string list;
            for (const std::string& s : m_known) {
                list += (list.empty() ? "" : ", ") + s;
            }
            msg += "; known keys: " + list;
        }
        m_ctx.fail(&v, msg);
    }
}

std::string oneLineToml(const toml::node& n) {
    if (const auto* a = n.as_array()) {
        std::string out = "[";
        for (std::size_t i = 0; i < a->size(); ++i) {
            out += (i ? ", " : "") + oneLineToml(*a->get(i));
        }
        return out + "]";
    }
    if (const auto* t = n.as_table()) {
        std::string out = "{";
        bool first = true;
        for (const auto& [k, v] : *t) {
            std::ostringstream name;
            name << toml::value<std::string>(std::string(k.str()));
            out += (first ? " " : ", ") + name.str() + " = " + oneLineToml(v);
            first = false;
        }
        return out + (first ? "}" : " }");
    }
    if (const auto* d = n.as_floating_point()) {
        const double v = d->get();
        if (!std::isfinite(v)) {
            return std::isnan(v) ? "nan" : v > 0.0 ? "inf" : "-inf";
        }
        // the shortest text that reads back to the same double (1.1, not 1.1000000000000001)
        std::string out;
        appendNumber(out, v);
        if (out.find_first_of(".eE") == std::string::npos) {
            out += ".0"; // still a float
        }
        return out;
    }
    std::ostringstream text;
    n.visit([&](auto&& v) { text << v; });
    return text.str();
}

} // namespace tumble
