// `tumble sweep FILE --plot METRIC [--by AXIS]` (app/sweep.h): an SVG of a metric against one axis, one
// line per combination of the other axes' values, cases that did not end ok marked with a cross, and the
// scenario's physics budget drawn where the metric is a physics time.

#include "app/sweep.h"
#include "engine/table_reader.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>

namespace tumble {

namespace {

struct PlotPoint {
    double x = 0.0;
    double y = 0.0;
    bool ok = true;
    bool finite = true; ///< a NaN or infinite value (a blow-up's) is drawn as a cross on the top edge
};

/// The points of each series (the other axes' values), in case order.
using Series = std::map<std::string, std::vector<PlotPoint>>;

bool parseNumber(const std::string& text, double& out) {
    char* end = nullptr;
    out = std::strtod(text.c_str(), &end);
    return !text.empty() && end && *end == '\0' && std::isfinite(out);
}

std::size_t findColumn(const std::vector<std::string>& names, const std::string& name,
                       const std::string& what, const std::string& file) {
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end()) {
        const std::string near = nearestName(name, names);
        std::string list;
        for (const std::string& n : names) {
            list += (list.empty() ? "" : ", ") + n;
        }
        throw ScenarioError(
            file, 0, 0,
            "no " + what + " '" + name + "'" +
                (near.empty()
                     ? "; the " + (what == "axis" ? std::string("axes") : what + "s") + " are " + list
                     : " (did you mean '" + near + "'?)"));
    }
    return std::size_t(it - names.begin());
}

/// x of every case: the axis's value when all are numbers, else its position among the axis's values.
bool numericAxis(const SweepAxis& a) {
    double v = 0.0;
    return std::all_of(a.display.begin(), a.display.end(),
                       [&](const std::string& t) { return parseNumber(t, v); });
}

Series collectPoints(const Sweep& s, const std::string& out, std::size_t column, std::size_t axis) {
    Series series;
    const bool numeric = numericAxis(s.axes[axis]);
    for (std::size_t c = 0; c < s.caseCount(); ++c) {
        const auto r = readCaseResult(out, c, s);
        if (!r) {
            continue;
        }
        const std::vector<std::string> row = resultRow(s, c, *r);
        PlotPoint p;
        if (!parseNumber(row[column], p.y)) {
            const std::string& cell = row[column];
            if (cell != "NaN" && cell != "Infinity" && cell != "-Infinity") {
                continue;
            }
            p.finite = false;
            p.y = 0.0;
        }
        const std::vector<std::size_t> at = s.caseValueIndices(c);
        if (!numeric || !parseNumber(s.axes[axis].display[at[axis]], p.x)) {
            p.x = double(at[axis]);
        }
        p.ok = r->status == "ok";
        // zipped axes move together: one line through every case
        std::string key;
        for (std::size_t i = 0; i < s.axes.size() && !s.zip; ++i) {
            if (i != axis) {
                key += (key.empty() ? "" : ", ") + s.axes[i].key + " = " + s.axes[i].display[at[i]];
            }
        }
        series[key].push_back(p);
    }
    return series;
}

/// Maps data to the picture: x linear or logarithmic, y linear, inside the plot's frame.
struct PlotFrame {
    double left = 80, right = 760, top = 40, bottom = 400;
    double x0 = 0, x1 = 1, y0 = 0, y1 = 1;
    bool logX = false;
    double px(double x) const {
        const double f =
            logX ? (std::log(x) - std::log(x0)) / (std::log(x1) - std::log(x0)) : (x - x0) / (x1 - x0);
        return left + f * (right - left);
    }
    double py(double y) const { return bottom - (y - y0) / (y1 - y0) * (bottom - top); }
};

PlotFrame frameFor(const Series& series, bool logX, double budget) {
    PlotFrame f;
    f.x0 = f.y0 = 1e300;
    f.x1 = f.y1 = -1e300;
    for (const auto& [key, points] : series) {
        for (const PlotPoint& p : points) {
            f.x0 = std::min(f.x0, p.x);
            f.x1 = std::max(f.x1, p.x);
            if (p.finite) {
                f.y0 = std::min(f.y0, p.y);
                f.y1 = std::max(f.y1, p.y);
            }
        }
    }
    if (f.y0 > f.y1) {
        f.y0 = f.y1 = 0.0;
    }
    f.logX = logX && f.x0 > 0.0;
    if (budget > 0.0) {
        f.y1 = std::max(f.y1, budget);
    }
    f.y0 = std::min(f.y0, 0.0);
    f.y1 = f.y1 > f.y0 ? f.y1 + 0.05 * (f.y1 - f.y0) : f.y0 + 1.0;
    if (!(f.x1 > f.x0)) {
        f.x0 -= 1.0;
        f.x1 += 1.0;
        f.logX = false;
    }
    return f;
}

std::string number(double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.4g", v);
    return text;
}

std::string escape(const std::string& s) {
    std::string out;
    for (char c : s) {
        out += c == '<' ? "&lt;" : c == '>' ? "&gt;" : c == '&' ? "&amp;" : std::string(1, c);
    }
    return out;
}

/// Tick values for [lo, hi]: multiples of 1, 2 or 5 times a power of ten, about five of them; on a log
/// scale the values' spread is split evenly in the log instead.
std::vector<double> ticks(double lo, double hi, bool log) {
    std::vector<double> out;
    if (log) {
        for (int i = 0; i <= 4; ++i) {
            out.push_back(lo * std::pow(hi / lo, double(i) / 4.0));
        }
        return out;
    }
    const double raw = (hi - lo) / 5.0;
    const double power = std::pow(10.0, std::floor(std::log10(raw)));
    const double step = power * (raw / power < 1.5   ? 1.0
                                 : raw / power < 3.5 ? 2.0
                                 : raw / power < 7.5 ? 5.0
                                                     : 10.0);
    for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step) {
        out.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
    }
    return out;
}

void drawAxes(std::string& svg, const PlotFrame& f, const SweepAxis& axis, const std::string& metric) {
    const bool numeric = numericAxis(axis);
    for (double y : ticks(f.y0, f.y1, false)) {
        svg += "<line x1='" + number(f.left) + "' x2='" + number(f.right) + "' y1='" + number(f.py(y)) +
               "' y2='" + number(f.py(y)) + "' stroke='#ddd'/><text x='" + number(f.left - 6) + "' y='" +
               number(f.py(y) + 4) + "' text-anchor='end'>" + number(y) + "</text>\n";
    }
    std::vector<double> xs = numeric ? ticks(f.x0, f.x1, f.logX) : std::vector<double>();
    for (std::size_t i = 0; !numeric && i < axis.display.size(); ++i) {
        xs.push_back(double(i));
    }
    for (double x : xs) {
        const std::string label = numeric ? number(x) : escape(axis.display[std::size_t(x)]);
        svg += "<text x='" + number(f.px(x)) + "' y='" + number(f.bottom + 18) + "' text-anchor='middle'>" +
               label + "</text>\n";
    }
    svg += "<rect x='" + number(f.left) + "' y='" + number(f.top) + "' width='" + number(f.right - f.left) +
           "' height='" + number(f.bottom - f.top) + "' fill='none' stroke='#333'/>\n";
    svg += "<text x='" + number((f.left + f.right) / 2) + "' y='" + number(f.bottom + 40) +
           "' text-anchor='middle'>" + escape(axis.key) + (f.logX ? " (log scale)" : "") + "</text>\n";
    svg += "<text transform='translate(18," + number((f.top + f.bottom) / 2) +
           ") rotate(-90)' text-anchor='middle'>" + escape(metric) + "</text>\n";
}

void drawSeries(std::string& svg, const PlotFrame& f, const Series& series) {
    static const char* colours[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b",
                                    "#e377c2", "#7f7f7f", "#bcbd22", "#17becf", "#393b79"};
    std::size_t k = 0;
    for (const auto& [key, points] : series) {
        const std::string colour = colours[k % std::size(colours)];
        std::vector<PlotPoint> sorted = points;
        std::stable_sort(sorted.begin(), sorted.end(),
                         [](const PlotPoint& a, const PlotPoint& b) { return a.x < b.x; });
        // the line through the cases that ended ok, broken at any that did not (a blow-up's times are no
        // point of the curve: it was drawn through them)
        std::string path;
        bool drawing = false;
        for (const PlotPoint& p : sorted) {
            if (p.ok && p.finite) {
                path += std::string(drawing        ? " L"
                                    : path.empty() ? "M"
                                                   : " M") +
                        number(f.px(p.x)) + " " + number(f.py(p.y));
            }
            drawing = p.ok && p.finite;
        }
        svg += "<path d='" + path + "' fill='none' stroke='" + colour + "' stroke-width='1.5'/>\n";
        for (const PlotPoint& p : sorted) {
            const std::string x = number(f.px(p.x)), y = number(p.finite ? f.py(p.y) : f.top);
            svg += p.ok && p.finite
                       ? "<circle cx='" + x + "' cy='" + y + "' r='3' fill='" + colour + "'/>\n"
                       : "<text x='" + x + "' y='" + number((p.finite ? f.py(p.y) : f.top) + 5) +
                             "' text-anchor='middle' fill='#d62728' font-weight='bold'>x</text>\n";
        }
        if (!key.empty() && k < 12) {
            svg += "<text x='" + number(f.right + 10) + "' y='" + number(f.top + 14 + 16 * double(k)) +
                   "' fill='" + colour + "'>" + escape(key) + "</text>\n";
        }
        ++k;
    }
}

} // namespace

std::string plotSweep(const Sweep& s, const std::string& out, const std::string& metric,
                      const std::string& by, double budgetMs) {
    if (s.axes.empty()) {
        throw ScenarioError(s.path, 0, 0, "the sweep has no axis to plot against");
    }
    // every column of numbers: results.csv's less the case, the axes, the status, the hash and the detail
    std::vector<std::string> metrics;
    for (const std::string& c : resultColumns(s)) {
        const bool isAxis =
            std::any_of(s.axes.begin(), s.axes.end(), [&](const SweepAxis& a) { return a.key == c; });
        if (!isAxis && c != "case" && c != "status" && c != "hash" && c != "detail") {
            metrics.push_back(c);
        }
    }
    findColumn(metrics, metric, "metric", "--plot");
    std::vector<std::string> axisKeys;
    for (const SweepAxis& a : s.axes) {
        axisKeys.push_back(a.key);
    }
    const std::size_t axis = by.empty() ? 0 : findColumn(axisKeys, by, "axis", "--by");
    const std::size_t column = findColumn(resultColumns(s), metric, "metric", "--plot");
    const Series series = collectPoints(s, out, column, axis);
    if (series.empty()) {
        throw ScenarioError("--plot", 0, 0, "no case in " + out + " has a value of '" + metric + "' yet");
    }
    const bool isTime = metric.rfind("physics_", 0) == 0;
    const PlotFrame f = frameFor(series, s.axes[axis].logScale, isTime ? budgetMs : 0.0);
    const bool legend = series.size() > 1;
    std::string svg =
        "<svg xmlns='http://www.w3.org/2000/svg' width='" + std::string(legend ? "1120" : "800") +
        "' height='460' font-family='sans-serif' font-size='12'>\n<rect width='100%' height='100%' "
        "fill='white'/>\n<text x='80' y='24' font-size='15'>" +
        escape(s.name + ": " + metric + " by " + s.axes[axis].key) + "</text>\n";
    drawAxes(svg, f, s.axes[axis], metric);
    if (isTime && budgetMs > 0.0) {
        const std::string y = number(f.py(budgetMs));
        svg += "<line x1='" + number(f.left) + "' x2='" + number(f.right) + "' y1='" + y + "' y2='" + y +
               "' stroke='#d62728' stroke-dasharray='6 4'/><text x='" + number(f.right - 4) + "' y='" +
               number(f.py(budgetMs) - 5) + "' text-anchor='end' fill='#d62728'>budget " + number(budgetMs) +
               " ms</text>\n";
    }
    drawSeries(svg, f, series);
    svg += "</svg>\n";
    std::string name = "plot_" + metric + "_by_" + s.axes[axis].key + ".svg";
    std::replace_if(
        name.begin(), name.end(), [](char c) { return c == '/' || c == ' '; }, '_');
    const std::string path = out + "/" + name;
    writeSweepFile(path, svg);
    return path;
}

} // namespace tumble
