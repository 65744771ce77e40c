// A sweep's results (app/sweep.h): each case's result.json, the metrics read from its final dump, and
// results.csv merged from them.

#include "app/sweep.h"
#include "engine/dump.h"
#include "engine/json.h"

#include <nlohmann/json.hpp>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <unistd.h>

namespace tumble {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::optional<double> optionalNumber(const json& j) {
    if (j.is_number()) {
        return j.get<double>();
    }
    return std::nullopt;
}

json numberOrNull(const std::optional<double>& v) {
    return v ? json(*v) : json(nullptr);
}

std::string readWhole(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

/// The text of a number as the table shows it: the shortest that reads back, non-finite ones as the dump
/// spells them (NaN, Infinity, -Infinity).
std::string numberCell(double v) {
    std::string s;
    appendNumber(s, v);
    return s;
}

std::string csvCell(const std::string& s) {
    if (s.find_first_of(",\"\n\r") == std::string::npos) {
        return s;
    }
    std::string out = "\"";
    for (char c : s) {
        out += c == '"' ? std::string("\"\"") : std::string(1, c);
    }
    return out + "\"";
}

/// Writes a file whole or not at all: a reader (a resumed sweep, --merge, --status) never sees half, and
/// two writers (two shards, a merge beside a merge) each write a temporary of their own.
void writeAtomically(const std::string& path, const std::string& text) {
    static std::atomic<unsigned> serial{0};
    const std::string temporary =
        path + ".partial." + std::to_string(::getpid()) + "." + std::to_string(serial.fetch_add(1));
    {
        std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
        out << text;
        out.close();
        if (!out) {
            std::error_code ec;
            fs::remove(temporary, ec);
            throw std::runtime_error("cannot write " + temporary);
        }
    }
    std::error_code ec;
    fs::rename(temporary, path, ec);
    if (ec) {
        fs::remove(temporary, ec);
        throw std::runtime_error("cannot write " + path + ": " + ec.message());
    }
}

/// One value of the dump's entity as the metric asks for it, or "" when it is not there.
std::string metricValue(const json& entity, const SweepMetric& m) {
    if (m.field == "count") {
        return entity.contains("count") && entity["count"].is_number()
                   ? numberCell(entity["count"].get<double>())
                   : "";
    }
    const json* items = nullptr;
    json flat;
    if (m.field == "h" && entity.contains("h") && entity["h"].is_array()) {
        flat = json::array();
        for (const json& row : entity["h"]) {
            for (const json& v : row) {
                flat.push_back(v);
            }
        }
        items = &flat;
    } else if (entity.contains(m.field) && entity[m.field].is_array()) {
        items = &entity[m.field];
    }
    if (!items || items->empty()) {
        return "";
    }
    const std::int64_t n = std::int64_t(items->size());
    const std::int64_t i = m.index < 0 ? n - 1 : m.index;
    if (i >= n) {
        return "";
    }
    const json& item = (*items)[std::size_t(i)];
    const json& value = item.is_array()
                            ? (std::size_t(m.component) < item.size() ? item[m.component] : json())
                            : (m.component == 0 ? item : json());
    if (value.is_number()) {
        return numberCell(value.get<double>());
    }
    // the dump writes non-finite numbers as the bare words NaN, Infinity, -Infinity: parsed as strings here
    return value.is_string() ? value.get<std::string>() : "";
}

} // namespace

std::vector<std::string> metricValues(const std::string& dumpLine, const std::vector<SweepMetric>& metrics) {
    std::vector<std::string> out(metrics.size());
    const json dump = json::parse(quoteNonFinite(dumpLine), nullptr, false);
    if (dump.is_discarded() || !dump.contains("entities") || !dump["entities"].is_object()) {
        return out;
    }
    for (std::size_t i = 0; i < metrics.size(); ++i) {
        const auto e = dump["entities"].find(metrics[i].entity);
        if (e != dump["entities"].end() && e->is_object()) {
            out[i] = metricValue(*e, metrics[i]);
        }
    }
    return out;
}

std::string metricProblem(const std::string& dumpLine, const SweepMetric& m) {
    const json dump = json::parse(quoteNonFinite(dumpLine), nullptr, false);
    if (dump.is_discarded() || !dump.contains("entities") || !dump["entities"].contains(m.entity)) {
        return "no entity '" + m.entity + "' in the dump";
    }
    const json& e = dump["entities"][m.entity];
    const std::string kind = e.value("kind", std::string("?"));
    const std::string what = "entity '" + m.entity + "' (" + kind + ")";
    if (m.field == "count" || !e.contains(m.field) || !e[m.field].is_array()) {
        return m.field == "count" && e.contains("count")
                   ? ""
                   : what + " has no " + m.field +
                         " (x, v: a mass, node, particle or body; count: particles; h: water)";
    }
    std::size_t rows = e[m.field].size(), width = 0;
    if (m.field == "h") {
        rows = 0;
        for (const json& row : e["h"]) {
            rows += row.size();
        }
        width = 1;
    } else if (rows > 0) {
        width = e[m.field][0].size();
    }
    // particles come and go: their index can only be checked as the run ends
    if (rows > 0 && kind != "particles" && m.index >= std::int64_t(rows)) {
        return what + " has " + std::to_string(rows) + " " + m.field + " values: index " +
               std::to_string(m.index) + " is past them";
    }
    if (rows > 0 && std::size_t(m.component) >= width) {
        return what + "'s " + m.field + " has " + std::to_string(width) + " components: component " +
               std::to_string(m.component) + " is past them";
    }
    return "";
}

std::vector<std::string> readMetrics(const std::string& dumpPath, const std::vector<SweepMetric>& metrics) {
    if (metrics.empty()) {
        return {};
    }
    std::ifstream in(dumpPath);
    std::string line, last;
    while (std::getline(in, line)) {
        if (!line.empty()) {
            last = std::move(line);
        }
    }
    return metricValues(last, metrics);
}

std::string caseFolder(const std::string& out, std::size_t c) {
    char name[32];
    std::snprintf(name, sizeof name, "%05zu", c);
    return out + "/cases/" + name;
}

void writeCaseResult(const std::string& out, std::size_t c, const CaseResult& r) {
    json j = {{"status", r.status},
              {"exit_code", r.exitCode},
              {"physics_p50_ms", numberOrNull(r.p50)},
              {"physics_p99_ms", numberOrNull(r.p99)},
              {"physics_max_ms", numberOrNull(r.max)},
              {"hash", r.hash},
              {"metrics", r.metrics},
              {"detail", r.detail},
              {"wall_s", r.wallSeconds},
              {"sweep", r.sweep}};
    // a message cut mid-character is not UTF-8: replaced, not thrown over
    writeAtomically(caseFolder(out, c) + "/result.json",
                    j.dump(-1, ' ', false, json::error_handler_t::replace) + "\n");
}

std::optional<CaseResult> readCaseResult(const std::string& out, std::size_t c, const Sweep& sweep) {
    const std::string path = caseFolder(out, c) + "/result.json";
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) {
        return std::nullopt;
    }
    // a result that does not read (a disk that filled, a hand edit) is no result: the case runs again
    try {
        const json j = json::parse(readWhole(path));
        CaseResult r;
        r.status = j.at("status").get<std::string>();
        r.exitCode = j.at("exit_code").get<int>();
        r.p50 = optionalNumber(j.at("physics_p50_ms"));
        r.p99 = optionalNumber(j.at("physics_p99_ms"));
        r.max = optionalNumber(j.at("physics_max_ms"));
        r.hash = j.at("hash").get<std::string>();
        r.metrics = j.at("metrics").get<std::vector<std::string>>();
        r.detail = j.at("detail").get<std::string>();
        r.wallSeconds = j.at("wall_s").get<double>();
        r.sweep = j.at("sweep").get<std::string>();
        if (r.metrics.size() != sweep.metrics.size() || r.sweep != hash16(sweepFingerprint(sweep))) {
            return std::nullopt;
        }
        return r;
    } catch (const json::exception&) {
        return std::nullopt;
    }
}

std::vector<std::size_t> shardCases(std::size_t caseCount, std::size_t shard, std::size_t shards) {
    std::vector<std::size_t> cases;
    for (std::size_t c = shard; c < caseCount; c += shards) {
        cases.push_back(c);
    }
    return cases;
}

std::vector<std::string> resultColumns(const Sweep& s) {
    std::vector<std::string> columns = {"case"};
    for (const SweepAxis& a : s.axes) {
        columns.push_back(a.key);
    }
    for (const char* c :
         {"status", "exit_code", "physics_p50_ms", "physics_p99_ms", "physics_max_ms", "hash"}) {
        columns.push_back(c);
    }
    for (const SweepMetric& m : s.metrics) {
        columns.push_back(m.name);
    }
    columns.push_back("detail");
    return columns;
}

std::vector<std::string> resultRow(const Sweep& s, std::size_t c, const CaseResult& r) {
    std::vector<std::string> row = {std::to_string(c)};
    const std::vector<std::size_t> at = s.caseValueIndices(c);
    for (std::size_t i = 0; i < s.axes.size(); ++i) {
        row.push_back(s.axes[i].display[at[i]]);
    }
    row.push_back(r.status);
    row.push_back(std::to_string(r.exitCode));
    for (const std::optional<double>& v : {r.p50, r.p99, r.max}) {
        row.push_back(v ? numberCell(*v) : "");
    }
    row.push_back(r.hash);
    for (const std::string& m : r.metrics) {
        row.push_back(m);
    }
    row.push_back(r.detail);
    return row;
}

std::size_t mergeResults(const Sweep& sweep, const std::string& out) {
    std::string text;
    auto line = [&](const std::vector<std::string>& cells) {
        for (std::size_t i = 0; i < cells.size(); ++i) {
            text += (i ? "," : "") + csvCell(cells[i]);
        }
        text += "\n";
    };
    line(resultColumns(sweep));
    std::size_t missing = 0;
    for (std::size_t c = 0; c < sweep.caseCount(); ++c) {
        if (const auto r = readCaseResult(out, c, sweep)) {
            line(resultRow(sweep, c, *r));
        } else {
            ++missing;
        }
    }
    writeAtomically(out + "/results.csv", text);
    return missing;
}

void writeSweepFile(const std::string& path, const std::string& text) {
    writeAtomically(path, text);
}

} // namespace tumble
