// Reading a sweep file and laying out its cases (app/sweep.h).

#include "app/cli.h"
#include "app/sweep.h"
#include "engine/dump.h"
#include "engine/hash.h"
#include "engine/json.h"
#include "engine/name.h"
#include "engine/parallel.h"
#include "engine/random.h"
#include "engine/scenario.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>

namespace tumble {

namespace fs = std::filesystem;

namespace {

/// More cases than this is a typo in a count, not a sweep (each case is at least one process).
constexpr std::size_t kMaxCases = 1'000'000;

/// The columns results.csv always has; a metric may not take one of their names.
const std::vector<std::string> kFixedColumns = {
    "case", "status", "exit_code", "physics_p50_ms", "physics_p99_ms", "physics_max_ms", "hash", "detail"};

std::string numberText(double v, bool integer) {
    if (integer) {
        return std::to_string(static_cast<std::int64_t>(std::llround(v)));
    }
    std::string s;
    appendNumber(s, v);
    // the shortest text that reads back (0.2), still a TOML float
    if (s.find_first_not_of("-0123456789") == std::string::npos) {
        s += ".0";
    }
    return s;
}

/// Whether a value is, or holds, a number that is not finite (TOML's nan and inf): no key takes one.
bool nonFinite(const toml::node& v) {
    if (v.is_floating_point()) {
        return !std::isfinite(v.value_or(0.0));
    }
    if (const toml::array* a = v.as_array()) {
        return std::any_of(a->begin(), a->end(), [](const toml::node& n) { return nonFinite(n); });
    }
    if (const toml::table* t = v.as_table()) {
        return std::any_of(t->begin(), t->end(), [](const auto& entry) { return nonFinite(entry.second); });
    }
    return false;
}

void addValue(SweepAxis& axis, const toml::node& v) {
    if (v.is_floating_point()) {
        axis.values.push_back(numberText(v.value_or(0.0), false));
        axis.display.push_back(axis.values.back());
        return;
    }
    axis.values.push_back(oneLineToml(v));
    axis.display.push_back(v.is_string() ? std::string(**v.as_string()) : oneLineToml(v));
}

void addNumber(SweepAxis& axis, double v, bool integer) {
    axis.values.push_back(numberText(v, integer));
    axis.display.push_back(axis.values.back());
}

/// range = [lo, hi, n] or log_range = [lo, hi, n]: n values evenly spaced (in the log for log_range);
/// rounded to whole numbers when the axis says `integer = true` (a count of rows, say).
void readRange(TableReader& r, std::string_view key, SweepAxis& axis, bool log, bool integer) {
    const toml::array* a = r.array(key, 3);
    if (!a || a->size() != 3 || !a->get(2)->is_integer()) {
        r.fail(key, std::string(key) + " is [lo, hi, count], count a whole number");
    }
    double ends[2];
    for (int i = 0; i < 2; ++i) {
        const toml::node& n = *a->get(std::size_t(i));
        if (!n.is_number() || !std::isfinite(n.value_or(0.0)) || (log && !(n.value_or(0.0) > 0.0))) {
            r.failAt(n, std::string(key) + "'s ends are finite numbers" + (log ? ", above zero" : ""));
        }
        ends[i] = n.value_or(0.0);
    }
    const std::int64_t n = **a->get(2)->as_integer();
    axis.generated = true;
    if (n < 1 || n > std::int64_t(kMaxCases)) {
        r.fail(key, "the count must be from 1 to " + std::to_string(kMaxCases));
    }
    for (std::int64_t i = 0; i < n; ++i) {
        // (lo (n-1-i) + hi i) / (n-1) rather than lo + i (hi-lo)/(n-1): [0.1, 0.5, 3] gives 0.3, not
        // 0.30000000000000004
        const double w = double(n - 1 - i), u = double(i), d = n == 1 ? 1.0 : double(n - 1);
        const double v = log ? std::exp((std::log(ends[0]) * w + std::log(ends[1]) * u) / d)
                             : (ends[0] * w + ends[1] * u) / d;
        // the ends are themselves, not their rounding through the logarithm
        addNumber(axis, i == 0 ? ends[0] : i == n - 1 ? ends[1] : v, integer);
    }
    axis.logScale = log;
}

/// random = { min, max, count }: uniform draws from a stream of the sweep's seed and the axis's key (whole
/// numbers from min to max, each as likely, when the axis says `integer = true`).
void readRandom(TableReader& r, SweepAxis& axis, std::uint64_t seed, bool integer, const LoadContext& ctx) {
    const toml::table* t = r.subtable("random");
    TableReader rr(*t, "the random of axis '" + axis.key + "'", ctx);
    const double lo = rr.requiredNumber("min", -1e300, 1e300);
    const double hi = rr.requiredNumber("max", lo, 1e300);
    const std::int64_t n = rr.integer("count", 0, 1, std::int64_t(kMaxCases));
    if (!rr.has("count")) {
        rr.fail("count", "random needs a count");
    }
    rr.finish();
    // whole numbers: each of those from min to max as likely
    const double first = std::ceil(lo), last = std::floor(hi);
    if (integer && first > last) {
        rr.fail("min", "no whole number lies from min to max");
    }
    axis.generated = true;
    Rng rng(streamSeed(seed, "sweep axis:" + axis.key));
    for (std::int64_t i = 0; i < n; ++i) {
        const double u = rng.uniform();
        addNumber(axis,
                  integer ? std::min(last, std::floor(first + u * (last - first + 1.0))) : lo + u * (hi - lo),
                  integer);
    }
}

SweepAxis readAxis(const toml::table& t, std::size_t i, std::uint64_t seed, const LoadContext& ctx) {
    SweepAxis axis;
    const toml::node* at = t.get("key") ? t.get("key") : &t;
    axis.line = int(at->source().begin.line);
    axis.column = int(at->source().begin.column);
    TableReader r(t, "[[axis]] " + std::to_string(i + 1), ctx);
    axis.key = r.requiredString("key");
    if (axis.key.empty() || axis.key.find('=') != std::string::npos ||
        axis.key.find('.') == std::string::npos) {
        r.fail("key", "the key is what --set takes before '=', e.g. \"chain.rope.stiffness\"");
    }
    if (axis.key == "scene.frames") {
        r.fail("key",
               "every case runs the sweep's own 'frames': an axis on scene.frames would change nothing "
               "(sweeps of their own for other lengths)");
    }
    const bool integer = r.boolean("integer", false);
    const int kinds =
        int(r.has("values")) + int(r.has("range")) + int(r.has("log_range")) + int(r.has("random"));
    r.finish();
    if (kinds != 1) {
        r.fail(kinds ? "range" : "key", "an axis takes exactly one of values, range, log_range or random");
    }
    if (const toml::array* a = r.array("values", kMaxCases)) {
        if (a->empty()) {
            r.fail("values", "values is empty");
        }
        if (integer) {
            r.fail("integer",
                   "integer = true rounds a range's or random's values: listed values are as written");
        }
        for (const toml::node& v : *a) {
            if (nonFinite(v)) {
                r.failAt(v, "values: " + oneLineToml(v) + " is not finite: no key takes nan or inf");
            }
            addValue(axis, v);
        }
    }
    for (std::string_view key : {"range", "log_range"}) {
        if (r.has(key)) {
            readRange(r, key, axis, key == "log_range", integer);
            // rounded to whole numbers, a range of more values than whole numbers in it repeats cases
            for (std::size_t v = 1; integer && v < axis.values.size(); ++v) {
                if (axis.values[v] == axis.values[v - 1]) {
                    r.fail(key,
                           std::string(key) + " with integer = true gives " + axis.values[v] +
                               " more than once: the same case again; ask for fewer values or a wider range");
                }
            }
        }
    }
    if (r.has("random")) {
        readRandom(r, axis, seed, integer, ctx);
    }
    return axis;
}

SweepMetric readMetric(const toml::table& t, std::size_t i, const LoadContext& ctx) {
    SweepMetric m;
    m.line = int(t.source().begin.line);
    m.column = int(t.source().begin.column);
    TableReader r(t, "[[metric]] " + std::to_string(i + 1), ctx);
    m.name = r.requiredString("name");
    if (m.name.empty()) {
        r.fail("name", "a metric's name is its column's heading: it must not be empty");
    }
    if (m.name.find_first_of(",\"\n\r") != std::string::npos) {
        r.fail("name", "a metric's name is its column: no commas, quotes or line breaks");
    }
    m.entity = r.requiredString("entity");
    m.field = r.choice("field", "x", {"x", "v", "count", "h"});
    m.index = r.integer("index", -1, -1, std::int64_t(1) << 40);
    m.component = int(r.integer("component", 0, 0, 2));
    r.finish();
    return m;
}

/// The scenario: a path (it has a '/' or ends in .toml) relative to the sweep file, else a demo's name.
std::string findScenario(const std::string& sweepFile, const std::string& given) {
    const bool looksLikePath = given.find('/') != std::string::npos || fs::path(given).extension() == ".toml";
    if (!looksLikePath) {
        return fs::absolute(resolveScenario(given)).lexically_normal().string();
    }
    const fs::path path =
        fs::path(given).is_absolute() ? fs::path(given) : fs::path(sweepFile).parent_path() / given;
    return fs::absolute(path).lexically_normal().string();
}

void readSweepTable(const toml::table& root, const LoadContext& ctx, Sweep& s) {
    const toml::table* t = root["sweep"].as_table();
    if (!t) {
        throw ScenarioError(s.path, 0, 0, "no [sweep] table: it names the scenario to sweep");
    }
    TableReader r(*t, "[sweep]", ctx);
    const std::string scenario = r.requiredString("scenario");
    try {
        s.scenarioPath = findScenario(s.file, scenario);
        s.scenarioText = readScenarioFile(s.scenarioPath);
    } catch (const ScenarioError& e) {
        r.fail("scenario", e.what());
    }
    // left out, the scene's own frames (0 here); given, at least one (0 read as the scene's whole length,
    // where `tumble run --frames 0` runs none)
    s.frames = r.has("frames") ? r.integer("frames", 1, 1, 1'000'000'000) : 0;
    s.threads = int(r.integer("threads", 1, 1, kMaxThreads));
    s.repeats = int(r.integer("repeats", 1, 1, 1000));
    s.zip = r.choice("combine", "grid", {"grid", "zip"}) == "zip";
    s.seed = std::uint64_t(r.integer("seed", 1, 0, std::numeric_limits<std::int64_t>::max()));
    s.timeout = r.number("timeout", 0.0, 0.0, 1e7);
    r.finish();
}

void checkNames(const Sweep& s) {
    std::set<std::string> taken(kFixedColumns.begin(), kFixedColumns.end());
    for (const SweepAxis& a : s.axes) {
        if (!taken.insert(a.key).second) {
            throw ScenarioError(s.path, a.line, a.column, "axis '" + a.key + "' is given twice");
        }
    }
    for (const SweepMetric& m : s.metrics) {
        if (!taken.insert(m.name).second) {
            throw ScenarioError(s.path, m.line, m.column,
                                "metric '" + m.name +
                                    "': the name is taken (by another metric, an axis or "
                                    "one of results.csv's own columns)");
        }
    }
}

void checkCaseCount(const Sweep& s) {
    if (s.zip) {
        for (const SweepAxis& a : s.axes) {
            if (a.values.size() != s.axes.front().values.size()) {
                throw ScenarioError(s.path, a.line, a.column,
                                    "combine = \"zip\" needs axes of one length: '" + a.key + "' has " +
                                        std::to_string(a.values.size()) + " values, '" + s.axes.front().key +
                                        "' " + std::to_string(s.axes.front().values.size()));
            }
        }
        return;
    }
    double product = 1.0;
    for (const SweepAxis& a : s.axes) {
        product *= double(a.values.size());
    }
    if (product > double(kMaxCases)) {
        char count[32];
        std::snprintf(count, sizeof count, "%.3g", product);
        throw ScenarioError(s.path, s.axes.back().line, s.axes.back().column,
                            std::string("the axes make ") + count + " cases; at most " +
                                std::to_string(kMaxCases));
    }
}

} // namespace

std::size_t Sweep::caseCount() const {
    if (axes.empty()) {
        return 1;
    }
    if (zip) {
        return axes.front().values.size();
    }
    std::size_t n = 1;
    for (const SweepAxis& a : axes) {
        n *= a.values.size();
    }
    return n;
}

std::vector<std::size_t> Sweep::caseValueIndices(std::size_t c) const {
    std::vector<std::size_t> at(axes.size(), c);
    if (!zip) {
        // the last axis fastest, as nested loops in the file's order
        for (std::size_t i = axes.size(); i-- > 0;) {
            at[i] = c % axes[i].values.size();
            c /= axes[i].values.size();
        }
    }
    return at;
}

std::vector<std::string> Sweep::caseSets(std::size_t c) const {
    const std::vector<std::size_t> at = caseValueIndices(c);
    std::vector<std::string> sets;
    for (std::size_t i = 0; i < axes.size(); ++i) {
        sets.push_back(axes[i].key + "=" + axes[i].values[at[i]]);
    }
    return sets;
}

Sweep readSweep(const std::string& path) {
    Sweep s;
    s.path = path;
    s.file = fs::absolute(path).lexically_normal().string();
    s.name = fs::path(path).stem().string();
    const std::string text = readScenarioFile(path, "the sweep file");
    const toml::table root = parseToml(path, text);
    LoadContext ctx;
    ctx.file = path;
    for (auto&& [k, v] : root) {
        if (k.str() != "sweep" && k.str() != "axis" && k.str() != "metric") {
            const std::string near = nearestName(k.str(), {"sweep", "axis", "metric"});
            ctx.fail(&v, "unknown top-level key '" + std::string(k.str()) + "'" +
                             (near.empty() ? "; a sweep file has [sweep], [[axis]] and [[metric]]"
                                           : " (did you mean '" + near + "'?)"));
        }
    }
    readSweepTable(root, ctx, s);
    auto tables = [&](const char* key, auto read) {
        if (const toml::node* n = root.get(key)) {
            const toml::array* a = n->as_array();
            if (!a || !a->is_array_of_tables()) {
                ctx.fail(n, std::string("'") + key + "' is a list of tables: [[" + key + "]]");
            }
            for (std::size_t i = 0; i < a->size(); ++i) {
                read(*a->get(i)->as_table(), i);
            }
        }
    };
    tables("axis",
           [&](const toml::table& t, std::size_t i) { s.axes.push_back(readAxis(t, i, s.seed, ctx)); });
    tables("metric",
           [&](const toml::table& t, std::size_t i) { s.metrics.push_back(readMetric(t, i, ctx)); });
    checkNames(s);
    checkCaseCount(s);
    return s;
}

namespace {

/// The values of an axis worth loading the scenario with: every listed one, a range's or draw's ends.
std::vector<std::size_t> valuesToCheck(const SweepAxis& a) {
    std::vector<std::size_t> at;
    std::set<std::string> seen;
    for (std::size_t i = 0; i < a.values.size(); ++i) {
        if (seen.insert(a.values[i]).second) {
            at.push_back(i);
        }
    }
    if (a.generated && at.size() > 16) {
        // a long generated axis: its least and greatest value stand for it (a range's ends)
        auto [lo, hi] = std::minmax_element(a.values.begin(), a.values.end(), [](auto& x, auto& y) {
            return std::strtod(x.c_str(), nullptr) < std::strtod(y.c_str(), nullptr);
        });
        at = {std::size_t(lo - a.values.begin()), std::size_t(hi - a.values.begin())};
    }
    return at;
}

} // namespace

/// Each metric read from the scenario's first state as it will be from each case's last: one that finds
/// no entity, no such field, index or component is refused now rather than an empty column later.
void checkMetrics(const Catalog& catalog, const Sweep& s, World& world) {
    std::set<std::string> names;
    world.view<const Name>().each([&](Entity, const Name& n) { names.insert(n.value); });
    std::string line;
    appendDumpLine(line, world, catalog, 0, 0.0, 0);
    for (const SweepMetric& m : s.metrics) {
        if (!names.count(m.entity)) {
            const std::string near = nearestName(m.entity, {names.begin(), names.end()});
            throw ScenarioError(s.path, m.line, m.column,
                                "metric '" + m.name + "': the scenario has no entity '" + m.entity + "'" +
                                    (near.empty() ? "" : " (did you mean '" + near + "'?)"));
        }
        if (const std::string problem = metricProblem(line, m); !problem.empty()) {
            throw ScenarioError(s.path, m.line, m.column, "metric '" + m.name + "': " + problem);
        }
    }
}

double checkSweep(const Catalog& catalog, const Sweep& s) {
    World base;
    const Scenario scenario = loadScenario(catalog, s.scenarioPath, s.scenarioText, {}, base);
    for (const SweepAxis& a : s.axes) {
        for (std::size_t i : valuesToCheck(a)) {
            World world;
            const std::string set = a.key + "=" + a.values[i];
            try {
                loadScenario(catalog, s.scenarioPath, s.scenarioText, {set}, world);
            } catch (const ScenarioError& e) {
                // the message names the --set; where the scenario's own text is at fault it says where
                throw ScenarioError(s.path, a.line, a.column,
                                    "axis '" + a.key +
                                        "': " + (e.line() > 0 ? std::string(e.what()) : e.message()));
            }
        }
    }
    checkMetrics(catalog, s, base);
    return scenario.scene.physicsBudgetMs;
}

std::uint64_t sweepFingerprint(const Sweep& s) {
    Hasher h;
    h.add(std::string_view(s.scenarioPath));
    h.add(std::string_view(s.scenarioText));
    h.add(s.frames);
    h.add(s.repeats);
    h.add(s.zip);
    for (const SweepAxis& a : s.axes) {
        h.add(std::string_view(a.key));
        for (const std::string& v : a.values) {
            h.add(std::string_view(v));
        }
    }
    for (const SweepMetric& m : s.metrics) {
        h.add(std::string_view(m.name + "|" + m.entity + "|" + m.field));
        h.add(m.index);
        h.add(m.component);
    }
    return h.digest();
}

} // namespace tumble
