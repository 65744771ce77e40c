#include "systems/builtin.h"

#include "systems/spring_system.h"

namespace tumble {

void registerBuiltinSystems(Catalog& catalog) {
    // fixed phase, in order
    registerSpringSystem(catalog);
}

} // namespace tumble
