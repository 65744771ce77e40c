#include "systems/builtin.h"

#include "components/air.h"
#include "components/force_field.h"
#include "components/grab.h"
#include "components/joint.h"
#include "components/particles.h"
#include "components/render_history.h"
#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "components/spring_network.h"
#include "components/water.h"
#include "engine/name.h"
#include "engine/render_output.h"
#include "engine/run_report.h"
#include "engine/transform.h"
#include "systems/air_system.h"
#include "systems/box2d_bridge.h"
#include "systems/bullet_bridge.h"
#include "systems/cloth_collision.h"
#include "systems/collision_system.h"
#include "systems/force_field_system.h"
#include "systems/grab_system.h"
#include "systems/particle_system.h"
#include "systems/render_system.h"
#include "systems/rigid_system.h"
#include "systems/spring_integrators.h"
#include "systems/spring_system.h"
#include "systems/water_system.h"

namespace tumble {

const std::vector<SystemEntry>& builtinSystems() {
    // Run order. The fixed phase follows the flow of one step: the renderer's history first (the poses the
    // step starts from), then what makes forces (fields, the mouse), what moves (particles, springs), what
    // pushes things apart (collisions with bodies, then the cloth's own contact, which must see the masses
    // where the springs and bodies left them), the rigid bridges (which apply the pushes left on bodies in
    // the same step) and the water (which reads where the bodies went). Reads and writes are checked while
    // each system runs (engine/access.h); a resource private to a system is among its writes.
    static const std::vector<SystemEntry> table = {
        {"render_history", Phase::Fixed, rememberPositions,
         accessOf<Reads<RenderOutput, SpringNetwork, RigidBody, RigidBody2D, Transform>,
                  Writes<RenderHistory, PoseHistory>>()},
        {"force_fields", Phase::Fixed, updateForceFields, accessOf<Reads<Transform>, Writes<ForceField>>()},
        {"mouse_spring", Phase::Fixed, pullGrabs,
         accessOf<Reads<Grab>, Writes<SpringNetwork, RigidBody, RigidBody2D>>()},
        {"emitters", Phase::Fixed, emitParticles, accessOf<Reads<Transform>, Writes<ParticleEmitter>>()},
        {"particles", Phase::Fixed, updateParticles,
         accessOf<Reads<SceneDef, ForceField, Air>, Writes<ParticleEmitter>>()},
        {"springs", Phase::Fixed, integrateSprings,
         accessOf<Reads<SceneDef, ForceField, Air, Name, Transform>,
                  Writes<SpringNetwork, SpringWorkspace, RigidBody, RigidBody2D, RunReport>>()},
        {"collisions", Phase::Fixed, collideWithBodies,
         accessOf<Reads<Transform>, Writes<SpringNetwork, ParticleEmitter, RigidBody, RigidBody2D>>()},
        {"cloth_collision", Phase::Fixed, collideCloth,
         accessOf<Reads<Name, RigidBody, RunChecks>,
                  Writes<SpringNetwork, ClothCollision, ClothScratch, ClothContactStats, RunReport>>()},
        {"rigid_in", Phase::Fixed, syncRigidIn,
         accessOf<Reads<SceneDef>, Writes<RigidBody, RigidBody2D, Joint, BulletWorld, Box2DWorld>>()},
        {"bullet", Phase::Fixed, bulletStep, accessOf<Reads<>, Writes<BulletWorld>>()},
        {"box2d", Phase::Fixed, box2dStep, accessOf<Reads<>, Writes<Box2DWorld>>()},
        {"rigid_out", Phase::Fixed, syncRigidOut,
         accessOf<Reads<Name>,
                  Writes<RigidBody, RigidBody2D, Transform, BulletWorld, Box2DWorld, RunReport>>()},
        {"collisions_2d", Phase::Fixed, settleOutside2DBodies,
         accessOf<Reads<RigidBody2D, Transform>, Writes<SpringNetwork, ParticleEmitter>>()},
        {"water", Phase::Fixed, stepWater,
         accessOf<Reads<SceneDef, Name, Transform>,
                  Writes<Water, RigidBody, RigidBody2D, SpringNetwork, ParticleEmitter, RunReport>>()},
        {"air", Phase::Fixed, advanceAir,
         accessOf<Reads<SceneDef, Transform, AirSource, RigidBody, Name>, Writes<Air, RunReport>>()},
        {"render", Phase::Frame, renderWorld,
         accessOf<Reads<SceneDef, SpringNetwork, RigidBody, RigidBody2D, Transform, Water, ParticleEmitter,
                        Air, RenderHistory, PoseHistory>,
                  Writes<RenderOutput, Renderer>>()},
    };
    return table;
}

void registerBuiltinSystems(Catalog& catalog) {
    // loaders, codecs and events, by concern; their order is the order of the scenario keys in messages
    registerForceFieldSystem(catalog);
    registerGrabSystem(catalog);
    registerParticleSystem(catalog);
    registerSpringSystem(catalog);
    registerRigidSystem(catalog);
    registerWaterSystem(catalog);
    registerAirSystem(catalog);
    for (const SystemEntry& s : builtinSystems()) {
        catalog.addSystem(s);
    }
}

const Catalog& builtinCatalog() {
    static const Catalog catalog = [] {
        Catalog c;
        registerBuiltinSystems(c);
        return c;
    }();
    return catalog;
}

} // namespace tumble
