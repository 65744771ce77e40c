#pragma once
// What a system reads and writes, declared as data (as Bevy's system parameters are) so that the schedule
// can check it and, later, run systems side by side that do not conflict. A declaration lists component
// and resource types:
//
//     accessOf<Reads<SceneDef, ForceField>, Writes<ParticleEmitter>>()
//
// While a system runs, the world holds its declaration and refuses (AccessError) any view, get or
// resource over a type the system did not declare: a view's non-const type must be declared written, a
// const one read or written; get, tryGet and the resources need either (they cannot tell a read from a
// write). The check is a bit test per call, so it stays on in every build. Structural changes go through
// the world's command queue, applied when the phase ends, and are not part of a declaration.
//
// A system that may touch anything (the engine's event input, which applies whatever actions the
// catalog registered) declares Access::everything(): nothing runs beside it.

#include <cstdint>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace tumble {

namespace detail {
/// Type ids index fixed tables of the world (so that systems running side by side never see one grow).
constexpr std::uint32_t kMaxTypes = 1024;
std::uint32_t nextTypeId();
/// A small dense id per C++ type, used to index the world's tables.
template <class T>
std::uint32_t typeId() {
    // `const T` would get an id, and so a table, of its own; const belongs in view type lists only
    static_assert(!std::is_const_v<T> && !std::is_volatile_v<T>, "name the component type without const");
    static const std::uint32_t id = nextTypeId();
    return id;
}
/// The name of T from a compiler's signature of typeName<T> ("... [with T = tumble::Water; ...]"), without
/// the project's namespace. From the signature, not typeid, so that a system may declare a type it only
/// forward-declares (its private resources).
std::string nameFromSignature(const char* signature);
template <class T>
std::string typeName() {
    return nameFromSignature(__PRETTY_FUNCTION__);
}
} // namespace detail

/// Thrown when a running system touches a type its declaration does not list.
struct AccessError : std::logic_error {
    using std::logic_error::logic_error;
};

/// A component or resource type in a declaration.
struct TypeRef {
    std::uint32_t id = 0; ///< the world's type id
    std::string name;     ///< for messages and the architecture table
};

template <class... Ts>
struct Reads {};
template <class... Ts>
struct Writes {};

/// The types a system reads and writes; see the header comment.
struct Access {
    std::vector<TypeRef> reads;  ///< read only
    std::vector<TypeRef> writes; ///< read and written
    bool all = false;            ///< may touch anything (exclusive)

    /// A declaration that allows everything.
    static Access everything() {
        Access a;
        a.all = true;
        return a;
    }
    /// True if the declaration lets the system read (or, with write, change) the type.
    bool allows(std::uint32_t id, bool write) const {
        if (all) {
            return true;
        }
        if (id < m_allowed.size()) {
            return write ? m_allowed[id] == 2 : m_allowed[id] != 0;
        }
        return false;
    }
    /// True if the two systems could not run side by side: one writes a type the other reads or writes.
    bool conflictsWith(const Access& other) const;
    /// Builds the lookup table that allows() reads; called once the lists are complete.
    void index();

private:
    std::vector<std::uint8_t> m_allowed; ///< by type id: 0 undeclared, 1 read, 2 written
};

namespace detail {
template <class... Ts>
void appendRefs(std::vector<TypeRef>& out) {
    (out.push_back(TypeRef{typeId<Ts>(), typeName<Ts>()}), ...);
}
template <class R, class W>
struct AccessBuilder;
template <class... R, class... W>
struct AccessBuilder<Reads<R...>, Writes<W...>> {
    static Access build() {
        Access a;
        appendRefs<R...>(a.reads);
        appendRefs<W...>(a.writes);
        a.index();
        return a;
    }
};
} // namespace detail

class Commands;

/// The system a thread is running right now, for the world's access check and command queue: set by the
/// schedule around each system, and handed by the worker pool to every worker that runs part of the
/// system's work (engine/parallel.h). Empty while no system runs.
struct RunningSystem {
    const void* world = nullptr;       ///< the world the system runs in
    const Access* access = nullptr;    ///< its declaration
    const std::string* name = nullptr; ///< its name
    Commands* commands = nullptr;      ///< its queue of structural changes (applied in table order)
};
inline thread_local RunningSystem t_runningSystem;
/// This thread's running system.
inline RunningSystem& runningSystem() {
    return t_runningSystem;
}

/// A declaration from type lists: accessOf<Reads<A, B>, Writes<C>>().
template <class R, class W = Writes<>>
Access accessOf() {
    return detail::AccessBuilder<R, W>::build();
}

} // namespace tumble
