#pragma once
// Helpers shared by the tests: running the real `tumble` program, temporary files, loading a scenario.

#include "engine/catalog.h"
#include "engine/name.h"
#include "engine/simulation.h"

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace tumble::test {

/// What a run of the `tumble` program did.
struct ProcessResult {
    int exitCode = -1;
    std::string out; ///< stdout
    std::string err; ///< stderr
};

/// Runs the built `tumble` with the given arguments (each shell-quoted), stdin from /dev/null; `environment`
/// (NAME=value words) is set for it alone.
ProcessResult runTumble(const std::vector<std::string>& args,
                        const std::vector<std::string>& environment = {});

/// A fresh path under the tests' temporary folder (the folder exists; the file does not).
std::string tempPath(const std::string& name);

/// Writes text to a fresh temporary file and returns its path.
std::string writeTemp(const std::string& name, const std::string& text);

/// Reads a whole file.
std::string readFile(const std::string& path);

/// No gravity; an entity "box" (`bodyTables`: its transform at (0, 1, 0) and its body) held at its centre
/// by a spring stretched to 200 N along +y from a pin at (0, 3, 0): the scene of the 2D and 3D tests that a
/// pull through a body's centre turns nothing while the body slides across it.
std::string slideAcrossAPull(const std::string& bodyTables);

/// An entity "bob" that blows up in its first steps at 60 Hz: a mass on a spring of k = 1e6 stretched by
/// half from a pin, under explicit Euler (for the tests of what a blow-up does).
extern const char* const kBlowingUpBob;

/// The names of the demos in demos/ (file stems), sorted.
std::vector<std::string> demoNames();

/// The catalog of built-in systems.
const Catalog& builtinCatalog();

/// The component T of the entity with this name; fails the test (and throws) if there is none.
template <class T>
T& component(Simulation& sim, const std::string& name) {
    T* out = nullptr;
    sim.world().view<const Name, T>().each([&](Entity, const Name& n, T& c) {
        if (n.value == name) {
            out = &c;
        }
    });
    if (!out) {
        throw std::runtime_error("no entity '" + name + "' with that component");
    }
    return *out;
}

/// A simulation of scenario text (throws ScenarioError like the CLI would).
std::unique_ptr<Simulation> makeSimulation(const std::string& text,
                                           const std::vector<std::string>& overrides = {});

} // namespace tumble::test
