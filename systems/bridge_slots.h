#pragma once
// The bookkeeping both rigid bridges share (systems/bullet_bridge.cpp, systems/box2d_bridge.cpp): the
// engine's bodies and joints live in slots whose index is the id a component keeps (RigidBody::bodyId,
// Joint::constraintId). A removed slot is emptied and its id reused by the next one taken, the most recently
// freed first, so ids stay small and their order depends only on the scene's history.

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace tumble {

/// Slots of one kind (bodies or joints) of a bridge; Slot{} is an empty slot.
template <class Slot>
class SlotTable {
public:
    /// Puts the slot into the most recently freed place, else at the end; returns its id.
    std::int32_t take(Slot slot) {
        if (!m_free.empty()) {
            const std::int32_t id = m_free.back();
            m_free.pop_back();
            m_slots[std::size_t(id)] = std::move(slot);
            return id;
        }
        m_slots.push_back(std::move(slot));
        return std::int32_t(m_slots.size() - 1);
    }
    /// Empties a slot (the engine's object already removed) and frees its id.
    void release(std::int32_t id) {
        m_slots[std::size_t(id)] = Slot{};
        m_free.push_back(id);
    }
    Slot& operator[](std::size_t id) { return m_slots[id]; }
    const Slot& operator[](std::size_t id) const { return m_slots[id]; }
    std::size_t size() const { return m_slots.size(); }
    auto begin() { return m_slots.begin(); }
    auto end() { return m_slots.end(); }

private:
    std::vector<Slot> m_slots;
    std::vector<std::int32_t> m_free; ///< empty slots, the most recently freed last
};

} // namespace tumble
