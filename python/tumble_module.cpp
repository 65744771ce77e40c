// The Python module `tumble` (CONTRACT.md, "Embedding"): tumble/sandbox.h through pybind11. Positions and
// velocities come back as NumPy arrays (N, 3) or (N, 2) of float64; dumps and profiles as dicts; bad input
// raises tumble.ScenarioError (a ValueError) with the command line's message (and its file, line and column);
// stepping releases the GIL, and each Sandbox has a lock, so that two Python threads sharing one take turns.

#include <tumble/sandbox.h>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <limits>
#include <mutex>
#include <utility>

namespace py = pybind11;

namespace {

/// Rows of three as an (N, dims) float64 array.
py::array_t<double> asArray(const std::vector<std::array<double, 3>>& rows, int dims) {
    py::array_t<double> out({py::ssize_t(rows.size()), py::ssize_t(dims)});
    auto w = out.mutable_unchecked<2>();
    for (std::size_t i = 0; i < rows.size(); ++i) {
        for (int k = 0; k < dims; ++k) {
            w(py::ssize_t(i), k) = rows[i][std::size_t(k)];
        }
    }
    return out;
}

/// A number or a sequence of numbers (None: none), for an action's value.
std::vector<double> numbers(const py::object& value) {
    if (value.is_none()) {
        return {};
    }
    try {
        if (py::isinstance<py::float_>(value) || py::isinstance<py::int_>(value)) {
            return {value.cast<double>()};
        }
        return value.cast<std::vector<double>>();
    } catch (const py::cast_error&) {
        throw py::type_error("apply: 'value' must be a number or a sequence of numbers, not " +
                             std::string(py::str(py::type::of(value).attr("__name__"))));
    }
}

/// A thread count from Python: None for every hardware thread, else 1 to 256.
int threadCount(std::optional<int> threads) {
    if (threads && (*threads < 1 || *threads > 256)) {
        throw py::value_error("threads must be from 1 to 256 (or None: every hardware thread)");
    }
    return threads.value_or(0);
}

/// A Sandbox and the lock that lets one thread at a time use it: step() runs without the GIL, so another
/// Python thread could otherwise read or step the same world while it steps.
struct Locked {
    Locked(const std::string& scenario, const std::vector<std::string>& set, int threads)
        : sandbox(scenario, set, threads) {}
    tumble::Sandbox sandbox;
    std::mutex lock;
};

/// fn(sandbox) under the Sandbox's lock, waited for and run without the GIL (fn makes no Python object).
template <class F>
auto withLock(Locked& s, F&& fn) {
    py::gil_scoped_release released;
    const std::lock_guard<std::mutex> hold(s.lock);
    return fn(s.sandbox);
}

py::object parseJson(const std::string& text) {
    return py::module_::import("json").attr("loads")(text);
}

void bindSandbox(py::module_& m) {
    using tumble::Sandbox;
    // every method takes the Locked by reference: one made by __new__ alone (no __init__) raises, not crashes
    py::class_<Locked>(m, "Sandbox", "One scenario running in one world (CONTRACT.md, \"Embedding\").")
        .def(py::init([](const std::filesystem::path& scenario, const std::vector<std::string>& set,
                         std::optional<int> threads) {
                 return std::make_unique<Locked>(scenario.string(), set, threadCount(threads));
             }),
             py::arg("scenario"), py::arg("set") = std::vector<std::string>{},
             py::arg("threads") = py::none(),
             "Loads a demo by name or a .toml file (a str or a path), with --set overrides (\"KEY=VALUE\").")
        .def(
            "step",
            [](Locked& s, long frames) {
                if (frames < 0 || frames > std::numeric_limits<int>::max()) {
                    throw py::value_error("frames must be from 0 to 2**31 - 1");
                }
                const std::vector<std::string> fresh = withLock(s, [&](Sandbox& b) {
                    const std::size_t before = b.failures().size();
                    b.step(int(frames));
                    std::vector<std::string> all = b.failures();
                    return std::vector<std::string>(all.begin() + std::ptrdiff_t(before), all.end());
                });
                // each problem met while stepping (a blow-up) as a RuntimeWarning, once, as the command line
                // prints it: step() returned as if all were well, the blow-up in failures() alone
                for (const std::string& failure : fresh) {
                    if (PyErr_WarnEx(PyExc_RuntimeWarning, failure.c_str(), 1) != 0) {
                        throw py::error_already_set(); // warnings turned into errors
                    }
                }
            },
            py::arg("frames") = 1,
            "Runs frames (each the scene's substeps fixed steps), the GIL released. A problem met on the way "
            "(a blow-up) is warned of (RuntimeWarning) and kept in failures().")
        .def_property_readonly(
            "frame", [](Locked& s) { return withLock(s, [](Sandbox& b) { return b.frame(); }); },
            "Frames run.")
        .def_property_readonly(
            "time", [](Locked& s) { return withLock(s, [](Sandbox& b) { return b.time(); }); },
            "Simulated time, s.")
        .def_property_readonly(
            "dt", [](Locked& s) { return withLock(s, [](Sandbox& b) { return b.dt(); }); },
            "The fixed step, s.")
        .def_property_readonly(
            "entities", [](Locked& s) { return withLock(s, [](Sandbox& b) { return b.entities(); }); },
            "Every named entity whose state the dump lists: name -> kind.")
        .def(
            "x",
            [](Locked& s, const std::string& name) {
                auto [rows, dims] = withLock(s, [&](Sandbox& b) {
                    return std::pair{b.x(name), b.dimensions(name)};
                });
                return asArray(rows, dims);
            },
            py::arg("name"), "Positions, (N, 3) or (N, 2) float64.")
        .def(
            "v",
            [](Locked& s, const std::string& name) {
                auto [rows, dims] = withLock(s, [&](Sandbox& b) {
                    return std::pair{b.v(name), b.dimensions(name)};
                });
                return asArray(rows, dims);
            },
            py::arg("name"), "Velocities, (N, 3) or (N, 2) float64.")
        .def(
            "apply",
            [](Locked& s, const std::string& entity, const std::string& action, const py::object& value,
               std::optional<std::array<double, 3>> position, std::optional<double> radius,
               std::optional<double> amount) {
                const std::vector<double> values = numbers(value);
                withLock(s, [&](Sandbox& b) { b.apply(entity, action, values, position, radius, amount); });
            },
            py::arg("entity"), py::arg("action"), py::arg("value") = py::none(),
            py::arg("position") = py::none(), py::arg("radius") = py::none(), py::arg("amount") = py::none(),
            "Applies one of the scenario's actions at the start of the next step (numbers finite, within "
            "+-1e9).")
        .def(
            "set", [](Locked& s, const std::string& kv) { withLock(s, [&](Sandbox& b) { b.set(kv); }); },
            py::arg("key_value"), "A set event: \"KEY=VALUE\" as --set takes it.")
        .def(
            "hash", [](Locked& s) { return withLock(s, [](Sandbox& b) { return b.hash(); }); },
            "The 64-bit state hash of this frame (the dump's \"hash\").")
        .def(
            "dump", [](Locked& s) { return parseJson(withLock(s, [](Sandbox& b) { return b.dump(); })); },
            "This frame's dump line, as a dict.")
        .def(
            "profile",
            [](Locked& s) { return parseJson(withLock(s, [](Sandbox& b) { return b.profile(); })); },
            "The budget summary, as a dict.")
        .def(
            "failures", [](Locked& s) { return withLock(s, [](Sandbox& b) { return b.failures(); }); },
            "Problems met while stepping (a blow-up), in order.")
        .def(
            "record",
            [](Locked& s, const std::filesystem::path& path) {
                withLock(s, [&](Sandbox& b) { b.record(path.string()); });
            },
            py::arg("path"), "Records a replay from frame 0 (call before step; one recording at a time).")
        .def(
            "finish_recording", [](Locked& s) { withLock(s, [](Sandbox& b) { b.finishRecording(); }); },
            "Ends the replay being recorded.");
}

} // namespace

PYBIND11_MODULE(tumble, m) {
    m.doc() = "Tumble, a real-time physics sandbox, as a Python module.";
    static py::exception<tumble::ScenarioError> scenarioError(m, "ScenarioError", PyExc_ValueError);
    static py::exception<tumble::ReplayError> replayError(m, "ReplayError", PyExc_ValueError);
    scenarioError.attr("__doc__") =
        "A problem in a scenario, its overrides or an action: str() is 'file:line:col: what is wrong'; "
        "also .file, .line and .column (0 when unknown) and .message.";
    replayError.attr("__doc__") =
        "A replay file that cannot be read: the message names the file and the byte.";
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) {
                std::rethrow_exception(p);
            }
        } catch (const tumble::ScenarioError& e) {
            py::object error = py::reinterpret_borrow<py::object>(scenarioError.ptr())(e.what());
            error.attr("file") = e.file();
            error.attr("line") = e.line();
            error.attr("column") = e.column();
            error.attr("message") = e.message();
            PyErr_SetObject(scenarioError.ptr(), error.ptr());
        } catch (const tumble::ReplayError& e) {
            replayError(e.what());
        }
    });
    bindSandbox(m);
    m.def(
        "verify",
        [](const std::filesystem::path& path, std::optional<int> threads) {
            const int count = threadCount(threads);
            std::string diverged;
            {
                py::gil_scoped_release released;
                diverged = tumble::verifyReplay(path.string(), count);
            }
            if (!diverged.empty()) {
                throw std::runtime_error(diverged);
            }
            return true;
        },
        py::arg("path"), py::arg("threads") = py::none(),
        "Replays a replay and compares every frame's hash: True, or RuntimeError naming the first "
        "divergence.");
}
