// `tumble sweep` (app/sweep.h): the sweep file's cases against nested loops and closed forms, shards that
// cover every case once, bad input refused before any case runs, and real sweeps of the real program: the
// table's hashes and metrics against the same runs made in this process, a failing case kept as a row, a
// sweep killed half-way finishing with the same table, the plot.

#include "app/sweep.h"
#include "components/spring_network.h"
#include "engine/dump.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <map>
#include <set>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace tumble {
namespace {

namespace fs = std::filesystem;
using test::readFile;
using test::runTumble;
using test::tempPath;
using test::writeTemp;

/// A CSV file as rows of cells (quoted cells may hold commas and doubled quotes).
std::vector<std::vector<std::string>> readCsv(const std::string& path) {
    std::vector<std::vector<std::string>> rows;
    const std::string text = readFile(path);
    std::vector<std::string> row(1);
    bool quoted = false;
    for (std::size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (quoted) {
            if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
                row.back() += '"';
                ++i;
            } else if (c == '"') {
                quoted = false;
            } else {
                row.back() += c;
            }
        } else if (c == '"') {
            quoted = true;
        } else if (c == ',') {
            row.emplace_back();
        } else if (c == '\n') {
            rows.push_back(row);
            row.assign(1, "");
        } else {
            row.back() += c;
        }
    }
    return rows;
}

/// The table without its timing columns (which no two runs share).
std::vector<std::vector<std::string>> untimed(std::vector<std::vector<std::string>> rows) {
    const std::vector<std::string> header = rows.at(0);
    for (auto& row : rows) {
        std::vector<std::string> kept;
        for (std::size_t i = 0; i < row.size(); ++i) {
            if (header[i].rfind("physics_", 0) != 0) {
                kept.push_back(row[i]);
            }
        }
        row = kept;
    }
    return rows;
}

/// The rope demo under symplectic Euler (the demo takes implicit Euler, stable at any stiffness), whose
/// stiff cases blow up as the sweeps' blow_up status needs: written once, beside the sweep files.
std::string symplecticRope() {
    static const std::string path = [] {
        std::string text = readFile(std::string(TUMBLE_SOURCE_DIR) + "/demos/rope.toml");
        const std::string::size_type at = text.find("integrator = \"implicit_euler\"");
        EXPECT_NE(at, std::string::npos);
        text.replace(at, std::string("integrator = \"implicit_euler\"").size(),
                     "integrator = \"symplectic_euler\"");
        return writeTemp("rope_symplectic.toml", text);
    }();
    return path;
}

std::string ropeSweep(const std::string& axes, const std::string& extra = "", int frames = 20) {
    symplecticRope();
    return "[sweep]\nscenario = \"rope_symplectic.toml\"\nframes = " + std::to_string(frames) + "\n" + extra +
           "\n" + axes;
}

TEST(SweepPlan, GridCasesAreNestedLoopsWithTheLastAxisFastest) {
    const std::string path = writeTemp("grid.toml", ropeSweep("[[axis]]\nkey = \"chain.rope.stiffness\"\n"
                                                              "values = [100.0, 200.0, 300.0]\n"
                                                              "[[axis]]\nkey = \"chain.rope.damping\"\n"
                                                              "values = [0.1, 0.2]\n"
                                                              "[[axis]]\nkey = \"chain.rope.mass\"\n"
                                                              "values = [1.0, 2.0, 3.0, 4.0]\n"));
    const Sweep s = readSweep(path);
    ASSERT_EQ(s.caseCount(), 24u);
    std::size_t c = 0;
    for (std::size_t i = 0; i < 3; ++i) {
        for (std::size_t j = 0; j < 2; ++j) {
            for (std::size_t k = 0; k < 4; ++k, ++c) {
                EXPECT_EQ(s.caseValueIndices(c), (std::vector<std::size_t>{i, j, k})) << c;
            }
        }
    }
    EXPECT_EQ(s.caseSets(23), (std::vector<std::string>{"chain.rope.stiffness=300.0",
                                                        "chain.rope.damping=0.2", "chain.rope.mass=4.0"}));
}

TEST(SweepPlan, ZipTakesEveryAxisValueIAndRefusesUnequalLengths) {
    const std::string axes = "[[axis]]\nkey = \"chain.rope.stiffness\"\nvalues = [100.0, 200.0, 300.0]\n"
                             "[[axis]]\nkey = \"chain.rope.damping\"\nrange = [0.1, 0.3, 3]\n";
    const Sweep s = readSweep(writeTemp("zip.toml", ropeSweep(axes, "combine = \"zip\"")));
    ASSERT_EQ(s.caseCount(), 3u);
    EXPECT_EQ(s.caseSets(1),
              (std::vector<std::string>{"chain.rope.stiffness=200.0", "chain.rope.damping=0.2"}));
    const std::string bad = "[[axis]]\nkey = \"chain.rope.stiffness\"\nvalues = [100.0, 200.0]\n"
                            "[[axis]]\nkey = \"chain.rope.damping\"\nrange = [0.1, 0.3, 3]\n";
    try {
        readSweep(writeTemp("zip_bad.toml", ropeSweep(bad, "combine = \"zip\"")));
        FAIL() << "unequal zipped axes were accepted";
    } catch (const ScenarioError& e) {
        EXPECT_EQ(e.line(), 9) << e.what();
        EXPECT_NE(e.message().find("one length"), std::string::npos) << e.what();
    }
}

TEST(SweepPlan, RangesMatchTheirClosedFormsWithExactEnds) {
    const Sweep s =
        readSweep(writeTemp("ranges.toml", ropeSweep("[[axis]]\nkey = \"chain.rope.damping\"\n"
                                                     "range = [0.1, 0.5, 5]\n"
                                                     "[[axis]]\nkey = \"chain.rope.stiffness\"\n"
                                                     "log_range = [10.0, 100000.0, 5]\n"
                                                     "[[axis]]\nkey = \"chain.rope.segments\"\n"
                                                     "log_range = [2, 1000, 4]\ninteger = true\n")));
    ASSERT_EQ(s.axes.size(), 3u);
    const std::vector<double> linear = {0.1, 0.2, 0.3, 0.4, 0.5};
    for (std::size_t i = 0; i < 5; ++i) {
        EXPECT_EQ(std::stod(s.axes[0].values[i]), linear[i]) << s.axes[0].values[i];
        // a decade a step: 10, 100, ..., 1e5, within rounding of the logarithm
        EXPECT_NEAR(std::stod(s.axes[1].values[i]), std::pow(10.0, double(i + 1)),
                    1e-9 * std::pow(10.0, i + 1));
    }
    EXPECT_EQ(std::stod(s.axes[1].values.front()), 10.0);
    EXPECT_EQ(std::stod(s.axes[1].values.back()), 100000.0);
    EXPECT_TRUE(s.axes[1].logScale);
    // whole numbers on request: 2 * 500^(i/3) rounded
    EXPECT_EQ(s.axes[2].values, (std::vector<std::string>{"2", "16", "126", "1000"}));
}

TEST(SweepPlan, RandomAxesFollowTheSeedAndStayInRange) {
    auto draws = [](int seed) {
        const std::string axis = "[[axis]]\nkey = \"chain.rope.damping\"\nrandom = { min = 0.25, max = 0.75, "
                                 "count = 200 }\n";
        return readSweep(writeTemp("random.toml", ropeSweep(axis, "seed = " + std::to_string(seed))))
            .axes[0]
            .values;
    };
    const std::vector<std::string> a = draws(1), again = draws(1), other = draws(2);
    EXPECT_EQ(a, again);
    EXPECT_NE(a, other);
    double sum = 0.0;
    for (const std::string& v : a) {
        const double x = std::stod(v);
        ASSERT_GE(x, 0.25);
        ASSERT_LE(x, 0.75);
        sum += x;
    }
    // the mean of 200 uniform draws: 0.5 within four standard errors (0.5 / sqrt(12 * 200) = 0.0102)
    EXPECT_NEAR(sum / 200.0, 0.5, 0.041);
}

TEST(SweepPlan, StringValuesAreSetQuotedAndShownBare) {
    const Sweep s =
        readSweep(writeTemp("strings.toml", ropeSweep("[[axis]]\nkey = \"chain.rope.integrator\"\n"
                                                      "values = [\"rk4\", \"implicit_euler\"]\n"
                                                      "[[axis]]\nkey = \"chain.rope.segments\"\n"
                                                      "random = { min = 0.5, max = 2.5, count = 40 }\n"
                                                      "integer = true\n")));
    EXPECT_EQ(s.caseSets(0)[0], "chain.rope.integrator='rk4'"); // a TOML literal string, as --set reads it
    EXPECT_EQ(s.axes[0].display, (std::vector<std::string>{"rk4", "implicit_euler"}));
    // whole numbers within [0.5, 2.5]: 1 and 2, both drawn
    EXPECT_EQ(std::set<std::string>(s.axes[1].values.begin(), s.axes[1].values.end()),
              (std::set<std::string>{"1", "2"}));
}

TEST(SweepPlan, ShardsCoverEveryCaseExactlyOnce) {
    for (std::size_t cases : {1u, 2u, 3u, 24u, 100u, 1001u}) {
        for (std::size_t shards : {1u, 2u, 3u, 4u, 7u}) {
            std::vector<int> seen(cases, 0);
            for (std::size_t i = 0; i < shards; ++i) {
                for (std::size_t c : shardCases(cases, i, shards)) {
                    ASSERT_LT(c, cases);
                    ++seen[c];
                }
            }
            for (std::size_t c = 0; c < cases; ++c) {
                ASSERT_EQ(seen[c], 1) << "case " << c << " of " << cases << " in " << shards << " shards";
            }
        }
    }
}

TEST(SweepPlan, BadInputIsLocatedWithADidYouMean) {
    struct Case {
        std::string text, fragment;
        int line;
    };
    const std::vector<Case> cases = {
        {"[sweep]\nscenario = \"rope\"\ntreads = 2\n", "did you mean 'threads'", 3},
        {"[sweep]\nscenario = \"rope\"\n[[axes]]\nkey = \"a.b\"\n", "did you mean 'axis'", 3},
        {"[sweep]\nscenario = \"rope\"\n[[axis]]\nkey = \"chain.rope.stiffness\"\nvalue = [1.0]\n",
         "did you mean 'values'", 5},
        {"[sweep]\nscenario = \"rope\"\n[[axis]]\nkey = \"chain.rope.stiffness\"\n", "exactly one of", 4},
        {"[sweep]\nscenario = \"rope\"\n[[axis]]\nkey = \"chain.rope.stiffness\"\nrange = [1.0, 2.0]\n",
         "[lo, hi, count]", 5},
        {"[sweep]\nscenario = \"rope\"\n[[axis]]\nkey = \"chain.rope.stiffness\"\nlog_range = [0.0, 2.0, "
         "3]\n",
         "above zero", 5},
        {"[sweep]\nscenario = \"no_such_demo\"\n", "no scenario file or demo", 2},
        {"[sweep]\nscenario = \"rope\"\n[[metric]]\nname = \"hash\"\nentity = \"chain\"\n", "name is taken",
         3},
        {"[sweep]\nscenario = \"rope\"\n[[metric]]\nname = \"m\"\nentity = \"chain\"\nfield = \"y\"\n",
         "one of", 6},
        // an empty name was told it had commas, quotes or line breaks
        {"[sweep]\nscenario = \"rope\"\n[[metric]]\nname = \"\"\nentity = \"chain\"\n", "must not be empty",
         4},
        {"[sweep]\nscenario = \"rope\"\n[[metric]]\nname = \"a,b\"\nentity = \"chain\"\n", "no commas", 4},
        {"[sweep]\nscenario = \"rope\"\nthreads = 512\n", "outside", 3},
        // frames = 0 ran the scene's whole length (found by a reviewer who had not seen the code)
        {"[sweep]\nscenario = \"rope\"\nframes = 0\n", "'frames' in [sweep] is 0, outside [1,", 3},
        // an axis that changes nothing, or repeats cases, passed without a word
        {"[sweep]\nscenario = \"rope\"\nframes = 5\n[[axis]]\nkey = \"scene.frames\"\nvalues = [10, 20]\n",
         "would change nothing", 5},
        {"[sweep]\nscenario = \"rope\"\n[[axis]]\nkey = \"scene.substeps\"\ninteger = true\nrange = [1, 2, "
         "5]\n",
         "more than once", 6},
        {"[sweep]\nscenario = \"rope\"\n[[axis]]\nkey = \"chain.rope.segments\"\ninteger = true\n"
         "random = { min = 0.2, max = 0.8, count = 3 }\n",
         "no whole number", 6},
        {"[sweep]\nscenario = \"rope\"\n[[axis]]\nkey = \"chain.rope.segments\"\ninteger = true\nvalues = "
         "[1]\n",
         "listed values are as written", 5},
        // a value no key takes (it was set as a bare word, and the scenario said "not a string")
        {"[sweep]\nscenario = \"rope\"\n[[axis]]\nkey = \"chain.rope.stiffness\"\nvalues = [1.0, nan]\n",
         "values: nan is not finite", 5},
        {"[sweep]\nscenario = \"rope\"\n[[axis]]\nkey = \"chain.transform.position\"\nvalues = [[0.0, "
         "inf, 0.0]]\n",
         "is not finite", 5},
    };
    for (const Case& c : cases) {
        try {
            readSweep(writeTemp("bad.toml", c.text));
            ADD_FAILURE() << "accepted:\n" << c.text;
        } catch (const ScenarioError& e) {
            EXPECT_EQ(e.line(), c.line) << e.what();
            EXPECT_NE(std::string(e.what()).find(c.fragment), std::string::npos) << e.what();
        }
    }
    // a sweep file that is not there is called that (it was "cannot open the scenario")
    try {
        readSweep(test::tempPath("no_such_sweep.toml"));
        ADD_FAILURE() << "a missing sweep file was read";
    } catch (const ScenarioError& e) {
        EXPECT_NE(std::string(e.what()).find("cannot open the sweep file: no such file"), std::string::npos)
            << e.what();
    }
}

TEST(SweepPlan, AxisKeysAndMetricsTheScenarioRefusesStopTheSweepBeforeAnyCase) {
    struct Case {
        std::string body, fragment;
        int line;
    };
    const std::vector<Case> cases = {
        {"[[axis]]\nkey = \"chain.rope.stifness\"\nvalues = [100.0]\n", "did you mean 'stiffness'", 6},
        {"[[axis]]\nkey = \"chain.rope.stiffness\"\nvalues = [100.0, -5.0]\n", "outside", 6},
        {"[[axis]]\nkey = \"chian.rope.stiffness\"\nvalues = [100.0]\n", "no section or entity", 6},
        {"[[axis]]\nkey = \"chain.rope.stiffness\"\nvalues = [100.0]\n[[metric]]\nname = \"m\"\nentity = "
         "\"chian\"\n",
         "did you mean 'chain'", 8},
        // a typo in the middle of a long list is found too, not only at its ends
        {"[[axis]]\nkey = \"chain.rope.integrator\"\nvalues = [\"rk4\", \"rk4\", \"midpoint\", \"rk5\", "
         "\"symplectic_euler\", \"implicit_euler\", \"a1\", \"a2\", \"a3\", \"a4\", \"a5\", \"a6\", \"a7\", "
         "\"a8\", \"a9\", \"b1\", \"b2\", \"rk4\"]\n",
         "'rk5'", 6},
        // metrics the scenario's entity cannot give: refused before any case, not an empty column
        {"[[metric]]\nname = \"m\"\nentity = \"chain\"\nfield = \"count\"\n", "has no count", 5},
        {"[[metric]]\nname = \"m\"\nentity = \"chain\"\nindex = 31\n", "index 31 is past them", 5},
        {"[[metric]]\nname = \"m\"\nentity = \"chain\"\nfield = \"h\"\n", "has no h", 5},
    };
    for (const Case& c : cases) {
        const std::string out = tempPath("refused_out");
        const std::string file = writeTemp("refused.toml", ropeSweep(c.body));
        const auto r = runTumble({"sweep", file, "--local", "--out", out});
        EXPECT_EQ(r.exitCode, 2) << r.err;
        EXPECT_NE(r.err.find(file + ":" + std::to_string(c.line) + ":"), std::string::npos) << r.err;
        EXPECT_NE(r.err.find(c.fragment), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(out)) << "a refused sweep made its folder";
    }
}

TEST(SweepResults, MetricsAreReadFromTheDumpsLastLineToTheBit) {
    // two lines: the metrics come from the last; non-finite numbers as the dump spells them; a name that
    // holds the word NaN stays a name
    const std::string dump = writeTemp(
        "metrics.jsonl",
        "{\"frame\": 1, \"entities\": {\"rope\": {\"kind\": \"springs\", \"x\": [[9, 9, 9]]}}}\n"
        "{\"frame\": 2, \"entities\": {\"rope\": {\"kind\": \"springs\", \"x\": [[0.1, 0.2, "
        "0.30000000000000004], "
        "[1e-300, -Infinity, NaN]], \"v\": [[1, 2, 3], [4, 5, 6]]}, \"NaNa\": {\"kind\": \"particles\", "
        "\"count\": 231}, \"pond\": {\"kind\": \"water\", \"h\": [[0.5, 0.25], [0.125, -0.0625]]}}}\n");
    auto metric = [](std::string entity, std::string field, std::int64_t index, int component) {
        SweepMetric m;
        m.name = field;
        m.entity = std::move(entity);
        m.field = std::move(field);
        m.index = index;
        m.component = component;
        return m;
    };
    const std::vector<SweepMetric> metrics = {
        metric("rope", "x", 0, 2),  metric("rope", "x", -1, 0), metric("rope", "x", -1, 1),
        metric("rope", "x", 1, 2),  metric("rope", "v", -1, 1), metric("NaNa", "count", -1, 0),
        metric("pond", "h", 2, 0),  metric("pond", "h", -1, 0), metric("rope", "x", 2, 0),
        metric("ghost", "x", 0, 0), metric("pond", "x", 0, 0)};
    EXPECT_EQ(readMetrics(dump, metrics),
              (std::vector<std::string>{"0.30000000000000004", "1e-300", "-Infinity", "NaN", "5", "231",
                                        "0.125", "-0.0625", "", "", ""}));
}

/// The same case run in this process: its final state hash and the last mass's x.
std::pair<std::string, double> runHere(const std::vector<std::string>& sets, int frames) {
    const std::string path = symplecticRope();
    Simulation sim(test::builtinCatalog(), path, readScenarioFile(path), sets, kDefaultMemoryCap, 1);
    for (int f = 0; f < frames; ++f) {
        sim.runFrame();
        sim.takeAppliedEvents();
    }
    return {hash16(sim.hash()), test::component<SpringNetwork>(sim, "chain").x.back().x};
}

TEST(SweepLocal, TableHoldsEachCaseHashAndMetricAsARunOfItsOwnGives) {
    const std::string file =
        writeTemp("table.toml", ropeSweep("[[axis]]\nkey = \"chain.rope.stiffness\"\n"
                                          "values = [300.0, 1e9]\n"
                                          "[[axis]]\nkey = \"chain.rope.damping\"\n"
                                          "values = [0.1, 0.4]\n"
                                          "[[metric]]\nname = \"end_x\"\nentity = \"chain\"\n"
                                          "field = \"x\"\nindex = -1\ncomponent = 0\n",
                                          "repeats = 2"));
    const std::string out = tempPath("table_out");
    const auto r = runTumble({"sweep", file, "--local", "-j", "2", "--out", out});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const auto rows = readCsv(out + "/results.csv");
    ASSERT_EQ(rows.size(), 5u);
    EXPECT_EQ(rows[0], (std::vector<std::string>{"case", "chain.rope.stiffness", "chain.rope.damping",
                                                 "status", "exit_code", "physics_p50_ms", "physics_p99_ms",
                                                 "physics_max_ms", "hash", "end_x", "detail"}));
    const Sweep s = readSweep(file);
    for (std::size_t c = 0; c < 4; ++c) {
        const auto& row = rows[c + 1];
        EXPECT_EQ(row[0], std::to_string(c));
        const auto [hash, endX] = runHere(s.caseSets(c), 20);
        EXPECT_EQ(row[8], hash) << "case " << c;
        // a blown-up chain is frozen where it blew up; either way the dump's number to the last bit
        EXPECT_EQ(std::stod(row[9]), endX) << "case " << c;
        const bool stiff = c >= 2;
        EXPECT_EQ(row[3], stiff ? "blow_up" : "ok");
        EXPECT_EQ(row[4], stiff ? "1" : "0");
        EXPECT_EQ(row[10].find("entity 'chain' blew up") != std::string::npos, stiff) << row[10];
        EXPECT_GT(std::stod(row[5]), 0.0);
        EXPECT_GE(std::stod(row[7]), std::stod(row[6]));
    }
}

TEST(SweepLocal, ACaseThatFailsIsARowAndTheSweepGoesOn) {
    // 5000 frames of 1000 steps (about a minute) cannot end inside a 3 s limit; the other case, 5000 steps,
    // runs on and ends well inside it (0.3 s in the sanitizer build; 20 000 of them took 1.1-2.3 s there,
    // and over 3 s once in CI while other tests ran beside it)
    const std::string file = writeTemp("timeout.toml", ropeSweep("[[axis]]\nkey = \"scene.substeps\"\n"
                                                                 "values = [1000, 1]\n",
                                                                 "timeout = 3.0", 5000));
    const std::string out = tempPath("timeout_out");
    const auto r = runTumble({"sweep", file, "--local", "-j", "1", "--out", out});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const auto rows = readCsv(out + "/results.csv");
    ASSERT_EQ(rows.size(), 3u);
    EXPECT_EQ(rows[1][2], "error");
    EXPECT_EQ(rows[1][3], std::to_string(128 + SIGKILL));
    EXPECT_NE(rows[1].back().find("timed out after 3"), std::string::npos) << rows[1].back();
    EXPECT_EQ(rows[2][2], "ok");
    EXPECT_NE(r.err.find("case 0 (scene.substeps=1000): error: timed out"), std::string::npos) << r.err;
}

/// Starts `tumble sweep` as a process of its own (to be killed), stdout and stderr to /dev/null.
pid_t startSweep(const std::vector<std::string>& args) {
    std::vector<std::string> argv = {TUMBLE_BINARY};
    argv.insert(argv.end(), args.begin(), args.end());
    const pid_t pid = ::fork();
    if (pid == 0) {
        std::vector<char*> raw;
        for (std::string& a : argv) {
            raw.push_back(a.data());
        }
        raw.push_back(nullptr);
        std::freopen("/dev/null", "w", stdout);
        std::freopen("/dev/null", "w", stderr);
        ::execv(raw[0], raw.data());
        ::_exit(127);
    }
    return pid;
}

std::size_t resultsIn(const std::string& out) {
    std::size_t n = 0;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(out + "/cases", ec)) {
        n += fs::exists(entry.path() / "result.json") ? 1 : 0;
    }
    return n;
}

/// Starts a --local sweep into `out`, waits until `results` of its cases have ended, sends it `signal`
/// and returns its wait status.
int stopSweepAfter(const std::string& file, const std::string& out, const char* jobs, std::size_t results,
                   int signal) {
    const pid_t pid = startSweep({"sweep", file, "--local", "-j", jobs, "--out", out});
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (resultsIn(out) < results && std::chrono::steady_clock::now() < deadline) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    ::kill(pid, signal);
    int status = 0;
    ::waitpid(pid, &status, 0);
    return status;
}

TEST(SweepLocal, ASweepKilledHalfWayFinishesWithTheSameTableAndRerunsNothingFinished) {
    const std::string file =
        writeTemp("killed.toml", ropeSweep("[[axis]]\nkey = \"chain.rope.stiffness\"\n"
                                           "log_range = [500.0, 5000.0, 12]\n"
                                           "[[metric]]\nname = \"end_y\"\nentity = \"chain\"\n"
                                           "component = 1\n",
                                           "", 240));
    const std::string whole = tempPath("whole_out"), killed = tempPath("killed_out");
    ASSERT_EQ(runTumble({"sweep", file, "--local", "-j", "2", "--out", whole}).exitCode, 0);

    stopSweepAfter(file, killed, "1", 4, SIGKILL);
    const std::size_t finished = resultsIn(killed);
    ASSERT_GE(finished, 4u);
    ASSERT_LT(finished, 12u) << "the sweep ended before it was killed: make its cases longer";
    std::map<std::string, std::string> before;
    for (const auto& entry : fs::directory_iterator(killed + "/cases")) {
        if (fs::exists(entry.path() / "result.json")) {
            before[entry.path().string()] = readFile((entry.path() / "result.json").string());
        }
    }

    const auto again = runTumble({"sweep", file, "--local", "-j", "2", "--out", killed});
    ASSERT_EQ(again.exitCode, 0) << again.err;
    EXPECT_NE(again.out.find("(" + std::to_string(12 - finished) + " run now, " + std::to_string(finished) +
                             " from before)"),
              std::string::npos)
        << again.out;
    EXPECT_EQ(untimed(readCsv(killed + "/results.csv")), untimed(readCsv(whole + "/results.csv")));
    for (const auto& [path, text] : before) {
        EXPECT_EQ(readFile(path + "/result.json"), text) << "a finished case ran again: " << path;
    }
}

TEST(SweepLocal, SigtermStopsTheRunsAndKeepsNoResultOfThem) {
    const std::string file = writeTemp("termed.toml", ropeSweep("[[axis]]\nkey = \"chain.rope.damping\"\n"
                                                                "range = [0.1, 0.5, 8]\n",
                                                                "", 240));
    const std::string whole = tempPath("termed_whole"), termed = tempPath("termed_out");
    ASSERT_EQ(runTumble({"sweep", file, "--local", "-j", "2", "--out", whole}).exitCode, 0);
    const int status = stopSweepAfter(file, termed, "2", 2, SIGTERM);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 130);
    const std::size_t kept = resultsIn(termed);
    ASSERT_LT(kept, 8u) << "the sweep ended before it was stopped: make its cases longer";
    // the runs it stopped left no result (a row of exit 130 would be an error never run again)
    for (const auto& entry : fs::directory_iterator(termed + "/cases")) {
        if (fs::exists(entry.path() / "result.json")) {
            EXPECT_EQ(readFile((entry.path() / "result.json").string()).find("\"exit_code\":130"),
                      std::string::npos);
        }
    }
    ASSERT_EQ(runTumble({"sweep", file, "--local", "--out", termed}).exitCode, 0);
    EXPECT_EQ(untimed(readCsv(termed + "/results.csv")), untimed(readCsv(whole + "/results.csv")));
}

TEST(SweepLocal, AChangedSweepFileIsRefusedInTheFolderOfTheOld) {
    const std::string out = tempPath("changed_out");
    const std::string a = writeTemp("changed.toml", ropeSweep("[[axis]]\nkey = \"chain.rope.stiffness\"\n"
                                                              "values = [300.0]\n"));
    ASSERT_EQ(runTumble({"sweep", a, "--local", "--out", out}).exitCode, 0);
    const std::string b = writeTemp("changed.toml", ropeSweep("[[axis]]\nkey = \"chain.rope.stiffness\"\n"
                                                              "values = [300.0, 400.0]\n"));
    const auto r = runTumble({"sweep", b, "--local", "--out", out});
    EXPECT_EQ(r.exitCode, 2);
    EXPECT_NE(r.err.find("holds the results of another sweep"), std::string::npos) << r.err;
}

// Two sweeps started in one folder before either had a result (shards of both, or Slurm arrays queued
// side by side): the second replaced sweep.json, and each then took the other's results for its own, so the
// merged table mixed rows of both (frames 20 and 21 here). A result now names the sweep it was run for:
// another's is no result. Seen to fail (the merge took both rows of the other sweep, exit 0).
TEST(SweepLocal, AnotherSweepsResultsInTheFolderAreNotTakenForThisOnes) {
    const std::string out = tempPath("mixed_out");
    const std::string axis = "[[axis]]\nkey = \"chain.rope.stiffness\"\nvalues = [300.0, 400.0]\n";
    const std::string a = writeTemp("mixed_a.toml", ropeSweep(axis, "", 20));
    ASSERT_EQ(runTumble({"sweep", a, "--local", "--out", out}).exitCode, 0);
    // as when the other sweep replaced sweep.json before any result: b's own, from a run of b elsewhere
    const std::string b = writeTemp("mixed_b.toml", ropeSweep(axis, "", 21));
    const std::string elsewhere = tempPath("mixed_b_out");
    ASSERT_EQ(runTumble({"sweep", b, "--local", "--out", elsewhere}).exitCode, 0);
    std::filesystem::copy_file(elsewhere + "/sweep.json", out + "/sweep.json",
                               std::filesystem::copy_options::overwrite_existing);
    const auto merged = runTumble({"sweep", b, "--merge", "--out", out});
    EXPECT_EQ(merged.exitCode, 1) << merged.err;
    EXPECT_NE(merged.err.find("2 cases have not run"), std::string::npos) << merged.err;
    // and its own run does them again, rather than skipping them as done
    ASSERT_EQ(runTumble({"sweep", b, "--local", "--out", out}).exitCode, 0);
    const auto rows = readCsv(out + "/results.csv");
    ASSERT_EQ(rows.size(), 3u);
    const std::string command = readFile(out + "/cases/00000/command.txt");
    EXPECT_NE(command.find("--frames 21"), std::string::npos) << command;
}

// A shard of another sweep started in a folder while a shard of the first runs there, before any of its
// cases has a result, is refused: before, it found the folder free (no result to lose), replaced
// sweep.json with its own and ran its cases beside the first one's (seen to fail: exit 0).
TEST(SweepLocal, AnotherSweepsShardIsRefusedWhileAShardRuns) {
    const std::string out = tempPath("racing_out");
    const std::string axis = "[[axis]]\nkey = \"chain.rope.stiffness\"\nvalues = [300.0]\n";
    const std::string a = writeTemp("racing_a.toml", ropeSweep(axis, "", 1000000));
    const std::string b = writeTemp("racing_b.toml", ropeSweep(axis, "", 21));
    const pid_t first = startSweep({"sweep", a, "--shard", "0/1", "--out", out});
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!fs::exists(out + "/cases/00000") && std::chrono::steady_clock::now() < deadline) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    const auto second = runTumble({"sweep", b, "--shard", "0/1", "--out", out});
    ::kill(first, SIGTERM);
    int status = 0;
    ::waitpid(first, &status, 0);
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 130) << "the first sweep ended: make it longer";
    EXPECT_EQ(second.exitCode, 2) << second.err;
    EXPECT_NE(second.err.find("another sweep is running in " + out), std::string::npos) << second.err;
    // with the first stopped (no result, no run), the folder is free for the other
    EXPECT_EQ(runTumble({"sweep", b, "--shard", "0/1", "--out", out}).exitCode, 0);
}

TEST(SweepLocal, ShardsRunTheirShareAndMergeMakesTheTable) {
    const std::string file = writeTemp("shards.toml", ropeSweep("[[axis]]\nkey = \"chain.rope.damping\"\n"
                                                                "range = [0.1, 0.6, 7]\n"));
    const std::string whole = tempPath("shards_whole"), sharded = tempPath("shards_out");
    ASSERT_EQ(runTumble({"sweep", file, "--local", "--out", whole}).exitCode, 0);
    for (int i = 0; i < 3; ++i) {
        const auto r = runTumble({"sweep", file, "--shard", std::to_string(i) + "/3", "--out", sharded});
        ASSERT_EQ(r.exitCode, 0) << r.err;
        EXPECT_EQ(resultsIn(sharded), std::size_t(i == 0 ? 3 : i == 1 ? 5 : 7));
        if (i == 1) {
            const auto status = runTumble({"sweep", file, "--status", "--out", sharded});
            EXPECT_NE(status.out.find("7 cases: 2 not run, 5 ok"), std::string::npos) << status.out;
            // a case under way (its folder made, no result yet) was counted as not run
            std::filesystem::create_directories(sharded + "/cases/00002");
            const auto running = runTumble({"sweep", file, "--status", "--out", sharded});
            EXPECT_NE(
                running.out.find("7 cases: 1 not run, 5 ok, 1 started (running, or stopped before its end)"),
                std::string::npos)
                << running.out;
            std::filesystem::remove(sharded + "/cases/00002");
            EXPECT_EQ(runTumble({"sweep", file, "--merge", "--out", sharded}).exitCode, 1);
        }
    }
    ASSERT_EQ(runTumble({"sweep", file, "--merge", "--out", sharded}).exitCode, 0);
    EXPECT_EQ(untimed(readCsv(sharded + "/results.csv")), untimed(readCsv(whole + "/results.csv")));
    EXPECT_EQ(runTumble({"sweep", file, "--shard", "3/3", "--out", sharded}).exitCode, 2);
    // sscanf read '1/-3' as shard 1 of 2^64 - 3 (case 1 alone, exit 0) and took leading blanks
    for (const char* bad : {"1/-3", " 1/3", "1/3x", "+1/3", "1/ 3"}) {
        const auto r = runTumble({"sweep", file, "--shard", bad, "--out", sharded});
        EXPECT_EQ(r.exitCode, 2) << bad;
        EXPECT_NE(r.err.find("is not a shard"), std::string::npos) << bad << ": " << r.err;
    }
    // an option of another mode, and an empty --out, were taken without a word
    EXPECT_NE(runTumble({"sweep", file, "--merge", "--threads", "2", "--out", sharded})
                  .err.find("--threads goes with --local, --slurm or --shard"),
              std::string::npos);
    EXPECT_EQ(runTumble({"sweep", file, "--status", "--threads", "3", "--out", sharded}).exitCode, 2);
    EXPECT_EQ(runTumble({"sweep", file, "--local", "--out", ""}).exitCode, 2);
    // --merge wrote a results.csv of empty rows into any folder it was given, made if missing
    const std::string elsewhere = test::tempPath("not_a_sweep_folder");
    std::filesystem::remove_all(elsewhere);
    const auto merged = runTumble({"sweep", file, "--merge", "--out", elsewhere});
    EXPECT_EQ(merged.exitCode, 1);
    EXPECT_NE(merged.err.find("holds no run of this sweep"), std::string::npos) << merged.err;
    EXPECT_FALSE(std::filesystem::exists(elsewhere));
    // and --progress with --quiet showed no progress: now refused, as two counts that are no whole number
    const auto both = runTumble({"sweep", file, "--local", "--progress", "--quiet", "--out", sharded});
    EXPECT_EQ(both.exitCode, 2);
    EXPECT_NE(both.err.find("--quiet excludes --progress"), std::string::npos) << both.err;
    const auto jobs = runTumble({"sweep", file, "--local", "-j", "two", "--out", sharded});
    EXPECT_EQ(jobs.exitCode, 2);
    EXPECT_NE(jobs.err.find("'two' is not a whole number (from 1 to 1024)"), std::string::npos) << jobs.err;
}

TEST(SweepLocal, PlotDrawsEachCaseAndTheBudgetForTimes) {
    const std::string file = writeTemp("plot.toml", ropeSweep("[[axis]]\nkey = \"chain.rope.stiffness\"\n"
                                                              "values = [300.0, 600.0, 1e9]\n"
                                                              "[[axis]]\nkey = \"chain.rope.damping\"\n"
                                                              "values = [0.1, 0.3]\n"));
    const std::string out = tempPath("plot_out");
    ASSERT_EQ(runTumble({"sweep", file, "--local", "--out", out}).exitCode, 0);
    const auto r = runTumble({"sweep", file, "--plot", "physics_p99_ms", "--out", out});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const std::string svg = readFile(out + "/plot_physics_p99_ms_by_chain.rope.stiffness.svg");
    auto count = [&](const std::string& what) {
        std::size_t n = 0;
        for (std::size_t at = 0; (at = svg.find(what, at)) != std::string::npos; ++at) {
            ++n;
        }
        return n;
    };
    // four cases ended ok (dots), two blew up (crosses); a line per damping; the rope's 2 ms budget
    EXPECT_EQ(count("<circle"), 4u);
    EXPECT_EQ(count(">x</text>"), 2u);
    EXPECT_EQ(count("<path"), 2u);
    // each line joins its two cases that ended ok, not the blown-up one (it was drawn through it: 4)
    EXPECT_EQ(count(" L"), 2u);
    EXPECT_NE(svg.find("budget 2 ms"), std::string::npos);
    EXPECT_NE(svg.find("chain.rope.damping = 0.3"), std::string::npos);
    const auto bad = runTumble({"sweep", file, "--plot", "physics_p99_m", "--out", out});
    EXPECT_EQ(bad.exitCode, 2);
    EXPECT_NE(bad.err.find("did you mean 'physics_p99_ms'"), std::string::npos) << bad.err;
}

TEST(SweepSlurm, WithoutSlurmTheMessageNamesWhatIsMissing) {
    const std::string file = writeTemp("noslurm.toml", ropeSweep(""));
    const std::string empty = tempPath("empty_path");
    fs::create_directories(empty);
    const std::string out = tempPath("noslurm_out");
    const auto r = runTumble({"sweep", file, "--slurm", "--out", out}, {"PATH=" + empty});
    EXPECT_EQ(r.exitCode, 2);
    EXPECT_NE(r.err.find("`sbatch` is not on this machine's PATH"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out)) << "a sweep that could not start made its folder";
}

} // namespace
} // namespace tumble
