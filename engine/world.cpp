#include "engine/world.h"

#include <limits>

namespace tumble {

Entity Commands::spawn() {
    return m_world->create();
}

void Commands::destroy(Entity e) {
    m_queue.emplace_back([e](World& w) {
        if (w.alive(e)) {
            w.destroy(e);
        }
    });
}

void Commands::flush() {
    // changes may queue further changes: apply batch after batch, each in order. Taking the batch out of
    // the queue first leaves the queue consistent even if a change throws.
    while (!m_queue.empty()) {
        std::vector<std::function<void(World&)>> batch;
        batch.swap(m_queue);
        for (auto& change : batch) {
            change(*m_world);
        }
    }
}

Entity World::create() {
    Entity e;
    if (!m_free.empty()) {
        e.index = m_free.back();
        m_free.pop_back();
        e.generation = m_generations[e.index];
    } else {
        if (m_generations.size() >= Entity::kInvalidIndex) {
            throw std::length_error("world: out of entity slots");
        }
        e.index = static_cast<std::uint32_t>(m_generations.size());
        e.generation = 0;
        m_generations.push_back(0);
        m_alive.push_back(0);
    }
    m_alive[e.index] = 1;
    ++m_living;
    return e;
}

void World::destroy(Entity e) {
    requireAlive(e, "destroy");
    requireUnlocked("destroy");
    for (auto& p : m_ownedPools) {
        p->erase(e.index);
    }
    m_alive[e.index] = 0;
    --m_living;
    // a slot whose generation would wrap is retired for good, so an old handle can never match again
    if (m_generations[e.index] == std::numeric_limits<std::uint32_t>::max()) {
        return;
    }
    ++m_generations[e.index];
    m_free.push_back(e.index);
}

std::vector<Entity> World::entities() const {
    std::vector<Entity> out;
    out.reserve(m_living);
    for (std::uint32_t i = 0; i < m_generations.size(); ++i) {
        if (m_alive[i]) {
            out.push_back(Entity{i, m_generations[i]});
        }
    }
    return out;
}

void World::requireAlive(Entity e, const char* what) const {
    if (!alive(e)) {
        throw StaleEntityError(std::string("world: ") + what + " on a stale or null entity handle (index " +
                               std::to_string(e.index) + ", generation " + std::to_string(e.generation) +
                               ")");
    }
}

void World::requireUnlocked(const char* what) const {
    if (m_iterating.load(std::memory_order_relaxed) > 0) {
        throw WorldLockedError(std::string("world: ") + what +
                               " while a view is iterating; queue it with world.commands()");
    }
}

void World::failGet(Entity e) const {
    if (!alive(e)) {
        requireAlive(e, "get");
    }
    throw StaleEntityError("world: entity " + std::to_string(e.index) + " has no component of that type");
}

PoolBase* World::makePool(std::uint32_t id, std::unique_ptr<PoolBase> (*make)()) {
    // two systems reading a type side by side may both find its set missing: one makes it
    std::lock_guard lock(m_poolMutex);
    if (PoolBase* made = m_pools[id].load(std::memory_order_acquire)) {
        return made;
    }
    m_ownedPools.push_back(make());
    m_pools[id].store(m_ownedPools.back().get(), std::memory_order_release);
    return m_ownedPools.back().get();
}

void World::failAccess(const std::string& type, bool write) const {
    throw AccessError("system '" + *runningSystem().name + "' " + (write ? "writes " : "reads ") + type +
                      " without declaring it; add it to the system's " + (write ? "Writes" : "Reads") +
                      " in systems/builtin.cpp");
}

} // namespace tumble
