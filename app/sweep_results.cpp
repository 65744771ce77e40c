// A sweep's results (app/sweep.h): each case's result.json, the metrics read from its final dump, and
// results.csv merged from them.

#include "app/sweep.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string_view>

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

/// The text of a number as the table shows it: the shortest that reads back, NaN as "nan".
std::string numberCell(double v) {
    if (!std::isfinite(v)) {
        return std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
    }
    char text[32];
    std::snprintf(text, sizeof text, "%.17g", v);
    for (int digits = 1; digits <= 17; ++digits) {
        char shorter[32];
        std::snprintf(shorter, sizeof shorter, "%.*g", digits, v);
        if (std::strtod(shorter, nullptr) == v) {
            return shorter;
        }
    }
    return text;
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

/// Writes a file whole or not at all: a reader (a resumed sweep, --merge, --status) never sees half.
void writeAtomically(const std::string& path, const std::string& text) {
    const std::string temporary = path + ".partial";
    {
        std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
        out << text;
        out.close();
        if (!out) {
            throw std::runtime_error("cannot write " + temporary);
        }
    }
    std::error_code ec;
    fs::rename(temporary, path, ec);
    if (ec) {
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

std::vector<std::string> readMetrics(const std::string& dumpPath, const std::vector<SweepMetric>& metrics) {
    std::vector<std::string> out(metrics.size());
    if (metrics.empty()) {
        return out;
    }
    std::ifstream in(dumpPath);
    std::string line, last;
    while (std::getline(in, line)) {
        if (!line.empty()) {
            last = std::move(line);
        }
    }
    // the dump spells non-finite numbers NaN / Infinity, which JSON does not: quoted, they parse
    for (const char* word : {"-Infinity", "Infinity", "NaN"}) {
        for (std::size_t at = 0; (at = last.find(word, at)) != std::string::npos;) {
            // a bare word is a value: it follows '[', ',' or ':' (spaces aside), never a letter or a quote
            std::size_t before = at;
            while (before > 0 && last[before - 1] == ' ') {
                --before;
            }
            if (before == 0 || std::string_view("[,:").find(last[before - 1]) == std::string_view::npos) {
                at += std::strlen(word);
                continue;
            }
            last.replace(at, std::strlen(word), std::string("\"") + word + "\"");
            at += std::strlen(word) + 2;
        }
    }
    const json dump = json::parse(last, nullptr, false);
    if (dump.is_discarded() || !dump.contains("entities")) {
        return out;
    }
    for (std::size_t i = 0; i < metrics.size(); ++i) {
        const auto e = dump["entities"].find(metrics[i].entity);
        if (e != dump["entities"].end()) {
            out[i] = metricValue(*e, metrics[i]);
        }
    }
    return out;
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
              {"wall_s", r.wallSeconds}};
    writeAtomically(caseFolder(out, c) + "/result.json", j.dump() + "\n");
}

std::optional<CaseResult> readCaseResult(const std::string& out, std::size_t c, std::size_t metricCount) {
    const std::string path = caseFolder(out, c) + "/result.json";
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) {
        return std::nullopt;
    }
    const json j = json::parse(readWhole(path), nullptr, false);
    // a result that does not read (a disk that filled) is no result: the case runs again
    if (j.is_discarded() || !j.is_object() || !j.contains("status") || !j.contains("metrics") ||
        !j["metrics"].is_array() || j["metrics"].size() != metricCount) {
        return std::nullopt;
    }
    CaseResult r;
    r.status = j.value("status", "error");
    r.exitCode = j.value("exit_code", 0);
    r.p50 = optionalNumber(j.value("physics_p50_ms", json()));
    r.p99 = optionalNumber(j.value("physics_p99_ms", json()));
    r.max = optionalNumber(j.value("physics_max_ms", json()));
    r.hash = j.value("hash", "");
    for (const json& m : j["metrics"]) {
        if (!m.is_string()) {
            return std::nullopt;
        }
        r.metrics.push_back(m.get<std::string>());
    }
    r.detail = j.value("detail", "");
    r.wallSeconds = j.value("wall_s", 0.0);
    return r;
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
        if (const auto r = readCaseResult(out, c, sweep.metrics.size())) {
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
