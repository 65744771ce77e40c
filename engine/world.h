#pragma once
// The ECS world. Tumble's own, because neither EnTT nor flecs is packaged for Debian 12 and nothing may be
// downloaded at build time; it is kept small on purpose.
//
// - Entities are {index, generation} handles (engine/entity.h); stale handles are detected on every access.
// - Each component type lives in its own sparse set: a dense array of values packed by type, a dense array
//   of owning entities beside it, and a sparse index -> dense position table. Systems iterate the dense
//   arrays, which are contiguous.
// - A view joins one to three component types: it walks the smallest set and probes the others. A const
//   type in the view's list hands out const references (read-only access, visible in the signature).
// - Resources are world-wide singletons keyed by type (the Bullet world, the random streams, ...).
// - While a system runs, the world holds what the system declared it reads and writes (engine/access.h) and
//   refuses views, gets and resources over anything else.
// - While a view iterates, the component sets must not change shape. Structural changes made inside a
//   phase go through commands(): each system has its own queue, and the schedule applies the queues in
//   the order of the table of systems when the phase ends (each in the order its changes were made), so
//   systems that ran side by side change the world as if they had run one after another. Changing a set
//   during iteration directly is an error.
// - Systems that do not conflict run side by side (engine/schedule.h). The world's tables of component
//   sets and resources have a fixed size (detail::kMaxTypes), so a set made on first use never moves
//   another; the running system is kept per thread. Making and destroying entities is not for systems
//   running side by side: it goes through commands().

#include "engine/access.h"
#include "engine/entity.h"

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

namespace tumble {

/// Thrown when a handle names an entity that was destroyed (or never existed) or lacks a component.
struct StaleEntityError : std::logic_error {
    using std::logic_error::logic_error;
};

/// Thrown when the world is changed structurally while a view is iterating.
struct WorldLockedError : std::logic_error {
    using std::logic_error::logic_error;
};

/// Type-erased face of a component set, so that destroying an entity can clear it from every set.
class PoolBase {
public:
    virtual ~PoolBase() = default;
    virtual bool contains(std::uint32_t index) const = 0;
    virtual void erase(std::uint32_t index) = 0;
    virtual std::size_t size() const = 0;
};

/// The sparse set of one component type.
template <class T>
class Pool final : public PoolBase {
public:
    static constexpr std::uint32_t kAbsent = 0xffffffffu;

    bool contains(std::uint32_t index) const override {
        return index < m_sparse.size() && m_sparse[index] != kAbsent;
    }
    std::size_t size() const override { return m_dense.size(); }

    /// Adds the entity's component, constructed from args, or replaces the one it has.
    template <class... Args>
    T& emplace(Entity e, Args&&... args) {
        if (e.index >= m_sparse.size()) {
            m_sparse.resize(std::size_t(e.index) + 1, kAbsent);
        }
        if (m_sparse[e.index] != kAbsent) {
            // replace the value in place: one component of a type per entity
            T& slot = m_values[m_sparse[e.index]];
            slot = T(std::forward<Args>(args)...);
            return slot;
        }
        m_sparse[e.index] = static_cast<std::uint32_t>(m_dense.size());
        m_dense.push_back(e);
        m_values.emplace_back(std::forward<Args>(args)...);
        return m_values.back();
    }

    /// Removes the entity's component, if any; the last value moves into its place (swap-remove).
    void erase(std::uint32_t index) override {
        if (!contains(index)) {
            return;
        }
        const std::uint32_t pos = m_sparse[index];
        const std::uint32_t last = static_cast<std::uint32_t>(m_dense.size() - 1);
        if (pos != last) {
            m_dense[pos] = m_dense[last];
            m_values[pos] = std::move(m_values[last]);
            m_sparse[m_dense[pos].index] = pos;
        }
        m_dense.pop_back();
        m_values.pop_back();
        m_sparse[index] = kAbsent;
    }

    /// The component of the entity in slot `index`; the caller has checked contains(index).
    T& at(std::uint32_t index) { return m_values[m_sparse[index]]; }
    const T& at(std::uint32_t index) const { return m_values[m_sparse[index]]; }

    /// Owning entities, packed; entities()[i] owns values()[i].
    const std::vector<Entity>& entities() const { return m_dense; }
    std::vector<T>& values() { return m_values; }
    const std::vector<T>& values() const { return m_values; }

private:
    std::vector<std::uint32_t> m_sparse; ///< entity index -> position in the dense arrays, or kAbsent
    std::vector<Entity> m_dense;         ///< owner of each packed value
    std::vector<T> m_values;             ///< the components, packed
};

class World;

/// Structural changes queued during a phase and applied in order when the phase ends.
class Commands {
public:
    explicit Commands(World& world) : m_world(&world) {}

    /// A new entity, alive at once (its handle can be used in further commands); components come later.
    Entity spawn();
    /// Queue adding (or replacing) a component.
    template <class T>
    void emplace(Entity e, T value);
    /// Queue the destruction of an entity (a no-op if it is already gone when applied).
    void destroy(Entity e);
    /// Queue any structural change.
    void push(std::function<void(World&)> change) { m_queue.push_back(std::move(change)); }

    /// Changes queued and not yet applied.
    std::size_t pending() const { return m_queue.size(); }
    /// Apply everything queued, in order; changes queued by those changes are applied too.
    void flush();

private:
    World* m_world;
    std::vector<std::function<void(World&)>> m_queue;
};

template <class... Ts>
class View;

/// Entities, their components in sparse sets, world-wide resources, and a queue of deferred changes.
class World {
public:
    World() : m_commands(*this) {}
    World(const World&) = delete;
    World& operator=(const World&) = delete;

    // ---- entities

    /// A new, empty entity. Allowed during iteration (it touches no component set).
    Entity create();
    /// Destroy an entity and every component it has; its handles become stale. Throws on a stale handle.
    void destroy(Entity e);
    /// True while the entity exists and the handle's generation matches.
    bool alive(Entity e) const {
        return e.index < m_generations.size() && m_alive[e.index] && m_generations[e.index] == e.generation;
    }
    /// Number of living entities.
    std::size_t size() const { return m_living; }
    /// Living entities in ascending slot order (a fixed order, used for dumps and hashes).
    std::vector<Entity> entities() const;

    // ---- components

    /// Adds (or replaces) a component; throws on a stale handle or while a view iterates.
    template <class T, class... Args>
    T& emplace(Entity e, Args&&... args) {
        requireAlive(e, "emplace");
        requireUnlocked("emplace");
        return pool<T>().emplace(e, std::forward<Args>(args)...);
    }
    /// Removes a component if present; throws on a stale handle or while a view iterates.
    template <class T>
    void remove(Entity e) {
        requireAlive(e, "remove");
        requireUnlocked("remove");
        if (auto* p = findPool<T>()) {
            p->erase(e.index);
        }
    }
    /// True if the entity is alive and has the component.
    template <class T>
    bool has(Entity e) const {
        checkAccess<T>(false);
        const auto* p = findPool<T>();
        return alive(e) && p && p->contains(e.index);
    }
    /// The component, or nullptr if the entity lacks it or is not alive.
    template <class T>
    T* tryGet(Entity e) {
        checkAccess<T>(false);
        auto* p = findPool<T>();
        return alive(e) && p && p->contains(e.index) ? &p->at(e.index) : nullptr;
    }
    template <class T>
    const T* tryGet(Entity e) const {
        checkAccess<T>(false);
        const auto* p = findPool<T>();
        return alive(e) && p && p->contains(e.index) ? &p->at(e.index) : nullptr;
    }
    /// The component; throws StaleEntityError if the handle is stale or the component absent.
    template <class T>
    T& get(Entity e) {
        T* c = tryGet<T>(e);
        if (!c) {
            failGet(e);
        }
        return *c;
    }
    template <class T>
    const T& get(Entity e) const {
        const T* c = tryGet<T>(e);
        if (!c) {
            failGet(e);
        }
        return *c;
    }

    /// The packed set of a component type (created empty on first use); unchecked (views check first).
    template <class T>
    Pool<T>& pool() {
        const auto id = detail::typeId<T>();
        PoolBase* p = m_pools[id].load(std::memory_order_acquire);
        if (!p) {
            p = makePool(id, [] { return std::unique_ptr<PoolBase>(new Pool<T>()); });
        }
        return static_cast<Pool<T>&>(*p);
    }
    /// The packed set of a component type, or nullptr if none was ever made.
    template <class T>
    const Pool<T>* findPool() const {
        checkAccess<T>(false);
        return static_cast<const Pool<T>*>(m_pools[detail::typeId<T>()].load(std::memory_order_acquire));
    }
    template <class T>
    Pool<T>* findPool() {
        checkAccess<T>(false);
        return static_cast<Pool<T>*>(m_pools[detail::typeId<T>()].load(std::memory_order_acquire));
    }

    /// Entities having every one of Ts; const types are read-only.
    template <class... Ts>
    View<Ts...> view();

    // ---- resources

    /// Sets (or replaces) the world's one resource of type T.
    template <class T, class... Args>
    T& setResource(Args&&... args) {
        checkAccess<T>(true);
        const auto id = detail::typeId<T>();
        auto holder = std::make_shared<T>(std::forward<Args>(args)...);
        T& ref = *holder;
        m_resources[id] = std::move(holder);
        return ref;
    }
    /// The resource of type T, or nullptr if it was never set.
    template <class T>
    T* tryResource() {
        checkAccess<T>(false);
        return static_cast<T*>(m_resources[detail::typeId<T>()].get());
    }
    /// The resource; throws std::logic_error if it was never set.
    template <class T>
    T& resource() {
        T* r = tryResource<T>();
        if (!r) {
            throw std::logic_error("world has no resource of the requested type");
        }
        return *r;
    }

    // ---- declared access

    /// Makes this thread run a system in this world: its name, declaration and command queue (all outlive
    /// the scope); see the header comment. The thread's previous running system comes back after.
    struct AccessScope {
        AccessScope(World& w, const std::string& system, const Access& access, Commands* queue = nullptr)
            : saved(runningSystem()) {
            runningSystem() = RunningSystem{&w, &access, &system, queue};
        }
        ~AccessScope() { runningSystem() = saved; }
        AccessScope(const AccessScope&) = delete;
        AccessScope& operator=(const AccessScope&) = delete;
        RunningSystem saved;
    };
    /// Throws AccessError if this thread runs a system in this world that did not declare T (written,
    /// when write is true).
    template <class T>
    void checkAccess(bool write) const {
        const RunningSystem& running = runningSystem();
        if (running.world == this && running.access && !running.access->allows(detail::typeId<T>(), write)) {
            failAccess(detail::typeName<T>(), write);
        }
    }

    // ---- deferred changes

    /// The queue for structural changes: the running system's own, else the world's (see the header
    /// comment).
    Commands& commands() {
        const RunningSystem& running = runningSystem();
        return running.world == this && running.commands ? *running.commands : m_commands;
    }

    /// Held by a view while it iterates; structural changes are refused while any is held.
    struct IterationLock {
        explicit IterationLock(World& w) : world(w) {
            world.m_iterating.fetch_add(1, std::memory_order_relaxed);
        }
        ~IterationLock() { world.m_iterating.fetch_sub(1, std::memory_order_relaxed); }
        IterationLock(const IterationLock&) = delete;
        IterationLock& operator=(const IterationLock&) = delete;
        World& world;
    };

private:
    void requireAlive(Entity e, const char* what) const;
    void requireUnlocked(const char* what) const;
    [[noreturn]] void failGet(Entity e) const;
    [[noreturn]] void failAccess(const std::string& type, bool write) const;
    PoolBase* makePool(std::uint32_t id, std::unique_ptr<PoolBase> (*make)());

    std::vector<std::uint32_t> m_generations; ///< current generation of each slot
    std::vector<std::uint8_t> m_alive;        ///< 1 while the slot holds a living entity
    std::vector<std::uint32_t> m_free;        ///< slots to reuse, most recently freed last
    std::size_t m_living = 0;
    std::atomic<int> m_iterating{0};                                  ///< views iterating right now
    std::array<std::atomic<PoolBase*>, detail::kMaxTypes> m_pools{};  ///< by detail::typeId
    std::vector<std::unique_ptr<PoolBase>> m_ownedPools;              ///< the same, owned, in order made
    std::mutex m_poolMutex;                                           ///< for making a set on first use
    std::array<std::shared_ptr<void>, detail::kMaxTypes> m_resources; ///< by detail::typeId
    Commands m_commands;
};

template <class T>
void Commands::emplace(Entity e, T value) {
    // held through a shared_ptr so that move-only components can be queued (std::function must copy);
    // an entity destroyed before the flush simply does not get the component
    auto held = std::make_shared<T>(std::move(value));
    m_queue.emplace_back([e, held](World& w) {
        if (w.alive(e)) {
            w.emplace<T>(e, std::move(*held));
        }
    });
}

/// Iterates the entities that have all of Ts, calling fn(Entity, Ts&...) on each.
template <class... Ts>
class View {
    static_assert(sizeof...(Ts) >= 1 && sizeof...(Ts) <= 3, "a view joins one to three component types");

public:
    explicit View(World& world)
        : m_world(world), m_pools((world.checkAccess<std::remove_const_t<Ts>>(!std::is_const_v<Ts>),
                                   world.pool<std::remove_const_t<Ts>>())...) {}

    template <class Fn>
    void each(Fn&& fn) {
        World::IterationLock lock(m_world);
        const PoolBase* driver = smallest();
        // the driver's entity list is stable during iteration: structural changes are locked out
        const std::vector<Entity>& owners = ownersOf(driver);
        for (std::size_t i = 0; i < owners.size(); ++i) {
            const Entity e = owners[i];
            if (containsAll(e.index)) {
                fn(e, static_cast<Ts&>(std::get<Pool<std::remove_const_t<Ts>>&>(m_pools).at(e.index))...);
            }
        }
    }

    /// Number of entities visited by each() (walks the join).
    std::size_t count() {
        std::size_t n = 0;
        each([&n](Entity, Ts&...) { ++n; });
        return n;
    }

private:
    bool containsAll(std::uint32_t index) const {
        return (std::get<Pool<std::remove_const_t<Ts>>&>(m_pools).contains(index) && ...);
    }
    const PoolBase* smallest() const {
        const PoolBase* best = nullptr;
        auto consider = [&best](const PoolBase& p) {
            if (!best || p.size() < best->size()) {
                best = &p;
            }
        };
        (consider(std::get<Pool<std::remove_const_t<Ts>>&>(m_pools)), ...);
        return best;
    }
    const std::vector<Entity>& ownersOf(const PoolBase* p) const {
        const std::vector<Entity>* out = nullptr;
        auto match = [&](const auto& pool) {
            if (&pool == p) {
                out = &pool.entities();
            }
        };
        (match(std::get<Pool<std::remove_const_t<Ts>>&>(m_pools)), ...);
        return *out;
    }

    World& m_world;
    std::tuple<Pool<std::remove_const_t<Ts>>&...> m_pools;
};

template <class... Ts>
View<Ts...> World::view() {
    return View<Ts...>(*this);
}

} // namespace tumble
