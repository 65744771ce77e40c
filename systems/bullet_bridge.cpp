#include "systems/bullet_bridge.h"

#include "components/joint.h"
#include "components/rigid_body.h"
#include "engine/name.h"
#include "engine/run_report.h"
#include "engine/transform.h"
#include "systems/bridge_slots.h"

#include <btBulletDynamicsCommon.h>

#include <vector>

namespace tumble {

namespace {

btVector3 bt(const Vec3& v) {
    return {btScalar(v.x), btScalar(v.y), btScalar(v.z)};
}
Vec3 fromBt(const btVector3& v) {
    return {double(v.x()), double(v.y()), double(v.z())};
}
btQuaternion bt(const Quat& q) {
    return {btScalar(q.x), btScalar(q.y), btScalar(q.z), btScalar(q.w)};
}
Quat fromBt(const btQuaternion& q) {
    return {double(q.x()), double(q.y()), double(q.z()), double(q.w())};
}

/// The margin Bullet keeps round a convex hull, m (small: GJK wants some).
constexpr double kHullMargin = 0.005;

struct BodySlot {
    Entity entity;
    std::unique_ptr<btTriangleMesh> triangles; ///< a static mesh's triangles (the shape points into them)
    std::unique_ptr<btCollisionShape> shape;
    std::unique_ptr<btRigidBody> body;
    btTransform restFrom = btTransform::getIdentity(); ///< where the body's current stretch of rest began
                                                       ///< (the sleep rule, below)
};

struct JointSlot {
    Entity joint;
    std::unique_ptr<btTypedConstraint> constraint; ///< none for a spring: its force is applied each step
};

} // namespace

struct BulletWorld::Impl {
    // declared in the order they must be built (and the reverse of the order they must go)
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world{&dispatcher, &broadphase, &solver, &config};
    SlotTable<BodySlot> bodies;
    SlotTable<JointSlot> joints;
    btScalar sleepLinear = 0, sleepAngular = 0, sleepTime = 0; ///< m/s, rad/s, s (the scene's, each step)

    ~Impl() {
        for (JointSlot& c : joints) {
            if (c.constraint) {
                world.removeConstraint(c.constraint.get());
            }
        }
        for (BodySlot& b : bodies) {
            if (b.body) {
                world.removeRigidBody(b.body.get());
            }
        }
    }

    btRigidBody* body(std::int32_t id) { return id >= 0 ? bodies[std::size_t(id)].body.get() : nullptr; }

    std::int32_t addBody(Entity e, const RigidBody& rb);
    void removeBody(std::int32_t id);
    std::int32_t addJoint(Entity jointEntity, const Joint& j, RigidBody& a, RigidBody* b);
    void removeJoint(std::int32_t id);
};

namespace {

// How two touching bodies' materials combine, as Box2D does it and as our own springs and particles do
// (systems/collision_system.cpp): friction the geometric mean, restitution the larger. Bullet's own rules
// (the product of both) would make any body bounce off the default ground as if its restitution were 0.
btScalar combinedFriction(const btCollisionObject* a, const btCollisionObject* b) {
    return btSqrt(a->getFriction() * b->getFriction());
}
btScalar combinedRestitution(const btCollisionObject* a, const btCollisionObject* b) {
    return btMax(a->getRestitution(), b->getRestitution());
}

} // namespace

void setBulletMaterialRules() {
    gCalculateCombinedFrictionCallback = combinedFriction;
    gCalculateCombinedRestitutionCallback = combinedRestitution;
}

BulletWorld::BulletWorld(const SceneDef& scene) : m_impl(std::make_unique<Impl>()) {
    setBulletMaterialRules();
    m_impl->world.setGravity(
        btVector3(btScalar(scene.gravity[0]), btScalar(scene.gravity[1]), btScalar(scene.gravity[2])));
    m_impl->world.getSolverInfo().m_numIterations = scene.solverIterations;
}

BulletWorld::~BulletWorld() = default;

std::size_t BulletWorld::bodyCount() const {
    return std::size_t(m_impl->world.getNumCollisionObjects());
}

std::size_t BulletWorld::constraintCount() const {
    return std::size_t(m_impl->world.getNumConstraints());
}

std::int32_t BulletWorld::Impl::addBody(Entity e, const RigidBody& rb) {
    BodySlot slot;
    slot.entity = e;
    switch (rb.shape) {
    case ShapeKind::Plane:
        slot.shape = std::make_unique<btStaticPlaneShape>(bt(rb.normal), btScalar(0));
        break;
    case ShapeKind::Box:
        slot.shape = std::make_unique<btBoxShape>(bt(rb.halfExtents));
        break;
    case ShapeKind::Sphere:
        slot.shape = std::make_unique<btSphereShape>(btScalar(rb.radius));
        break;
    case ShapeKind::Capsule:
        slot.shape = std::make_unique<btCapsuleShape>(btScalar(rb.radius), btScalar(rb.height));
        break;
    case ShapeKind::Cylinder:
        slot.shape = std::make_unique<btCylinderShape>(bt(Vec3{rb.radius, 0.5 * rb.height, rb.radius}));
        break;
    case ShapeKind::Convex: {
        auto hull = std::make_unique<btConvexHullShape>();
        for (const Vec3& p : rb.mesh->vertices) {
            hull->addPoint(bt(p), false);
        }
        // Bullet pads a hull by a margin outside its points (0.04 m by default): rocks would rest that far
        // above the ground and apart, while they are drawn, and springs collide, without it
        hull->setMargin(btScalar(kHullMargin));
        hull->recalcLocalAabb();
        hull->optimizeConvexHull();
        // no initializePolyhedralFeatures(): its clipping contacts cost the avalanche 4.2-5.0 ms a frame
        // (p50) against 2.2-2.8 ms with Bullet's default GJK contacts, and the rocks settle as well
        slot.shape = std::move(hull);
        break;
    }
    case ShapeKind::Mesh: {
        slot.triangles = std::make_unique<btTriangleMesh>();
        const auto& v = rb.mesh->vertices;
        for (const auto& t : rb.mesh->triangles) {
            slot.triangles->addTriangle(bt(v[t[0]]), bt(v[t[1]]), bt(v[t[2]]), true);
        }
        slot.shape = std::make_unique<btBvhTriangleMeshShape>(slot.triangles.get(), true);
        break;
    }
    }
    btVector3 inertia(0, 0, 0);
    if (rb.dynamic()) {
        slot.shape->calculateLocalInertia(btScalar(rb.mass), inertia);
    }
    btRigidBody::btRigidBodyConstructionInfo info(btScalar(rb.mass), nullptr, slot.shape.get(), inertia);
    info.m_startWorldTransform = btTransform(bt(rb.orientation), bt(rb.position));
    info.m_friction = btScalar(rb.friction);
    info.m_restitution = btScalar(rb.restitution);
    slot.body = std::make_unique<btRigidBody>(info);
    if (rb.dynamic()) {
        slot.body->setLinearVelocity(bt(rb.linearVelocity));
        slot.body->setAngularVelocity(bt(rb.angularVelocity));
        // Bullet's own test (instantaneous speeds) is left always passing: the sleep rule is ours (keepAwake)
        slot.body->setSleepingThresholds(BT_LARGE_FLOAT, BT_LARGE_FLOAT);
        slot.restFrom = slot.body->getWorldTransform();
        if (!rb.canSleep) {
            slot.body->setActivationState(DISABLE_DEACTIVATION);
        }
    }
    world.addRigidBody(slot.body.get());
    const std::int32_t id = bodies.take(std::move(slot));
    bodies[std::size_t(id)].body->setUserIndex(id); // (keepAwake finds a contact's bodies by it)
    return id;
}

void BulletWorld::Impl::removeBody(std::int32_t id) {
    world.removeRigidBody(bodies[std::size_t(id)].body.get());
    bodies.release(id);
}

namespace {

/// A body's frame as Bullet has it: for the world, the identity.
btTransform frameOf(const RigidBody* b) {
    return b ? btTransform(bt(b->orientation), bt(b->position)) : btTransform::getIdentity();
}

/// The joint's frame in world space at the start: at the pivot, its z along the axis (hinge) or its x along
/// it (slider). Both bodies' frames are made from this one, so the joint starts at zero, untwisted.
btTransform jointFrame(const Joint& j) {
    const btVector3 axis = bt(j.axis).normalized();
    btQuaternion turn(0, 0, 0, 1);
    if (j.kind == JointKind::Hinge) {
        turn = shortestArcQuat(btVector3(0, 0, 1), axis);
    } else if (j.kind == JointKind::Slider) {
        turn = shortestArcQuat(btVector3(1, 0, 0), axis);
    }
    return btTransform(turn, bt(j.pivot));
}

} // namespace

std::int32_t BulletWorld::Impl::addJoint(Entity jointEntity, const Joint& j, RigidBody& a, RigidBody* b) {
    btRigidBody& ra = *body(a.bodyId);
    btRigidBody& rb = b ? *body(b->bodyId) : btTypedConstraint::getFixedBody();
    const btTransform shared = jointFrame(j);
    const btTransform inA = frameOf(&a).inverse() * shared, inB = frameOf(b).inverse() * shared;
    std::unique_ptr<btTypedConstraint> c;
    switch (j.kind) {
    case JointKind::Hinge: {
        // Bullet's hinge angle is a's turn relative to b about the axis: the sign the limits are given in
        auto hinge = std::make_unique<btHingeConstraint>(ra, rb, inA, inB);
        if (j.limited) {
            hinge->setLimit(btScalar(j.lower), btScalar(j.upper));
        }
        c = std::move(hinge);
        break;
    }
    case JointKind::Point:
        c = std::make_unique<btPoint2PointConstraint>(ra, rb, inA.getOrigin(), inB.getOrigin());
        break;
    case JointKind::Fixed:
        c = std::make_unique<btFixedConstraint>(ra, rb, inA, inB);
        break;
    case JointKind::Slider: {
        // Bullet's slider position is its second body's travel along the first's frame: b first, so that
        // the limits are a's travel relative to b
        auto slider = std::make_unique<btSliderConstraint>(rb, ra, inB, inA, true);
        if (j.limited) {
            slider->setLowerLinLimit(btScalar(j.lower));
            slider->setUpperLinLimit(btScalar(j.upper));
        }
        c = std::move(slider);
        break;
    }
    case JointKind::Spring:
        break; // a force, applied each step
    }
    if (c) {
        // the bodies a joint holds together do not also collide with each other
        world.addConstraint(c.get(), true);
    }
    return joints.take(JointSlot{jointEntity, std::move(c)});
}

void BulletWorld::Impl::removeJoint(std::int32_t id) {
    if (btTypedConstraint* c = joints[std::size_t(id)].constraint.get()) {
        world.removeConstraint(c);
    }
    joints.release(id);
}

namespace {

/// The body a joint end names, if it is still a body of this engine that the bridge has made.
RigidBody* jointBody(World& world, Entity e) {
    if (e == kNullEntity || !world.alive(e)) {
        return nullptr;
    }
    RigidBody* b = world.tryGet<RigidBody>(e);
    return b && b->bodyId >= 0 ? b : nullptr;
}

/// A damped spring between a point of body a and a point of body b (or of the world): F = k (|d| - rest)
/// d/|d| plus damping on the speed along d, pulling a towards b and b towards a.
void applySpring(BulletWorld::Impl& impl, const Joint& j, const RigidBody& a, const RigidBody* b) {
    const Vec3 pa = a.toWorld(j.localA), pb = b ? b->toWorld(j.localB) : j.localB;
    const Vec3 d = pb - pa;
    const double len = length(d);
    if (len < 1e-12) {
        return;
    }
    const Vec3 n = d * (1.0 / len);
    const Vec3 va = a.velocityAt(pa), vb = b ? b->velocityAt(pb) : Vec3{};
    const double magnitude = j.stiffness * (len - j.rest) + j.damping * dot(vb - va, n);
    const Vec3 f = n * magnitude;
    impl.body(a.bodyId)->applyForce(bt(f), bt(pa - a.position));
    impl.body(a.bodyId)->activate();
    if (b && b->dynamic()) {
        impl.body(b->bodyId)->applyForce(bt(-f), bt(pb - b->position));
        impl.body(b->bodyId)->activate();
    }
}

} // namespace

namespace {

// bulletSyncIn's stages, named as box2dSyncIn's are

/// The Bullet world, made on the first step that has a 3D body; null while there is none.
BulletWorld::Impl* createWorld(World& world) {
    if (BulletWorld* bw = world.tryResource<BulletWorld>()) {
        return &bw->impl();
    }
    const Pool<RigidBody>* pool = world.findPool<RigidBody>();
    if (!pool || pool->size() == 0) {
        return nullptr;
    }
    return &world.setResource<BulletWorld>(world.resource<SceneDef>()).impl();
}

/// Joints whose joint entity or bodies are gone (first: a joint must go before its bodies).
void removeDeadJoints(World& world, BulletWorld::Impl& impl) {
    for (std::size_t i = 0; i < impl.joints.size(); ++i) {
        const Entity je = impl.joints[i].joint;
        if (je == kNullEntity) {
            continue;
        }
        const Joint* j = world.alive(je) ? world.tryGet<Joint>(je) : nullptr;
        if (!j || j->constraintId != std::int32_t(i) || !jointBody(world, j->a) ||
            (j->b != kNullEntity && !jointBody(world, j->b))) {
            impl.removeJoint(std::int32_t(i));
        }
    }
}

/// Bodies whose entities (or RigidBody components) are gone.
void removeDeadBodies(World& world, BulletWorld::Impl& impl) {
    for (std::size_t i = 0; i < impl.bodies.size(); ++i) {
        const Entity e = impl.bodies[i].entity;
        if (e == kNullEntity) {
            continue;
        }
        const RigidBody* b = world.alive(e) ? world.tryGet<RigidBody>(e) : nullptr;
        if (!b || b->bodyId != std::int32_t(i)) {
            impl.removeBody(std::int32_t(i));
        }
    }
}

/// New bodies, in entity order; then what was set (teleported) or pushed (impulses) onto existing ones.
/// Bodies new this step, added to Bullet. Many at once go in in bit-reversed order of their place in the
/// list (the van der Corput sequence: 0, n/2, n/4, 3n/4, ...), not in list order: Bullet's dynamic AABB
/// tree, filled with bodies sorted along a line (a `repeat`), grows one branch deep and each insertion walks
/// all of it (30,000 spheres in a row took 13 s to add and 4 s for the first step); spread out this way it
/// stays balanced. The order is a function of the list alone, so the bits are the same on every run.
void addNewBodies(World& world, BulletWorld::Impl& impl) {
    std::vector<Entity> fresh;
    world.view<RigidBody>().each([&](Entity e, RigidBody& b) {
        if (b.bodyId < 0) {
            fresh.push_back(e);
        }
    });
    constexpr std::size_t kBulk = 1024; // fewer go in in list order (the first round's bits)
    auto add = [&](Entity e) {
        RigidBody& b = world.get<RigidBody>(e);
        b.bodyId = impl.addBody(e, b);
        b.teleported = false;
    };
    if (fresh.size() < kBulk) {
        for (Entity e : fresh) {
            add(e);
        }
        return;
    }
    unsigned bits = 0;
    while ((std::size_t(1) << bits) < fresh.size()) {
        ++bits;
    }
    for (std::size_t k = 0; k < (std::size_t(1) << bits); ++k) {
        std::size_t r = 0;
        for (unsigned i = 0; i < bits; ++i) {
            r |= ((k >> i) & 1u) << (bits - 1 - i);
        }
        if (r < fresh.size()) {
            add(fresh[r]);
        }
    }
}

/// Wakes the bodies in contact with this one (its material changed: a crate asleep on a floor set to ice
/// slides).
void wakeWhatTouches(BulletWorld::Impl& impl, const btCollisionObject& body) {
    btDispatcher& dispatcher = *impl.world.getDispatcher();
    for (int i = 0; i < dispatcher.getNumManifolds(); ++i) {
        const btPersistentManifold& m = *dispatcher.getManifoldByIndexInternal(i);
        if (m.getBody0() == &body || m.getBody1() == &body) {
            const btCollisionObject* other = m.getBody0() == &body ? m.getBody1() : m.getBody0();
            if (!other->isStaticObject()) {
                const_cast<btCollisionObject*>(other)->activate(true);
            }
        }
    }
}

void addBodiesAndApplyPushes(World& world, BulletWorld::Impl& impl) {
    addNewBodies(world, impl);
    world.view<RigidBody>().each([&](Entity, RigidBody& b) {
        btRigidBody& body = *impl.body(b.bodyId);
        if (b.retuned) {
            // a set event changed its mass, material or sleep (engine/retune.h)
            if (b.dynamic()) {
                btVector3 inertia(0, 0, 0);
                body.getCollisionShape()->calculateLocalInertia(btScalar(b.mass), inertia);
                body.setMassProps(btScalar(b.mass), inertia);
                body.updateInertiaTensor();
                body.forceActivationState(b.canSleep ? ACTIVE_TAG : DISABLE_DEACTIVATION);
                body.activate(true);
            }
            // (Bullet mixes the materials of every contact point again each step: its contacts take them)
            body.setFriction(btScalar(b.friction));
            body.setRestitution(btScalar(b.restitution));
            wakeWhatTouches(impl, body);
            b.retuned = false;
        }
        if (!b.dynamic()) {
            if (b.teleported) {
                // a static body set elsewhere: whatever rested on it, or sleeps where it now is, wakes
                body.setWorldTransform(btTransform(bt(b.orientation), bt(b.position)));
                impl.world.updateSingleAabb(&body);
                for (int i = 0; i < impl.world.getNumCollisionObjects(); ++i) {
                    impl.world.getCollisionObjectArray()[i]->activate(true);
                }
                b.teleported = false;
            }
            return;
        }
        if (b.teleported) {
            body.setWorldTransform(btTransform(bt(b.orientation), bt(b.position)));
            body.setLinearVelocity(bt(b.linearVelocity));
            body.setAngularVelocity(bt(b.angularVelocity));
            body.activate(true);
            b.teleported = false;
        }
        if (b.impulse != Vec3{} || b.angularImpulse != Vec3{}) {
            body.applyCentralImpulse(bt(b.impulse));
            body.applyTorqueImpulse(bt(b.angularImpulse));
            body.activate(true);
            b.impulse = b.angularImpulse = Vec3{};
        }
    });
}

/// New joints, and the springs' forces (a spring joint is a force applied every step).
void addJoints(World& world, BulletWorld::Impl& impl) {
    world.view<Joint>().each([&](Entity e, Joint& j) {
        if (j.twoD) {
            return;
        }
        RigidBody* a = jointBody(world, j.a);
        RigidBody* b = j.b == kNullEntity ? nullptr : jointBody(world, j.b);
        if (!a || (j.b != kNullEntity && !b)) {
            j.constraintId = -1; // its joint went with the body, above
            return;
        }
        if (j.constraintId < 0) {
            j.constraintId = impl.addJoint(e, j, *a, b);
            // the spring's ends, kept in the bodies' frames from here on
            j.localA = a->toLocal(j.pivot);
            j.localB = b ? b->toLocal(j.pivotB) : j.pivotB;
        }
        if (j.kind == JointKind::Spring) {
            applySpring(impl, j, *a, b);
        }
    });
}

} // namespace

/// The scene's gravity, solver iterations and sleep rule, which a set event may change during a run.
void followScene(const SceneDef& scene, BulletWorld::Impl& impl) {
    const btVector3 g(btScalar(scene.gravity[0]), btScalar(scene.gravity[1]), btScalar(scene.gravity[2]));
    if (impl.world.getGravity() != g) {
        impl.world.setGravity(g); // (bodies take the world's gravity as they are added, so each is told)
        for (BodySlot& b : impl.bodies) {
            if (b.body && !b.body->isStaticObject()) {
                b.body->setGravity(g);
                b.body->activate(true);
            }
        }
    }
    impl.world.getSolverInfo().m_numIterations = scene.solverIterations;
    impl.sleepLinear = btScalar(scene.sleepLinear);
    impl.sleepAngular = btScalar(scene.sleepAngularDeg * 3.14159265358979323846 / 180.0);
    impl.sleepTime = btScalar(scene.sleepTime);
}

/// Whether a body touches anything (a contact point within Bullet's contact distance), per body slot.
std::vector<std::uint8_t> touching(BulletWorld::Impl& impl) {
    std::vector<std::uint8_t> out(impl.bodies.size(), 0);
    btDispatcher& d = *impl.world.getDispatcher();
    for (int m = 0; m < d.getNumManifolds(); ++m) {
        const btPersistentManifold* manifold = d.getManifoldByIndexInternal(m);
        if (manifold->getNumContacts() == 0) {
            continue;
        }
        for (const btCollisionObject* o : {manifold->getBody0(), manifold->getBody1()}) {
            const int slot = o->getUserIndex();
            if (slot >= 0 && std::size_t(slot) < out.size()) {
                out[std::size_t(slot)] = 1;
            }
        }
    }
    return out;
}

/// The sleep rule. Box2D's: a body may sleep once its speeds have stayed under sleep_linear and
/// sleep_angular for sleep_time, and an island sleeps when all of its bodies may (Bullet's own 0.8 m/s and
/// 1 rad/s froze a pendulum swinging at 0.27 m/s at a turning point). But Bullet's contacts jitter a resting
/// stack's boxes at up to 0.15 m/s and 10 degrees/s while none leaves its place by more than a few
/// centimetres, so a body that touches something is judged by how far it has gone instead (after Jolt): it
/// may sleep once it has stayed, for sleep_time, within sleep_linear x sleep_time of where that stretch
/// began and turned less than sleep_angular x sleep_time (its average speeds under the thresholds). Bullet
/// keeps the timer: it counts each body's time at rest and puts an island to sleep; a body that is not at
/// rest has it set back to zero here, before each step.
void keepAwake(BulletWorld::Impl& impl) {
    const btScalar reach = impl.sleepLinear * impl.sleepTime, turn = impl.sleepAngular * impl.sleepTime;
    const std::vector<std::uint8_t> inContact = touching(impl);
    for (std::size_t i = 0; i < impl.bodies.size(); ++i) {
        BodySlot& b = impl.bodies[i];
        if (!b.body || b.body->isStaticObject() || b.body->getActivationState() == DISABLE_DEACTIVATION) {
            continue;
        }
        const btTransform& now = b.body->getWorldTransform();
        if (b.body->getActivationState() == ISLAND_SLEEPING) {
            b.restFrom = now;
            continue;
        }
        bool resting = false;
        if (inContact[i]) {
            const btScalar moved = (now.getOrigin() - b.restFrom.getOrigin()).length();
            const btScalar turned = now.getRotation().angleShortestPath(b.restFrom.getRotation());
            resting = moved <= reach && turned <= turn;
        } else {
            resting = b.body->getLinearVelocity().length() < impl.sleepLinear &&
                      b.body->getAngularVelocity().length() < impl.sleepAngular;
        }
        if (!resting) {
            b.restFrom = now;
            b.body->setDeactivationTime(0);
        }
    }
}

void bulletSyncIn(World& world, const StepContext&) {
    BulletWorld::Impl* impl = createWorld(world);
    if (!impl) {
        return; // no 3D bodies: no Bullet world
    }
    followScene(world.resource<SceneDef>(), *impl);
    removeDeadJoints(world, *impl);
    removeDeadBodies(world, *impl);
    addBodiesAndApplyPushes(world, *impl);
    addJoints(world, *impl);
    keepAwake(*impl);
}

void bulletStep(World& world, const StepContext& ctx) {
    if (BulletWorld* bw = world.tryResource<BulletWorld>()) {
        // how long a body must stay under the thresholds to sleep: a process-wide setting of Bullet's, so
        // set to this scene's before each of its steps
        gDeactivationTime = bw->impl().sleepTime;
        // no fixed substep of Bullet's own: a maximum of 0 substeps takes exactly one step of dt
        bw->impl().world.stepSimulation(btScalar(ctx.dt), 0, btScalar(ctx.dt));
    }
}

void bulletSyncOut(World& world, const StepContext& ctx) {
    BulletWorld* bw = world.tryResource<BulletWorld>();
    if (!bw) {
        return;
    }
    BulletWorld::Impl& impl = bw->impl();
    world.view<RigidBody, Transform>().each([&](Entity e, RigidBody& b, Transform& t) {
        if (b.bodyId < 0 || !b.dynamic() || b.frozen) {
            return;
        }
        btRigidBody& body = *impl.body(b.bodyId);
        const btTransform& x = body.getWorldTransform();
        const Vec3 position = fromBt(x.getOrigin()), velocity = fromBt(body.getLinearVelocity());
        if (!isFinite(position) || !isFinite(velocity) || length(velocity) > 1e4) {
            // a joint spring stiffer than the step can take, say: keep the last good pose, stop the body
            // and say so once; the rest of the scene runs on
            b.frozen = true;
            body.setActivationState(DISABLE_SIMULATION);
            const Name* name = world.tryGet<Name>(e);
            world.resource<RunReport>().failures.push_back(
                "rigid body '" + (name ? name->value : std::string("?")) + "' blew up at frame " +
                std::to_string(ctx.frame) + " (its state became non-finite or faster than 10 km/s); it is " +
                "frozen from here on. Remedy: a smaller step (--set scene.dt=...) or softer joint springs");
            return;
        }
        b.position = position;
        b.orientation = fromBt(x.getRotation());
        b.linearVelocity = velocity;
        b.angularVelocity = fromBt(body.getAngularVelocity());
        b.sleeping = body.getActivationState() == ISLAND_SLEEPING;
        t.position = b.position;
    });
}

} // namespace tumble
