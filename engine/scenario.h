#pragma once
// The scenario loader: a TOML file (README, "Using it") and its --set overrides become a SceneDef, a list of
// events and the entities of a world. toml++ parses; every table is then read against its schema through
// TableReader, so an unknown key, a wrong type, a value out of range or a non-finite number stops the load
// with `file:line:col: what is wrong`. Entity components are read by the loaders the systems registered in
// the Catalog; the loader knows none of them by name.
//
// Overrides (`--set KEY=VALUE`) are applied to the parsed tree before validation, so they are typed and
// checked by the same schema as the file. KEY is `section.key` for scene, budget, camera and render, or
// `entity.component.key` (any depth) for the entity with that name. VALUE is read as a TOML value; a
// value that is not valid TOML is taken as a string (so `integrator=rk4` works without quotes).

#include "engine/catalog.h"
#include "engine/scene.h"
#include "engine/table_reader.h"
#include "engine/world.h"

#include <optional>
#include <string>
#include <vector>

namespace tumble {

/// A loaded scenario: what the run needs beyond the entities it created.
struct Scenario {
    std::string path;                   ///< as given (messages name it)
    std::string text;                   ///< the file's text, unchanged (replays keep it)
    std::vector<std::string> overrides; ///< the --set arguments, in order
    SceneDef scene;
    std::vector<EventDef> events; ///< sorted by step, then file order
};

/// Reads a scenario file (or another TOML file: `what` is how the messages name it). Throws ScenarioError
/// (file named, no line) when it cannot be read.
std::string readScenarioFile(const std::string& path, const std::string& what = "the scenario");

/// Parses TOML text; a syntax error is a ScenarioError at its line and column (other files in TOML, such
/// as sweep files, are read with it too).
toml::table parseToml(const std::string& path, const std::string& text);

/// Parses, applies overrides, validates, and creates the scenario's entities in the world.
/// Throws ScenarioError for the first problem. The world is left partly filled on error.
/// `memoryCap` bounds the memory the scene's components may ask for (LoadContext::charge).
Scenario loadScenario(const Catalog& catalog, const std::string& path, std::string text,
                      const std::vector<std::string>& overrides, World& world,
                      std::uint64_t memoryCap = kDefaultMemoryCap);

/// loadScenario with `sets` applied after the overrides, as `set` events apply them (messages name each
/// as "set KEY=VALUE"), and the scenario's own set events not checked: for engine/retune.h's scratch loads.
Scenario loadScenarioWithSets(const Catalog& catalog, const std::string& path, std::string text,
                              const std::vector<std::string>& overrides, const std::vector<std::string>& sets,
                              World& world, std::uint64_t memoryCap);

/// Reads only [scene] name and description, for `tumble list`. Throws ScenarioError.
SceneDef peekScene(const std::string& path, const std::string& text);

/// The first fixed step whose time reaches `at` seconds, as the scenario's `at` of an event means it.
std::uint64_t stepReaching(double at, double dt);

/// Resolves an event that did not come from the scenario file (external input, a replay): its entity by
/// name and its action, checked as the scenario's events are; `present` lists the optional keys it gave
/// (value, position, radius, amount). The message says what is wrong, or nothing when it resolves.
std::optional<std::string> resolveEvent(const Catalog& catalog, const World& world, EventDef& ev,
                                        const std::vector<std::string>& present);

} // namespace tumble
