#include "engine/retune.h"

#include "engine/name.h"
#include "engine/transform.h"

#include <limits>
#include <map>
#include <optional>

namespace tumble {

namespace {

/// The scenario loaded with the overrides and `sets` into a world of its own.
struct Scratch {
    World world;
    Scenario scenario;
    std::map<std::string, Entity> byName;

    Scratch(const Catalog& catalog, const Scenario& sc, const std::vector<std::string>& sets,
            std::uint64_t memoryCap)
        : scenario(loadScenarioWithSets(catalog, sc.path, sc.text, sc.overrides, sets, world, memoryCap)) {
        for (Entity e : world.entities()) {
            if (const Name* n = world.tryGet<Name>(e)) {
                byName[n->value] = e;
            }
        }
    }
};

std::string quoted(const std::string& spec) {
    return "set " + (spec.size() > 100 ? spec.substr(0, 100) + "..." : spec);
}

/// A scene setting that differs between the two loads and cannot change during a run, if any.
std::optional<std::string> fixedSceneSetting(const SceneDef& a, const SceneDef& b) {
    if (a.dt != b.dt || a.substeps != b.substeps) {
        return std::string("scene.dt and scene.substeps cannot change during a run (its events and replay "
                           "count in its steps)");
    }
    if (a.name != b.name || a.description != b.description || a.frames != b.frames || a.seed != b.seed ||
        a.stress != b.stress) {
        return std::string("scene.name, description, frames and seed, and budget.stress, hold for the "
                           "whole run");
    }
    if (a.renderWidth != b.renderWidth || a.renderHeight != b.renderHeight) {
        return std::string("render.width and render.height cannot change during a run (the frames and "
                           "video keep one size)");
    }
    return std::nullopt;
}

/// The scene settings that differ between the two loads, written into `live`.
void patchScene(SceneDef& live, const SceneDef& before, const SceneDef& after) {
    auto take = [](auto& to, const auto& was, const auto& now) {
        if (was != now) {
            to = now;
        }
    };
    take(live.gravity, before.gravity, after.gravity);
    take(live.solverIterations, before.solverIterations, after.solverIterations);
    take(live.velocityIterations, before.velocityIterations, after.velocityIterations);
    take(live.positionIterations, before.positionIterations, after.positionIterations);
    take(live.sleepLinear, before.sleepLinear, after.sleepLinear);
    take(live.sleepAngularDeg, before.sleepAngularDeg, after.sleepAngularDeg);
    take(live.sleepTime, before.sleepTime, after.sleepTime);
    take(live.physicsBudgetMs, before.physicsBudgetMs, after.physicsBudgetMs);
    take(live.cameraEye, before.cameraEye, after.cameraEye);
    take(live.cameraTarget, before.cameraTarget, after.cameraTarget);
    take(live.cameraFovDeg, before.cameraFovDeg, after.cameraFovDeg);
    take(live.background, before.background, after.background);
}

/// The component key a KEY=VALUE names (the second part of entity.component.key), or "" for a section.
std::string componentKey(const std::string& spec) {
    const std::string key = spec.substr(0, spec.find('='));
    const auto first = key.find('.');
    if (first == std::string::npos) {
        return "";
    }
    const std::string head = key.substr(0, first);
    if (head == "scene" || head == "budget" || head == "camera" || head == "render") {
        return "";
    }
    const auto second = key.find('.', first + 1);
    return key.substr(first + 1, second == std::string::npos ? std::string::npos : second - first - 1);
}

/// What a running scene cannot take between two loads of it (a fixed scene setting, entities or components
/// added or removed, a component's own refusal), or nothing.
std::optional<std::string> cannotTake(const Catalog& catalog, const Scratch& before, const Scratch& after) {
    if (auto fixed = fixedSceneSetting(before.scenario.scene, after.scenario.scene)) {
        return fixed;
    }
    if (before.byName.size() != after.byName.size()) {
        return std::string("it would add or remove entities, which a running scene cannot");
    }
    for (const auto& [name, b] : before.byName) {
        const auto found = after.byName.find(name);
        if (found == after.byName.end()) {
            return std::string("it would add or remove entities, which a running scene cannot");
        }
        const Entity a = found->second;
        for (const Retune& r : catalog.retunes()) {
            if (r.has(before.world, b) != r.has(after.world, a)) {
                return "it would add or remove a component of '" + name + "', which a running scene cannot";
            }
            if (!r.has(before.world, b)) {
                continue;
            }
            if (auto problem = r.check(before.world, b, after.world, a)) {
                return problem;
            }
        }
    }
    return std::nullopt;
}

/// A value moved so that it differs from the given one: numbers by `variant` (+1, -1, halved), each of
/// an array's alike, true and false swapped; false when it cannot be (a string, a table).
bool moveValue(toml::node& n, int variant) {
    if (auto* a = n.as_array()) {
        bool any = !a->empty();
        for (auto& item : *a) {
            any = moveValue(item, variant) && any;
        }
        return any;
    }
    if (auto* i = n.as_integer()) {
        const std::int64_t v = i->get();
        constexpr std::int64_t top = std::numeric_limits<std::int64_t>::max();
        constexpr std::int64_t bottom = std::numeric_limits<std::int64_t>::min();
        *i = variant == 0   ? (v < top ? v + 1 : v - 1)
             : variant == 1 ? (v > bottom ? v - 1 : v + 1)
                            : v / 2 + (v == 0 ? 2 : 0);
        return true;
    }
    if (auto* d = n.as_floating_point()) {
        const double v = d->get();
        *d = variant == 0 ? v + 1.0 : variant == 1 ? v - 1.0 : (v == 0.0 ? 0.5 : 0.5 * v);
        return true;
    }
    if (auto* b = n.as_boolean()) {
        *b = !b->get();
        return variant == 0;
    }
    return false;
}

/// The load to compare a set with when it is applied: the earlier sets and this key at another value, so
/// that whatever the key reaches differs from the set's own load and is taken, even where the set's value
/// is the file's (a velocity set back to the file's [0, 0, 0] while the body moves). None where no other
/// value loads (a string, a value at its range's end both ways) or would reshape a thing.
void comparedWith(const Catalog& catalog, const Scenario& scenario, const std::vector<std::string>& earlier,
                  const std::string& spec, std::uint64_t memoryCap, const Scratch& after,
                  std::optional<Scratch>& before) {
    const auto eq = spec.find('=');
    toml::table parsed;
    try {
        parsed = toml::parse("v = " + spec.substr(eq + 1));
    } catch (const toml::parse_error&) {
        parsed = {};
    }
    for (int variant = 0; variant < 3 && parsed.contains("v"); ++variant) {
        toml::table copy = parsed;
        if (!moveValue(*copy.get("v"), variant)) {
            continue;
        }
        std::vector<std::string> probe = earlier;
        probe.push_back(spec.substr(0, eq) + "=" + oneLineToml(*copy.get("v")));
        try {
            before.emplace(catalog, scenario, probe, memoryCap);
        } catch (const ScenarioError&) {
            continue; // out of the key's range that way: try another
        }
        if (!cannotTake(catalog, *before, after)) {
            return; // (a moved value that would reshape a thing, rows = 7 for rows = 6, is no comparison)
        }
        before.reset();
    }
}

} // namespace

std::optional<std::string> checkSet(const Catalog& catalog, const Scenario& scenario,
                                    const std::vector<std::string>& earlier, const std::string& spec,
                                    std::uint64_t memoryCap) {
    const std::string component = componentKey(spec);
    if (!component.empty() && component != "transform" && !catalog.findRetune(component)) {
        return quoted(spec) + ": '" + component +
               "' cannot change during a run (a set event changes a component's settings: "
               "transform, or a component such as cloth, emitter, rigid_body)";
    }
    // the loads: a bad key or value fails here with the loader's own message, naming the set
    std::vector<std::string> with = earlier;
    with.push_back(spec);
    std::optional<Scratch> before, after;
    try {
        before.emplace(catalog, scenario, earlier, memoryCap);
    } catch (const ScenarioError& e) {
        return e.message();
    }
    try {
        after.emplace(catalog, scenario, with, memoryCap);
    } catch (const ScenarioError& e) {
        // the loader names the set where the set's own key or value is at fault; what the set breaks
        // elsewhere (a source left outside its moved air grid) it does not
        const std::string message = e.message();
        return message.rfind(quoted(spec), 0) == 0 ? message : quoted(spec) + ": with it, " + message;
    }
    if (auto problem = cannotTake(catalog, *before, *after)) {
        return quoted(spec) + ": " + *problem;
    }
    return std::nullopt;
}

void applySet(const Catalog& catalog, const Scenario& scenario, const std::vector<std::string>& earlier,
              const std::string& spec, std::uint64_t memoryCap, World& live, SceneDef& scene) {
    std::vector<std::string> with = earlier;
    with.push_back(spec);
    const Scratch plain(catalog, scenario, earlier, memoryCap), after(catalog, scenario, with, memoryCap);
    // what the set changes against the earlier sets (whatever the key's being there brings: a wave maker
    // that one of its keys adds), then what the key reaches against the key at another value (whatever it
    // sets to the file's own value, which the run may have moved from)
    auto pass = [&](const Scratch& before) {
        patchScene(scene, before.scenario.scene, after.scenario.scene);
        patchScene(live.resource<SceneDef>(), before.scenario.scene, after.scenario.scene);
        for (Entity e : live.entities()) {
            const Name* name = live.tryGet<Name>(e);
            if (!name) {
                continue;
            }
            const auto b = before.byName.find(name->value), a = after.byName.find(name->value);
            if (b == before.byName.end() || a == after.byName.end()) {
                continue;
            }
            // the components first (they may look at how the entity's transform changed), then the transform
            for (const Retune& r : catalog.retunes()) {
                if (r.has(live, e) && r.has(before.world, b->second)) {
                    r.patch(live, e, before.world, b->second, after.world, a->second);
                }
            }
            const Transform* tb = before.world.tryGet<Transform>(b->second);
            const Transform* ta = after.world.tryGet<Transform>(a->second);
            if (Transform* t = live.tryGet<Transform>(e); t && tb && ta) {
                if (tb->position != ta->position) {
                    t->position = ta->position;
                }
            }
        }
    };
    pass(plain);
    std::optional<Scratch> moved;
    comparedWith(catalog, scenario, earlier, spec, memoryCap, after, moved);
    if (moved) {
        pass(*moved);
    }
}

} // namespace tumble
