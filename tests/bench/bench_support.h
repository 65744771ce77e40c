#pragma once
// What the benchmark files share: the catalog of built-in systems, made once.

#include "engine/catalog.h"
#include "systems/builtin.h"

namespace tumble::bench {

/// The built-in systems, as the `tumble` program registers them.
inline const Catalog& builtinCatalog() {
    static const Catalog catalog = [] {
        Catalog c;
        registerBuiltinSystems(c);
        return c;
    }();
    return catalog;
}

} // namespace tumble::bench
