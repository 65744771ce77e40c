#pragma once
// An entity is a handle: a slot index and the generation of that slot. Destroying an entity bumps its
// slot's generation, so every handle still held to it becomes stale and is detected as such; a slot whose
// generation would wrap around is retired rather than reused, so a stale handle can never come back alive.

#include <cstdint>
#include <functional>

namespace tumble {

/// Handle to an entity of a World: slot index plus the slot's generation when the entity was created.
struct Entity {
    std::uint32_t index = kInvalidIndex; ///< slot in the world's entity table
    std::uint32_t generation = 0;        ///< must match the slot's current generation to be alive

    static constexpr std::uint32_t kInvalidIndex = 0xffffffffu;

    /// True unless this is the null handle (it may still be stale: ask World::alive).
    constexpr bool valid() const { return index != kInvalidIndex; }
    friend constexpr bool operator==(Entity, Entity) = default;
};

/// The null handle: never alive in any world.
inline constexpr Entity kNullEntity{};

} // namespace tumble

template <>
struct std::hash<tumble::Entity> {
    std::size_t operator()(tumble::Entity e) const noexcept {
        return std::hash<std::uint64_t>{}((std::uint64_t(e.generation) << 32) | e.index);
    }
};
