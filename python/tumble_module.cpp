// The Python module `tumble` (CONTRACT.md, "Embedding"): tumble/sandbox.h through pybind11. Positions and
// velocities come back as NumPy arrays (N, 3) or (N, 2) of float64; dumps and profiles as dicts; bad input
// raises tumble.ScenarioError (a ValueError) with the command line's message; stepping releases the GIL.

#include <tumble/sandbox.h>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <limits>

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
    if (py::isinstance<py::float_>(value) || py::isinstance<py::int_>(value)) {
        return {value.cast<double>()};
    }
    return value.cast<std::vector<double>>();
}

py::object parseJson(const std::string& text) {
    return py::module_::import("json").attr("loads")(text);
}

void bindSandbox(py::module_& m) {
    using tumble::Sandbox;
    py::class_<Sandbox>(m, "Sandbox", "One scenario running in one world (CONTRACT.md, \"Embedding\").")
        .def(py::init([](const std::string& scenario, const std::vector<std::string>& set,
                         std::optional<int> threads) {
                 if (threads && (*threads < 1 || *threads > 256)) {
                     throw py::value_error("threads must be from 1 to 256 (or None: every hardware thread)");
                 }
                 return std::make_unique<Sandbox>(scenario, set, threads.value_or(0));
             }),
             py::arg("scenario"), py::arg("set") = std::vector<std::string>{},
             py::arg("threads") = py::none(),
             "Loads a demo by name or a .toml file, with --set overrides (\"KEY=VALUE\").")
        .def(
            "step",
            [](Sandbox& s, long frames) {
                if (frames < 0 || frames > std::numeric_limits<int>::max()) {
                    throw py::value_error("frames must be from 0 to 2**31 - 1");
                }
                py::gil_scoped_release released;
                s.step(int(frames));
            },
            py::arg("frames") = 1, "Runs frames (each the scene's substeps fixed steps), the GIL released.")
        .def_property_readonly("frame", &Sandbox::frame, "Frames run.")
        .def_property_readonly("time", &Sandbox::time, "Simulated time, s.")
        .def_property_readonly("dt", &Sandbox::dt, "The fixed step, s.")
        .def_property_readonly("entities", &Sandbox::entities, "Every named entity: name -> kind.")
        .def(
            "x",
            [](const Sandbox& s, const std::string& name) { return asArray(s.x(name), s.dimensions(name)); },
            py::arg("name"), "Positions, (N, 3) or (N, 2) float64.")
        .def(
            "v",
            [](const Sandbox& s, const std::string& name) { return asArray(s.v(name), s.dimensions(name)); },
            py::arg("name"), "Velocities, (N, 3) or (N, 2) float64.")
        .def(
            "apply",
            [](Sandbox& s, const std::string& entity, const std::string& action, const py::object& value,
               std::optional<std::array<double, 3>> position, std::optional<double> radius,
               std::optional<double> amount) {
                s.apply(entity, action, numbers(value), position, radius, amount);
            },
            py::arg("entity"), py::arg("action"), py::arg("value") = py::none(),
            py::arg("position") = py::none(), py::arg("radius") = py::none(), py::arg("amount") = py::none(),
            "Applies one of the scenario's actions at the start of the next step.")
        .def("set", &Sandbox::set, py::arg("key_value"), "A set event: \"KEY=VALUE\" as --set takes it.")
        .def("hash", &Sandbox::hash, "The 64-bit state hash of this frame (the dump's \"hash\").")
        .def(
            "dump", [](const Sandbox& s) { return parseJson(s.dump()); },
            "This frame's dump line, as a dict.")
        .def(
            "profile", [](const Sandbox& s) { return parseJson(s.profile()); },
            "The budget summary, as a dict.")
        .def("failures", &Sandbox::failures, "Problems met while stepping (a blow-up), in order.")
        .def("record", &Sandbox::record, py::arg("path"), "Records a replay from frame 0 (call before step).")
        .def("finish_recording", &Sandbox::finishRecording, "Ends the replay being recorded.");
}

} // namespace

PYBIND11_MODULE(tumble, m) {
    m.doc() = "Tumble, a real-time physics sandbox, as a Python module.";
    static py::exception<tumble::ScenarioError> scenarioError(m, "ScenarioError", PyExc_ValueError);
    static py::exception<tumble::ReplayError> replayError(m, "ReplayError", PyExc_ValueError);
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) {
                std::rethrow_exception(p);
            }
        } catch (const tumble::ScenarioError& e) {
            scenarioError(e.what());
        } catch (const tumble::ReplayError& e) {
            replayError(e.what());
        }
    });
    bindSandbox(m);
    m.def(
        "verify",
        [](const std::string& path, std::optional<int> threads) {
            std::string diverged;
            {
                py::gil_scoped_release released;
                diverged = tumble::verifyReplay(path, threads.value_or(0));
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
