#include "engine/catalog.h"

namespace tumble {

const ComponentLoader* Catalog::findComponent(std::string_view key) const {
    for (const ComponentLoader& c : m_components) {
        if (c.key == key) {
            return &c;
        }
    }
    return nullptr;
}

std::vector<std::string> Catalog::componentKeys() const {
    std::vector<std::string> out;
    for (const ComponentLoader& c : m_components) {
        out.push_back(c.key);
    }
    return out;
}

const Retune* Catalog::findRetune(std::string_view key) const {
    for (const Retune& r : m_retunes) {
        for (const std::string& k : r.keys) {
            if (k == key) {
                return &r;
            }
        }
    }
    return nullptr;
}

} // namespace tumble
