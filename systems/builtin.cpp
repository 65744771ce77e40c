#include "systems/builtin.h"

#include "systems/cloth_collision.h"
#include "systems/collision_system.h"
#include "systems/force_field_system.h"
#include "systems/grab_system.h"
#include "systems/particle_system.h"
#include "systems/render_system.h"
#include "systems/rigid_system.h"
#include "systems/spring_system.h"
#include "systems/water_system.h"

namespace tumble {

void registerBuiltinSystems(Catalog& catalog) {
    // the fixed phase runs in this order; the renderer's first, to keep the positions before the step
    registerRenderSystem(catalog);
    registerForceFieldSystem(catalog);
    registerGrabSystem(catalog);
    registerParticleSystem(catalog);
    registerSpringSystem(catalog);
    registerCollisionSystem(catalog);
    registerClothCollisionSystem(catalog);
    registerRigidSystem(catalog);
    registerWaterSystem(catalog);
}

} // namespace tumble
