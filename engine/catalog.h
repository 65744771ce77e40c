#pragma once
// The catalog is how systems plug into the engine without the engine knowing them by name: the systems
// library registers its component loaders (scenario keys), state codecs (dump and hash), event actions and
// systems here, and the engine drives them through these entries alone.

#include "engine/hash.h"
#include "engine/json.h"
#include "engine/phase.h"
#include "engine/scene.h"
#include "engine/schedule.h"
#include "engine/table_reader.h"
#include "engine/world.h"

#include <array>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tumble {

/// Resolves an entity named by a key of a table (a joint's `a`, `b`): the entity, the null entity when the
/// key is absent and not required, or a failure that names the key, the table and the nearest name.
using EntityLookup = std::function<Entity(TableReader& reader, std::string_view key, bool required)>;

/// Reads `[entity.KEY]` and puts the resulting components on the entity.
struct ComponentLoader {
    std::string key; ///< the scenario key, e.g. "springs"
    std::function<void(TableReader& reader, World& world, Entity entity, const SceneDef& scene)> load;
    /// If set, called once every entity exists (before the joints), with the same table and a lookup of
    /// entities by name: for a component that names another entity (an air source's air). `load` must
    /// have read the key too, or the table's check of unknown keys refuses it.
    std::function<void(TableReader& reader, World& world, Entity entity, const EntityLookup& lookup)> link =
        {};
    /// A body (springs, a rigid body, water, ...): an entity holds one at most, and the loader refuses a
    /// second (the dump and the hash take one component per entity; an emitter may ride on a body).
    bool body = false;
};

/// How one component type appears in dumps and in the state hash.
struct StateCodec {
    std::string kind; ///< the dump's "kind" field
    std::function<bool(const World&, Entity)> has;
    /// Writes the entity's fields (after "kind") into an open JSON object.
    std::function<void(const World&, Entity, JsonWriter&)> dump;
    /// Feeds every simulated byte of the component to the hasher.
    std::function<void(const World&, Entity, Hasher&)> hash;
    /// Optional: the rows the dump writes under "x" or "v" (`field`), the same numbers, without writing the
    /// dump (for the embedding API's x() and v() on large entities). False when it has no such field.
    std::function<bool(const World&, Entity, std::string_view field,
                       std::vector<std::array<double, 3>>& rows)>
        rows = {};
};

/// An event action on entities that have some component.
struct EventAction {
    std::string action; ///< e.g. "impulse"
    std::string needs;  ///< what the entity must be, for messages, e.g. "a spring network"
    std::vector<std::string>
        fields; ///< event keys it reads (of value, position, radius, amount); others are errors
    std::function<bool(const World&, Entity)> appliesTo; ///< true if the entity takes this action
    /// Load-time check of the event's fields; returns a message when they do not fit.
    std::function<std::optional<std::string>(const World&, Entity, const EventDef&)> check;
    std::function<void(World&, Entity, const EventDef&)> apply; ///< run at the start of the event's step
};

/// How a `set` event (engine/retune.h) reaches one kind of component of a live entity. `before` and `after`
/// are the scenario's worlds loaded without and with the change; an entity in them has the live one's name.
struct Retune {
    std::vector<std::string> keys; ///< the component keys (scenario tables) whose settings it takes
    std::function<bool(const World&, Entity)> has;
    /// A message when what differs between before and after cannot change during a run.
    std::function<std::optional<std::string>(const World& before, Entity, const World& after, Entity)> check;
    /// Writes into the live component what differs between before and after (and nothing else).
    std::function<void(World& live, Entity, const World& before, Entity, const World& after, Entity)> patch;
};

/// Reads one [[joint]] table after every entity exists, and makes what it describes.
using JointLoader =
    std::function<void(TableReader& reader, World& world, const SceneDef& scene, const EntityLookup& lookup)>;

/// A system: its name (which labels the profile and trace), the phase it runs in, its function and what
/// it reads and writes. Systems of a phase run in the order they were added (systems/builtin.cpp's table).
struct SystemEntry {
    std::string name;
    Phase phase;
    SystemFn fn;
    Access access;
};

/// Everything the systems library registers; see the header comment.
class Catalog {
public:
    void addComponent(ComponentLoader loader) { m_components.push_back(std::move(loader)); }
    void addState(StateCodec codec) { m_states.push_back(std::move(codec)); }
    void addEventAction(EventAction action) { m_actions.push_back(std::move(action)); }
    void setJointLoader(JointLoader loader) { m_jointLoader = std::move(loader); }
    void addSystem(SystemEntry system) { m_systems.push_back(std::move(system)); }
    void addRetune(Retune retune) { m_retunes.push_back(std::move(retune)); }

    /// Rows of a component's "x" or "v", as StateCodec::rows gives them.
    using Rows = std::vector<std::array<double, 3>>;
    /// A state codec for component type T from a dump and a hash function of the component, and
    /// optionally its x and v rows.
    template <class T>
    void addState(std::string kind, std::function<void(const T&, JsonWriter&)> dump,
                  std::function<void(const T&, Hasher&)> hash,
                  std::function<bool(const T&, std::string_view, Rows&)> rows = {}) {
        StateCodec codec{std::move(kind), [](const World& w, Entity e) { return w.has<T>(e); },
                         [dump](const World& w, Entity e, JsonWriter& out) { dump(w.get<T>(e), out); },
                         [hash](const World& w, Entity e, Hasher& h) { hash(w.get<T>(e), h); }};
        if (rows) {
            codec.rows = [rows](const World& w, Entity e, std::string_view field, Rows& out) {
                return rows(w.get<T>(e), field, out);
            };
        }
        addState(std::move(codec));
    }

    const ComponentLoader* findComponent(std::string_view key) const;
    std::vector<std::string> componentKeys() const;
    const std::vector<StateCodec>& states() const { return m_states; }
    const std::vector<EventAction>& actions() const { return m_actions; }
    const std::vector<SystemEntry>& systems() const { return m_systems; }
    const JointLoader& jointLoader() const { return m_jointLoader; }
    const std::vector<Retune>& retunes() const { return m_retunes; }
    /// The retune of a component key ("cloth"), or null when none takes it.
    const Retune* findRetune(std::string_view key) const;

private:
    std::vector<ComponentLoader> m_components;
    std::vector<StateCodec> m_states;
    std::vector<EventAction> m_actions;
    std::vector<SystemEntry> m_systems;
    std::vector<Retune> m_retunes;
    JointLoader m_jointLoader;
};

} // namespace tumble
