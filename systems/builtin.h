#pragma once
// Every system Tumble ships, registered into a catalog. The fixed phase runs in this order
// (docs/architecture.md): force fields -> emitters -> particles -> springs/cloth -> collisions -> rigid
// bridges -> water.

#include "engine/catalog.h"

#include <vector>

namespace tumble {

/// Every built-in system in run order, with what it reads and writes: the one table of systems.
const std::vector<SystemEntry>& builtinSystems();

/// Registers the built-in components, state codecs and event actions, then builtinSystems() in order.
void registerBuiltinSystems(Catalog& catalog);

/// A catalog of the built-in systems, made once (the library and the tests share it).
const Catalog& builtinCatalog();

} // namespace tumble
