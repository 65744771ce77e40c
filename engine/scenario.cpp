#include "engine/scenario.h"

#include "engine/retune.h"

#include "engine/name.h"
#include "engine/random.h"
#include "engine/transform.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <sys/stat.h>
#include <vector>

namespace tumble {

namespace {

constexpr double kHuge = 1e9; // bound on coordinates, m
constexpr std::string_view kSections[] = {"scene", "budget", "camera", "render"};
// components of the scenario format (README) that arrive with later work

bool validName(std::string_view s) {
    if (s.empty() || s.size() > 64) {
        return false;
    }
    return std::all_of(s.begin(), s.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
               c == '-';
    });
}

bool isSection(std::string_view s) {
    return std::find(std::begin(kSections), std::end(kSections), s) != std::end(kSections);
}

// ---- overrides

/// A word that --set takes as a string without quotes: letters, digits, '_', '-', '.', and not a number.
bool isBareWord(std::string_view s) {
    if (s.empty()) {
        return true; // KEY= sets the empty string
    }
    const char c0 = s.front();
    if (!((c0 >= 'a' && c0 <= 'z') || (c0 >= 'A' && c0 <= 'Z') || c0 == '_')) {
        return false;
    }
    return std::all_of(s.begin(), s.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
               c == '-' || c == '.';
    });
}

toml::table* findEntityTable(toml::table& root, std::string_view name) {
    toml::array* entities = root["entity"].as_array();
    if (!entities) {
        return nullptr;
    }
    for (toml::node& n : *entities) {
        toml::table* t = n.as_table();
        if (t && t->get_as<std::string>("name") && t->get_as<std::string>("name")->get() == name) {
            return t;
        }
    }
    return nullptr;
}

/// Whether TOML refused a number for its size alone: strtod reads all of it as an infinity, and it is no
/// spelling of inf or nan, nor a hex float (which TOML refuses for its form).
bool beyondDouble(const std::string& text) {
    char* end = nullptr;
    return !text.empty() && std::isinf(std::strtod(text.c_str(), &end)) &&
           end == text.c_str() + text.size() && text.find_first_of("iInNxXpP") == std::string::npos;
}

/// An override's value put at `last` in `table`: one TOML value, or a bare word taken as a string
/// (integrator=rk4); anything else is an error, which says what TOML found wrong with it.
void setOverrideValue(toml::table& table, const std::string& last, const std::string& text,
                      const std::string& origin, LoadContext& ctx) {
    toml::table parsed;
    bool isToml = text.find('\n') == std::string::npos && text.find('\r') == std::string::npos;
    std::string tomlSays; // what the TOML parser found wrong, for the message
    if (isToml) {
        try {
            parsed = toml::parse("v = " + text, origin);
        } catch (const toml::parse_error& e) {
            isToml = false;
            tomlSays = std::string(e.description());
        }
    }
    if (isToml && parsed.size() == 1 && parsed.contains("v")) {
        parsed.get("v")->visit([&](auto&& n) { table.insert_or_assign(last, std::move(n)); });
    } else if (isBareWord(text)) {
        table.insert_or_assign(last, text);
    } else if (beyondDouble(text)) {
        throw ScenarioError(ctx.file, 0, 0,
                            origin + ": the number is beyond a double's range (about +-1.8e308)");
    } else {
        throw ScenarioError(ctx.file, 0, 0,
                            origin +
                                ": the value is not one TOML value (a number, true/false, [array], "
                                "\"string\") nor a bare word" +
                                (tomlSays.empty() ? std::string() : "; as TOML: " + tomlSays));
    }
    ctx.overrideOf[table.get(last)] = origin;
}

/// Applies KEY=VALUE to the tree; `how` ("--set", "set") begins the messages that quote it.
void applyOverride(toml::table& root, const std::string& spec, const char* how, LoadContext& ctx) {
    // messages quote the override, shortened: a long value need not be echoed whole
    const std::string origin =
        std::string(how) + " " + (spec.size() > 100 ? spec.substr(0, 100) + "..." : spec);
    const auto eq = spec.find('=');
    if (eq == std::string::npos || eq == 0) {
        throw ScenarioError(ctx.file, 0, 0, origin + ": expected KEY=VALUE, e.g. scene.dt=0.005");
    }
    const std::string key = spec.substr(0, eq);
    const std::string text = spec.substr(eq + 1);
    std::vector<std::string> path;
    std::stringstream ss(key);
    for (std::string part; std::getline(ss, part, '.');) {
        path.push_back(part);
    }
    if (path.size() < 2 ||
        std::any_of(path.begin(), path.end(), [](const std::string& p) { return p.empty(); })) {
        throw ScenarioError(ctx.file, 0, 0,
                            origin + ": KEY must be section.key (scene.dt) or entity.component.key "
                                     "(curtain.cloth.integrator)");
    }

    // where the value goes
    toml::table* table = nullptr;
    if (isSection(path[0])) {
        if (!root.contains(path[0])) {
            root.insert(path[0], toml::table{});
            ctx.overrideOf[root.get(path[0])] = origin;
        }
        table = root[path[0]].as_table();
        if (!table) {
            throw ScenarioError(ctx.file, 0, 0,
                                origin + ": [" + path[0] + "] is not a table in the scenario");
        }
    } else {
        table = findEntityTable(root, path[0]);
        if (!table) {
            throw ScenarioError(ctx.file, 0, 0,
                                origin + ": no section or entity named '" + path[0] +
                                    "' (sections: scene, budget, camera, render; or an entity's name)");
        }
    }
    for (std::size_t i = 1; i + 1 < path.size(); ++i) {
        if (!table->contains(path[i])) {
            // a table made by the override: problems found in it are the override's
            table->insert(path[i], toml::table{});
            ctx.overrideOf[table->get(path[i])] = origin;
        }
        toml::table* next = table->get_as<toml::table>(path[i]);
        if (!next) {
            throw ScenarioError(ctx.file, 0, 0, origin + ": '" + path[i] + "' is not a table");
        }
        table = next;
    }

    setOverrideValue(*table, path.back(), text, origin, ctx);
}

// ---- sections

/// [render]: the image, its samples, the key light and its shadows; and the memory its frames take.
void readRender(const toml::table* t, const LoadContext& ctx, SceneDef& scene) {
    if (t) {
        TableReader r(*t, "[render]", ctx);
        scene.renderWidth = static_cast<int>(r.integer("width", scene.renderWidth, 16, 8192));
        scene.renderHeight = static_cast<int>(r.integer("height", scene.renderHeight, 16, 8192));
        scene.background = r.vector<3>("background", scene.background, 0.0, 1.0);
        scene.renderSamples = static_cast<int>(r.integer("msaa", scene.renderSamples, 1, 16));
        if ((scene.renderSamples & (scene.renderSamples - 1)) != 0) {
            r.fail("msaa", "'msaa' in [render] is the samples per pixel: 1 (none), 2, 4, 8 or 16, not " +
                               std::to_string(scene.renderSamples));
        }
        scene.renderShadows = r.boolean("shadows", scene.renderShadows);
        scene.renderSkyGradient = r.boolean("sky_gradient", scene.renderSkyGradient);
        scene.renderHemisphere = r.boolean("hemisphere_ambient", scene.renderHemisphere);
        scene.renderGamma = r.boolean("gamma", scene.renderGamma);
        if (t->contains("light_direction")) {
            const auto d = r.vector<3>("light_direction", {0.0, -1.0, 0.0}, -1e6, 1e6);
            const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            if (!(n > 1e-9)) {
                r.fail("light_direction",
                       "'light_direction' in [render] is where the light shines: not zero");
            }
            scene.lightDirection = std::array<double, 3>{d[0] / n, d[1] / n, d[2] / n};
        }
        r.finish();
    }
    // the frame buffers (colour and depth: 8 bytes a sample; the resolved colour), the read-back frame and
    // the PNG's rows
    const std::uint64_t perPixel =
        24u + 8u * std::uint64_t(scene.renderSamples > 1 ? scene.renderSamples : 0);
    ctx.charge(t, std::uint64_t(scene.renderWidth) * std::uint64_t(scene.renderHeight) * perPixel,
               "[render] (" + std::to_string(scene.renderWidth) + " x " + std::to_string(scene.renderHeight) +
                   " frames)");
}

void readSections(toml::table& root, const LoadContext& ctx, SceneDef& scene) {
    const toml::node* sceneNode = root.get("scene");
    if (!sceneNode) {
        ctx.fail(nullptr, "the scenario needs a [scene] table with at least name = \"...\"");
    }
    if (!sceneNode->is_table()) {
        ctx.fail(sceneNode, "'scene' must be a table, not " + describeType(*sceneNode));
    }
    TableReader s(*sceneNode->as_table(), "[scene]", ctx);
    scene.name = s.requiredString("name");
    if (!validName(scene.name)) {
        s.fail("name",
               "'name' in [scene] must be 1-64 letters, digits, '_' or '-' (it names the output folder)");
    }
    scene.description = s.string("description", "");
    scene.dt = s.number("dt", 1.0 / 60.0, 1e-6, 1.0);
    scene.substeps = static_cast<int>(s.integer("substeps", 1, 1, 1000));
    scene.frames = s.integer("frames", 600, 0, 100'000'000);
    scene.gravity = s.vector<3>("gravity", scene.gravity, -1e4, 1e4);
    scene.seed =
        static_cast<std::uint64_t>(s.integer("seed", 1, 0, std::numeric_limits<std::int64_t>::max()));
    scene.solverIterations = static_cast<int>(s.integer("solver_iterations", 10, 1, 1000));
    scene.sleepLinear = s.number("sleep_linear", scene.sleepLinear, 0.0, 1e3);
    scene.sleepAngularDeg = s.number("sleep_angular_deg", scene.sleepAngularDeg, 0.0, 1e5);
    scene.sleepTime = s.number("sleep_time", scene.sleepTime, 1e-3, 1e6);
    scene.velocityIterations = static_cast<int>(s.integer("velocity_iterations", 8, 1, 1000));
    scene.positionIterations = static_cast<int>(s.integer("position_iterations", 3, 1, 1000));
    s.finish();

    auto section = [&](const char* key) -> const toml::table* {
        const toml::node* n = root.get(key);
        if (n && !n->is_table()) {
            ctx.fail(n, "'" + std::string(key) + "' must be a table, not " + describeType(*n));
        }
        return n ? n->as_table() : nullptr;
    };
    if (const toml::table* t = section("budget")) {
        TableReader b(*t, "[budget]", ctx);
        scene.physicsBudgetMs = b.number("physics_ms", scene.physicsBudgetMs, 1e-3, 1e6);
        scene.stress = b.boolean("stress", false);
        b.finish();
    }
    if (const toml::table* t = section("camera")) {
        TableReader c(*t, "[camera]", ctx);
        scene.cameraEye = c.vector<3>("eye", scene.cameraEye, -kHuge, kHuge);
        scene.cameraTarget = c.vector<3>("target", scene.cameraTarget, -kHuge, kHuge);
        scene.cameraFovDeg = c.number("fov_deg", scene.cameraFovDeg, 1.0, 179.0);
        if (scene.cameraEye == scene.cameraTarget) {
            c.fail("target", "'target' in [camera] must differ from 'eye'");
        }
        c.finish();
    }
    readRender(section("render"), ctx, scene);
}

// ---- entities

/// Values in a table, counted recursively (a measure of the work of loading it).
std::size_t countNodes(const toml::node& n) {
    std::size_t count = 1;
    if (const toml::table* t = n.as_table()) {
        for (auto&& [k, v] : *t) {
            count += countNodes(v);
        }
    } else if (const toml::array* a = n.as_array()) {
        for (const toml::node& v : *a) {
            count += countNodes(v);
        }
    }
    return count;
}

std::string_view repeatOrScatterKey(const toml::table& t) {
    return t.contains("scatter") ? "scatter" : t.contains("repeat") ? "repeat" : "name";
}

struct Placement {
    std::string name;
    Vec3 position;
};

/// The instances one [[entity]] stands for: itself, or its repeat / scatter copies.
std::vector<Placement> placements(TableReader& e, const std::string& name, Vec3 base, const SceneDef& scene,
                                  std::int64_t budget) {
    const toml::table* repeat = e.subtable("repeat");
    const toml::table* scatter = e.subtable("scatter");
    if (repeat && scatter) {
        e.fail("scatter", "entity '" + name + "' has both 'repeat' and 'scatter'; use one");
    }
    std::vector<Placement> out;
    if (repeat) {
        TableReader r(*repeat, "entity '" + name + "' repeat", e.context());
        const std::int64_t count = r.integer("count", 1, 1, budget);
        const auto offset = r.vector<3>("offset", {0.0, 0.0, 0.0}, -kHuge, kHuge);
        r.finish();
        for (std::int64_t i = 0; i < count; ++i) {
            const double k = static_cast<double>(i);
            out.push_back(
                {name + "_" + std::to_string(i), base + Vec3{offset[0] * k, offset[1] * k, offset[2] * k}});
        }
    } else if (scatter) {
        TableReader r(*scatter, "entity '" + name + "' scatter", e.context());
        const std::int64_t count = r.integer("count", 1, 1, budget);
        const auto lo = r.vector<3>("min", {-1.0, 0.0, -1.0}, -kHuge, kHuge);
        const auto hi = r.vector<3>("max", {1.0, 0.0, 1.0}, -kHuge, kHuge);
        r.finish();
        for (int a = 0; a < 3; ++a) {
            if (lo[std::size_t(a)] > hi[std::size_t(a)]) {
                r.fail("min", "'min' of entity '" + name + "' scatter is above its 'max'");
            }
        }
        // offsets relative to the entity's position, from a stream of their own
        Rng rng(streamSeed(scene.seed, "scatter:" + name));
        for (std::int64_t i = 0; i < count; ++i) {
            const Vec3 d{rng.uniform(lo[0], hi[0]), rng.uniform(lo[1], hi[1]), rng.uniform(lo[2], hi[2])};
            out.push_back({name + "_" + std::to_string(i), base + d});
        }
    } else {
        out.push_back({name, base});
    }
    return out;
}

/// An entity's component tables, each with its loader: every key that is not the entity's own bookkeeping
/// (name, transform, repeat, scatter). An unknown key fails with the nearest known one.
std::vector<std::pair<const ComponentLoader*, const toml::table*>>
componentTables(const toml::table& table, const std::string& where, const LoadContext& ctx,
                const Catalog& catalog, TableReader& e) {
    std::vector<std::pair<const ComponentLoader*, const toml::table*>> components;
    std::string body; // the entity's body component, once met
    for (auto&& [k, v] : table) {
        const std::string key(k.str());
        if (key == "name" || key == "transform" || key == "repeat" || key == "scatter") {
            continue;
        }
        const ComponentLoader* loader = catalog.findComponent(key);
        if (!loader) {
            std::vector<std::string> known = catalog.componentKeys();
            known.insert(known.end(), {"name", "transform", "repeat", "scatter"});
            const std::string near = nearestName(key, known);
            std::string keys;
            for (const std::string& s : catalog.componentKeys()) {
                keys += (keys.empty() ? "" : ", ") + s;
            }
            ctx.fail(&v, "unknown key '" + key + "' in " + where +
                             (near.empty() ? "; components in this build: " + keys
                                           : " (did you mean '" + near + "'?)"));
        }
        if (!v.is_table()) {
            ctx.fail(&v, where + ": '" + key + "' must be a table, written [entity." + key + "]");
        }
        e.has(key);
        components.emplace_back(loader, v.as_table());
        // an entity is one body: a second would be loaded and then lost (the dump and the hash take the
        // first), or a --set of a table the entity does not have would put one beside its own
        if (loader->body) {
            if (!body.empty()) {
                ctx.fail(
                    &v,
                    where + ": '" + body + "' and '" + key +
                        "' are two bodies; an entity is one body (give the other an [[entity]] of its own)");
            }
            body = key;
        }
    }
    return components;
}

/// A component table to link once every entity exists (ComponentLoader::link).
struct PendingLink {
    const ComponentLoader* loader;
    const toml::table* table;
    std::string where;
    Entity entity;
};

void readEntities(const toml::table& root, const LoadContext& ctx, const Catalog& catalog,
                  const SceneDef& scene, World& world, std::map<std::string, Entity>& byName,
                  std::vector<PendingLink>& links) {
    const toml::node* node = root.get("entity");
    if (!node) {
        return;
    }
    const toml::array* list = node->as_array();
    if (!list || !list->is_array_of_tables()) {
        ctx.fail(node, "'entity' must be an array of tables, written [[entity]]");
    }
    std::int64_t remaining = Limits::kMaxEntities;
    for (const toml::node& item : *list) {
        const toml::table& table = *item.as_table();
        TableReader e(table, "[[entity]]", ctx);
        const std::string name = e.requiredString("name");
        if (!validName(name)) {
            e.fail("name", "entity name '" + name + "' must be 1-64 letters, digits, '_' or '-'");
        }
        const std::string where = "entity '" + name + "'";
        Vec3 base;
        if (const toml::table* t = e.subtable("transform")) {
            TableReader tr(*t, where + " [transform]", ctx);
            const auto p = tr.vector<3>("position", {0.0, 0.0, 0.0}, -kHuge, kHuge);
            base = {p[0], p[1], p[2]};
            tr.finish();
        }
        const std::vector<Placement> instances = placements(e, name, base, scene, remaining);
        remaining -= static_cast<std::int64_t>(instances.size());
        if (remaining < 0) {
            e.fail("name", "the scene has more than " + std::to_string(Limits::kMaxEntities) + " entities");
        }

        const auto components = componentTables(table, where, ctx, catalog, e);
        e.finish();

        // every instance re-reads the component tables: bound the total work a small file can ask for
        std::size_t nodes = 0;
        for (const auto& [loader, sub] : components) {
            nodes += countNodes(*sub);
        }
        if (nodes * instances.size() > Limits::kMaxLoadedNodes) {
            e.fail(repeatOrScatterKey(e.table()),
                   where + " makes " + std::to_string(instances.size()) + " copies of " +
                       std::to_string(nodes) + " values; at most " + std::to_string(Limits::kMaxLoadedNodes) +
                       " values may be loaded");
        }

        for (const Placement& p : instances) {
            if (byName.count(p.name)) {
                e.fail("name", "entity name '" + p.name + "' is used twice");
            }
            const Entity entity = world.create();
            byName[p.name] = entity;
            world.emplace<Name>(entity, Name{p.name});
            world.emplace<Transform>(entity, Transform{p.position});
            for (const auto& [loader, sub] : components) {
                TableReader cr(*sub, where + " [" + loader->key + "]", ctx);
                loader->load(cr, world, entity, scene);
                cr.finish();
                if (loader->link) {
                    links.push_back({loader, sub, where + " [" + loader->key + "]", entity});
                }
            }
        }
    }
}

// ---- links and joints

/// Entities by name for a table's key, failing at the key with the nearest name.
EntityLookup lookupIn(const std::map<std::string, Entity>& byName) {
    return [&byName](TableReader& r, std::string_view key, bool required) {
        if (!required && !r.has(key)) {
            return kNullEntity;
        }
        const std::string name = r.requiredString(key);
        const auto found = byName.find(name);
        if (found == byName.end()) {
            std::vector<std::string> names;
            for (const auto& [n, e] : byName) {
                names.push_back(n);
            }
            const std::string near = nearestName(name, names);
            r.fail(key, "no entity named '" + name + "'" +
                            (near.empty() ? "" : " (did you mean '" + near + "'?)"));
        }
        return found->second;
    };
}

void linkEntities(const std::vector<PendingLink>& links, const LoadContext& ctx, World& world,
                  const std::map<std::string, Entity>& byName) {
    const EntityLookup lookup = lookupIn(byName);
    for (const PendingLink& l : links) {
        TableReader r(*l.table, l.where, ctx);
        l.loader->link(r, world, l.entity, lookup);
    }
}

void readJoints(const toml::table& root, const LoadContext& ctx, const Catalog& catalog,
                const SceneDef& scene, World& world, const std::map<std::string, Entity>& byName) {
    const toml::node* node = root.get("joint");
    if (!node) {
        return;
    }
    if (!catalog.jointLoader()) {
        ctx.fail(node, "[[joint]] connects rigid bodies, which this build does not have");
    }
    const toml::array* list = node->as_array();
    if (!list || !list->is_array_of_tables()) {
        ctx.fail(node, "'joint' must be an array of tables, written [[joint]]");
    }
    if (list->size() > Limits::kMaxArray) {
        ctx.fail(node, "too many joints (at most " + std::to_string(Limits::kMaxArray) + ")");
    }
    const EntityLookup lookup = lookupIn(byName);
    for (const toml::node& item : *list) {
        TableReader r(*item.as_table(), "[[joint]]", ctx);
        catalog.jointLoader()(r, world, scene, lookup);
        r.finish();
    }
}

// ---- events

std::optional<std::pair<std::string, std::string>> matchAction(const Catalog& catalog, const World& world,
                                                               EventDef& ev,
                                                               const std::vector<std::string>& present) {
    // the action must be one that some component of this entity takes; the first that does is the one
    const EventAction* match = nullptr;
    std::vector<std::string> actionNames;
    for (std::size_t i = 0; i < catalog.actions().size(); ++i) {
        const EventAction& a = catalog.actions()[i];
        if (std::find(actionNames.begin(), actionNames.end(), a.action) == actionNames.end()) {
            actionNames.push_back(a.action);
        }
        if (!match && a.action == ev.action && a.appliesTo(world, ev.target)) {
            match = &a;
            ev.actionIndex = i;
        }
    }
    if (!match) {
        const bool known = std::find(actionNames.begin(), actionNames.end(), ev.action) != actionNames.end();
        std::string names;
        for (const std::string& s : actionNames) {
            names += (names.empty() ? "" : ", ") + s;
        }
        if (known) {
            std::string takers;
            for (const EventAction& a : catalog.actions()) {
                if (a.action == ev.action) {
                    takers += (takers.empty() ? "" : " or ") + a.needs;
                }
            }
            return std::pair{std::string("action"), "action '" + ev.action + "' does not apply to entity '" +
                                                        ev.entity + "'; it applies to " + takers};
        }
        const std::string near = nearestName(ev.action, actionNames);
        return std::pair{std::string("action"), "unknown action '" + ev.action + "'" +
                                                    (near.empty() ? "; actions in this build: " + names
                                                                  : " (did you mean '" + near + "'?)")};
    }
    for (const std::string& key : present) {
        if (std::find(match->fields.begin(), match->fields.end(), key) == match->fields.end()) {
            std::string takes;
            for (const std::string& f : match->fields) {
                takes += (takes.empty() ? "" : ", ") + f;
            }
            return std::pair{key, "action '" + ev.action + "' does not use '" + key + "'" +
                                      (takes.empty() ? "" : "; it takes: " + takes)};
        }
    }
    if (auto problem = match->check(world, ev.target, ev)) {
        return std::pair{std::string("value"), "action '" + ev.action + "': " + *problem};
    }
    return std::nullopt;
}

std::optional<std::string> resolveNamedEvent(const Catalog& catalog, const World& world, EventDef& ev,
                                             const std::vector<std::string>& present) {
    ev.target = kNullEntity;
    std::vector<std::string> names;
    for (Entity e : world.entities()) {
        if (const Name* n = world.tryGet<Name>(e)) {
            if (n->value == ev.entity) {
                ev.target = e;
            }
            names.push_back(n->value);
        }
    }
    if (ev.target == kNullEntity) {
        const std::string near = nearestName(ev.entity, names);
        return "no entity named '" + ev.entity + "'" +
               (near.empty() ? "" : " (did you mean '" + near + "'?)");
    }
    if (auto problem = matchAction(catalog, world, ev, present)) {
        return problem->second;
    }
    return std::nullopt;
}

std::uint64_t firstStepReaching(double at, double dt) {
    const double s = at / dt;
    const double nearest = std::round(s);
    return static_cast<std::uint64_t>(std::abs(s - nearest) <= 1e-6 * std::max(1.0, s) ? nearest
                                                                                       : std::ceil(s));
}

/// A `set` event's own keys: `key` (what --set takes as KEY) and `value` (any TOML value), no entity.
void readSetEvent(TableReader& r, EventDef& ev) {
    ev.action = r.requiredString("action");
    // The key is the one --set takes (scene.gravity, curtain.cloth.stretch); with 'entity', the key within
    // that entity (entity = "curtain", key = "cloth.stretch").
    std::string key = r.requiredString("key");
    if (r.has("entity")) {
        const std::string entity = r.requiredString("entity");
        // (a key that is its component's alone after the name, entity = "cloth" with key = "cloth.stretch",
        // is the component's key: it is kept)
        if (key.rfind(entity + ".", 0) == 0 && key.find('.', entity.size() + 1) != std::string::npos) {
            r.fail("key", "key '" + key + "' names the entity that 'entity' already gives: within entity '" +
                              entity + "' the key is '" + key.substr(entity.size() + 1) +
                              "' (or leave out 'entity' and keep the whole key)");
        }
        key = entity + "." + key;
    }
    const toml::node* value = r.node("value");
    if (!value) {
        r.fail("key", "a 'set' event needs a 'value' (a number, true/false, [array] or \"string\")");
    }
    ev.set = key + "=" + oneLineToml(*value);
    r.finish();
}

std::vector<EventDef> readEvents(const toml::table& root, const LoadContext& ctx, const Catalog& catalog,
                                 const SceneDef& scene, const World& world,
                                 const std::map<std::string, Entity>& byName) {
    std::vector<EventDef> events;
    const toml::node* node = root.get("event");
    if (!node) {
        return events;
    }
    const toml::array* list = node->as_array();
    if (!list || !list->is_array_of_tables()) {
        ctx.fail(node, "'event' must be an array of tables, written [[event]]");
    }
    if (list->size() > Limits::kMaxArray) {
        ctx.fail(node, "too many events (at most " + std::to_string(Limits::kMaxArray) + ")");
    }
    for (const toml::node& item : *list) {
        TableReader r(*item.as_table(), "[[event]]", ctx);
        EventDef ev;
        const bool hasAt = r.has("at");
        const bool hasFrame = r.has("frame");
        if (hasAt == hasFrame) {
            r.fail(hasAt ? "frame" : "action", "an [[event]] needs exactly one of 'at' (seconds) or 'frame'");
        }
        if (hasAt) {
            const double at = r.number("at", 0.0, 0.0, 1e9);
            ev.step = firstStepReaching(at, scene.dt);
        } else {
            ev.step = static_cast<std::uint64_t>(r.integer("frame", 0, 0, 1'000'000'000)) *
                      static_cast<std::uint64_t>(scene.substeps);
        }
        ev.line = int(item.source().begin.line);
        ev.column = int(item.source().begin.column);
        if (r.has("action") && r.node("action")->value_or(std::string_view{}) == "set") {
            readSetEvent(r, ev);
            events.push_back(std::move(ev));
            continue;
        }
        ev.entity = r.requiredString("entity");
        const auto found = byName.find(ev.entity);
        if (found == byName.end()) {
            std::vector<std::string> names;
            for (const auto& [n, e] : byName) {
                names.push_back(n);
            }
            const std::string near = nearestName(ev.entity, names);
            r.fail("entity", "no entity named '" + ev.entity + "'" +
                                 (near.empty() ? "" : " (did you mean '" + near + "'?)"));
        }
        ev.action = r.requiredString("action");
        if (const toml::node* v = r.node("value")) {
            if (v->is_number()) {
                ev.value.push_back(r.number("value", 0.0, -kHuge, kHuge));
            } else {
                const toml::array* a = r.array("value", 4096);
                ev.value.resize(a->size());
                r.readNumbers(*v, "value", ev.value.data(), a->size(), -kHuge, kHuge);
            }
        }
        ev.position = r.vector<3>("position", ev.position, -kHuge, kHuge);
        ev.radius = r.number("radius", 0.0, 0.0, kHuge);
        ev.amount = r.number("amount", 0.0, -kHuge, kHuge);
        r.finish();

        std::vector<std::string> present;
        for (const char* key : {"value", "position", "radius", "amount"}) {
            if (r.table().contains(key)) {
                present.push_back(key);
            }
        }
        ev.target = found->second;
        if (auto problem = matchAction(catalog, world, ev, present)) {
            r.fail(problem->first, problem->second);
        }
        events.push_back(std::move(ev));
    }
    std::stable_sort(events.begin(), events.end(),
                     [](const EventDef& a, const EventDef& b) { return a.step < b.step; });
    return events;
}

} // namespace

toml::table parseToml(const std::string& path, const std::string& text) {
    try {
        return toml::parse(text, path);
    } catch (const toml::parse_error& err) {
        throw ScenarioError(path, static_cast<int>(err.source().begin.line),
                            static_cast<int>(err.source().begin.column),
                            "TOML syntax error: " + std::string(err.description()));
    }
}

std::string readScenarioFile(const std::string& path, const std::string& what) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) {
        throw ScenarioError(path, 0, 0,
                            "cannot open " + what + ": no such file" +
                                (what == "the scenario" ? " (or a demo name: see `tumble list`)" : ""));
    }
    if (!S_ISREG(st.st_mode)) {
        throw ScenarioError(path, 0, 0, what + " is not a regular file");
    }
    if (static_cast<std::uint64_t>(st.st_size) > Limits::kMaxFileBytes) {
        throw ScenarioError(path, 0, 0,
                            what + " is larger than " + std::to_string(Limits::kMaxFileBytes >> 20) + " MiB");
    }
    if (st.st_size == 0) {
        return ""; // nothing to read (and /proc's files, which say 0, may block a read forever)
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        throw ScenarioError(path, 0, 0, "cannot open " + what + " for reading");
    }
    // in blocks, to the end or one byte past the limit (the file may have grown since stat); a buffer of
    // the limit's size, cleared on every call, cost a millisecond a load, which a sweep of short runs paid
    // each time
    std::string text;
    text.reserve(static_cast<std::size_t>(st.st_size) + 1);
    std::vector<char> block(std::size_t(1) << 16);
    while (in && text.size() <= Limits::kMaxFileBytes) {
        const std::size_t want = std::min(block.size(), Limits::kMaxFileBytes + 1 - text.size());
        in.read(block.data(), static_cast<std::streamsize>(want));
        text.append(block.data(), static_cast<std::size_t>(in.gcount()));
    }
    if (text.size() > Limits::kMaxFileBytes) {
        throw ScenarioError(path, 0, 0,
                            what + " is larger than " + std::to_string(Limits::kMaxFileBytes >> 20) + " MiB");
    }
    return text;
}

namespace {

/// The loader: the overrides (--set), then `sets` (set events before the one being checked or applied), then
/// every table; the scenario's set events are checked (engine/retune.h) when `checkSets`.
Scenario load(const Catalog& catalog, const std::string& path, std::string text,
              const std::vector<std::string>& overrides, const std::vector<std::string>& sets, World& world,
              std::uint64_t memoryCap, bool checkSets) {
    Scenario sc;
    sc.path = path;
    sc.text = std::move(text);
    sc.overrides = overrides;
    LoadContext ctx;
    ctx.file = path;
    ctx.memoryCap = memoryCap;

    if (sc.text.size() > Limits::kMaxFileBytes) {
        throw ScenarioError(path, 0, 0,
                            "the scenario is larger than " + std::to_string(Limits::kMaxFileBytes >> 20) +
                                " MiB");
    }
    toml::table root = parseToml(path, sc.text);
    for (const std::string& o : overrides) {
        applyOverride(root, o, "--set", ctx);
    }
    for (const std::string& o : sets) {
        applyOverride(root, o, "set", ctx);
    }

    // top-level keys
    for (auto&& [k, v] : root) {
        const std::string_view key = k.str();
        if (isSection(key) || key == "entity" || key == "event" || key == "joint") {
            continue;
        }
        const std::string near =
            nearestName(key, {"scene", "budget", "camera", "render", "entity", "event", "joint"});
        ctx.fail(&v, "unknown top-level key '" + std::string(key) + "'" +
                         (near.empty() ? "; expected scene, budget, camera, render, entity, event or joint"
                                       : " (did you mean '" + near + "'?)"));
    }
    readSections(root, ctx, sc.scene);
    std::map<std::string, Entity> byName;
    std::vector<PendingLink> links;
    readEntities(root, ctx, catalog, sc.scene, world, byName, links);
    linkEntities(links, ctx, world, byName);
    readJoints(root, ctx, catalog, sc.scene, world, byName);
    if (!checkSets) {
        return sc; // a set event's scratch load (engine/retune.h): the scene alone, its events were read
    }
    sc.events = readEvents(root, ctx, catalog, sc.scene, world, byName);
    {
        // each set event, in the order they apply, against the scenario with the ones before it; each
        // loads the scene twice more beside the running one, to see what the set changes
        const auto setEvents = std::size_t(std::count_if(
            sc.events.begin(), sc.events.end(), [](const EventDef& ev) { return ev.action == "set"; }));
        if (setEvents > Limits::kMaxSetEvents) {
            throw ScenarioError(path, 0, 0,
                                std::to_string(setEvents) + " set events; at most " +
                                    std::to_string(Limits::kMaxSetEvents) +
                                    " (each loads the scene twice to see what it changes)");
        }
        if (setEvents > 0 && ctx.memoryCharged > memoryCap / 3) {
            throw ScenarioError(path, 0, 0,
                                "the scene needs about " + formatBytes(ctx.memoryCharged) +
                                    " and its set events load it twice more beside it: about " +
                                    formatBytes(3 * ctx.memoryCharged) + ", above the memory cap of " +
                                    formatBytes(memoryCap) + " (--memory-cap MiB raises it)");
        }
        std::vector<std::string> earlier;
        for (const EventDef& ev : sc.events) {
            if (ev.action != "set") {
                continue;
            }
            if (auto problem = checkSet(catalog, sc, earlier, ev.set, memoryCap)) {
                throw ScenarioError(path, ev.line, ev.column, *problem);
            }
            earlier.push_back(ev.set);
        }
    }
    return sc;
}

} // namespace

Scenario loadScenario(const Catalog& catalog, const std::string& path, std::string text,
                      const std::vector<std::string>& overrides, World& world, std::uint64_t memoryCap) {
    return load(catalog, path, std::move(text), overrides, {}, world, memoryCap, true);
}

Scenario loadScenarioWithSets(const Catalog& catalog, const std::string& path, std::string text,
                              const std::vector<std::string>& overrides, const std::vector<std::string>& sets,
                              World& world, std::uint64_t memoryCap) {
    return load(catalog, path, std::move(text), overrides, sets, world, memoryCap, false);
}

SceneDef peekScene(const std::string& path, const std::string& text) {
    LoadContext ctx;
    ctx.file = path;
    toml::table root = parseToml(path, text);
    SceneDef scene;
    const toml::table* s = root["scene"].as_table();
    if (!s) {
        ctx.fail(nullptr, "the scenario needs a [scene] table");
    }
    scene.name = s->get_as<std::string>("name") ? s->get_as<std::string>("name")->get() : "";
    scene.description =
        s->get_as<std::string>("description") ? s->get_as<std::string>("description")->get() : "";
    return scene;
}

std::optional<std::string> resolveEvent(const Catalog& catalog, const World& world, EventDef& ev,
                                        const std::vector<std::string>& present) {
    return resolveNamedEvent(catalog, world, ev, present);
}

std::uint64_t stepReaching(double at, double dt) {
    return firstStepReaching(at, dt);
}

} // namespace tumble
