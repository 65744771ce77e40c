#pragma once
// Every system Tumble ships, registered into a catalog. The fixed phase runs in DESIGN.md's order:
// force fields -> emitters -> particles -> springs/cloth -> collisions -> rigid bridges -> water.

#include "engine/catalog.h"

namespace tumble {

/// Registers the built-in components, state codecs, event actions and systems, in run order.
void registerBuiltinSystems(Catalog& catalog);

} // namespace tumble
