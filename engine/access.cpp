#include "engine/access.h"

#include <algorithm>
#include <atomic>

namespace tumble {

namespace detail {

std::uint32_t nextTypeId() {
    static std::atomic<std::uint32_t> counter{0};
    const std::uint32_t id = counter.fetch_add(1);
    if (id >= kMaxTypes) {
        throw std::logic_error("more than " + std::to_string(kMaxTypes) +
                               " component and resource types; raise detail::kMaxTypes in engine/access.h");
    }
    return id;
}

std::string nameFromSignature(const char* signature) {
    std::string name = signature;
    const std::size_t from = name.find("T = ");
    if (from == std::string::npos) {
        return name;
    }
    name = name.substr(from + 4, name.find_first_of(";]", from) - from - 4);
    const std::string ns = "tumble::";
    if (name.rfind(ns, 0) == 0) {
        name.erase(0, ns.size());
    }
    return name;
}

} // namespace detail

void Access::index() {
    m_allowed.clear();
    auto mark = [this](const TypeRef& t, std::uint8_t level) {
        if (t.id >= m_allowed.size()) {
            m_allowed.resize(std::size_t(t.id) + 1, 0);
        }
        m_allowed[t.id] = std::max(m_allowed[t.id], level);
    };
    for (const TypeRef& t : reads) {
        mark(t, 1);
    }
    for (const TypeRef& t : writes) {
        mark(t, 2);
    }
}

bool Access::conflictsWith(const Access& other) const {
    if (all || other.all) {
        return true;
    }
    for (const TypeRef& t : writes) {
        if (other.allows(t.id, false)) {
            return true;
        }
    }
    for (const TypeRef& t : other.writes) {
        if (allows(t.id, false)) {
            return true;
        }
    }
    return false;
}

} // namespace tumble
