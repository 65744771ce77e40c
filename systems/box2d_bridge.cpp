#include "systems/box2d_bridge.h"

#include "components/joint.h"
#include "components/rigid_body_2d.h"
#include "engine/transform.h"
#include "systems/bridge_slots.h"

#include <box2d/box2d.h>

#include <numbers>
#include <vector>

namespace tumble {

namespace {

b2Vec2 b2(const Vec2& v) {
    return {float(v[0]), float(v[1])};
}
b2Vec2 b2xy(const Vec3& v) {
    return {float(v.x), float(v.y)};
}

struct BodySlot {
    Entity entity;
    b2Body* body = nullptr;
};

struct JointSlot {
    Entity joint;
    b2Joint* joint2d = nullptr;
};

} // namespace

struct Box2DWorld::Impl {
    b2World world;
    b2Body* ground = nullptr; ///< static, at the origin: what joints to the world hold on to
    SlotTable<BodySlot> bodies;
    SlotTable<JointSlot> joints;
    int velocityIterations = 8, positionIterations = 3;

    explicit Impl(const SceneDef& scene) : world(b2Vec2(float(scene.gravity[0]), float(scene.gravity[1]))) {
        b2BodyDef def;
        ground = world.CreateBody(&def);
        velocityIterations = scene.velocityIterations;
        positionIterations = scene.positionIterations;
    }
    b2Body* body(std::int32_t id) { return bodies[std::size_t(id)].body; }
};

Box2DWorld::Box2DWorld(const SceneDef& scene) : m_impl(std::make_unique<Impl>(scene)) {}
Box2DWorld::~Box2DWorld() = default;

std::size_t Box2DWorld::bodyCount() const {
    return std::size_t(m_impl->world.GetBodyCount()) - 1;
}

std::size_t Box2DWorld::jointCount() const {
    return std::size_t(m_impl->world.GetJointCount());
}

double shapeArea2D(const RigidBody2D& b) {
    switch (b.shape) {
    case Shape2DKind::Box:
        return 4.0 * b.halfExtents[0] * b.halfExtents[1];
    case Shape2DKind::Circle:
        return std::numbers::pi * b.radius * b.radius;
    case Shape2DKind::Polygon: {
        double twice = 0.0;
        for (std::size_t i = 0; i < b.vertices.size(); ++i) {
            const Vec2& p = b.vertices[i];
            const Vec2& q = b.vertices[(i + 1) % b.vertices.size()];
            twice += p[0] * q[1] - q[0] * p[1];
        }
        return 0.5 * twice;
    }
    case Shape2DKind::Edge:
        return 0.0;
    }
    return 0.0;
}

namespace {

std::int32_t addBody(Box2DWorld::Impl& impl, Entity e, const RigidBody2D& rb) {
    b2BodyDef def;
    def.type = rb.dynamic() ? b2_dynamicBody : b2_staticBody;
    def.position = b2(rb.position);
    def.angle = float(rb.angle);
    def.linearVelocity = b2(rb.velocity);
    def.angularVelocity = float(rb.angularVelocity);
    def.allowSleep = rb.canSleep;
    b2Body* body = impl.world.CreateBody(&def);
    b2FixtureDef fixture;
    fixture.friction = float(rb.friction);
    fixture.restitution = float(rb.restitution);
    const double area = shapeArea2D(rb);
    fixture.density = rb.dynamic() && area > 0.0 ? float(rb.mass / area) : 0.0f;
    b2PolygonShape polygon;
    b2CircleShape circle;
    b2EdgeShape edge;
    switch (rb.shape) {
    case Shape2DKind::Box:
        polygon.SetAsBox(float(rb.halfExtents[0]), float(rb.halfExtents[1]));
        fixture.shape = &polygon;
        break;
    case Shape2DKind::Circle:
        circle.m_radius = float(rb.radius);
        fixture.shape = &circle;
        break;
    case Shape2DKind::Polygon: {
        b2Vec2 points[b2_maxPolygonVertices];
        for (std::size_t i = 0; i < rb.vertices.size(); ++i) {
            points[i] = b2(rb.vertices[i]);
        }
        polygon.Set(points, int32(rb.vertices.size()));
        fixture.shape = &polygon;
        break;
    }
    case Shape2DKind::Edge:
        edge.SetTwoSided(b2(rb.from), b2(rb.to));
        fixture.shape = &edge;
        break;
    }
    body->CreateFixture(&fixture);
    return impl.bodies.take(BodySlot{e, body});
}

/// The Box2D joint for j between bodies a and b (Box2D's order: the caller passes the joint's b first).
b2Joint* makeJoint(Box2DWorld::Impl& impl, const Joint& j, b2Body* a, b2Body* b) {
    switch (j.kind) {
    case JointKind::Hinge:
    case JointKind::Point: {
        // in the plane a hinge (about z) and a point joint are the same revolute joint
        b2RevoluteJointDef def;
        def.Initialize(a, b, b2xy(j.pivot));
        def.enableLimit = j.limited;
        def.lowerAngle = float(j.lower);
        def.upperAngle = float(j.upper);
        return impl.world.CreateJoint(&def);
    }
    case JointKind::Fixed: {
        b2WeldJointDef def;
        def.Initialize(a, b, b2xy(j.pivot));
        return impl.world.CreateJoint(&def);
    }
    case JointKind::Slider: {
        b2PrismaticJointDef def;
        b2Vec2 axis = b2xy(j.axis);
        axis.Normalize();
        def.Initialize(a, b, b2xy(j.pivot), axis);
        def.enableLimit = j.limited;
        def.lowerTranslation = float(j.lower);
        def.upperTranslation = float(j.upper);
        return impl.world.CreateJoint(&def);
    }
    case JointKind::Spring: {
        b2DistanceJointDef def;
        def.Initialize(a, b, b2xy(j.pivotB), b2xy(j.pivot)); // a is the joint's b, b its a: see the caller
        def.length = float(j.rest);
        def.minLength = 0.0f;
        def.maxLength = b2_maxFloat;
        def.stiffness = float(j.stiffness);
        def.damping = float(j.damping);
        return impl.world.CreateJoint(&def);
    }
    }
    return nullptr;
}

RigidBody2D* jointBody(World& world, Entity e) {
    if (e == kNullEntity || !world.alive(e)) {
        return nullptr;
    }
    RigidBody2D* b = world.tryGet<RigidBody2D>(e);
    return b && b->bodyId >= 0 ? b : nullptr;
}

} // namespace

namespace {

// box2dSyncIn's stages, named as bulletSyncIn's are

/// The Box2D world, made on the first step that has a 2D body; null while there is none.
Box2DWorld::Impl* createWorld(World& world) {
    if (Box2DWorld* bw = world.tryResource<Box2DWorld>()) {
        return &bw->impl();
    }
    const Pool<RigidBody2D>* pool = world.findPool<RigidBody2D>();
    if (!pool || pool->size() == 0) {
        return nullptr;
    }
    return &world.setResource<Box2DWorld>(world.resource<SceneDef>()).impl();
}

/// Joints whose joint entity or bodies are gone (first: Box2D would destroy them with a body, but the slot
/// must go too).
void removeDeadJoints(World& world, Box2DWorld::Impl& impl) {
    for (std::size_t i = 0; i < impl.joints.size(); ++i) {
        const Entity je = impl.joints[i].joint;
        if (je == kNullEntity) {
            continue;
        }
        const Joint* j = world.alive(je) ? world.tryGet<Joint>(je) : nullptr;
        if (!j || j->constraintId != std::int32_t(i) || !jointBody(world, j->a) ||
            (j->b != kNullEntity && !jointBody(world, j->b))) {
            impl.world.DestroyJoint(impl.joints[i].joint2d);
            impl.joints.release(std::int32_t(i));
        }
    }
}

/// Bodies whose entities (or RigidBody2D components) are gone.
void removeDeadBodies(World& world, Box2DWorld::Impl& impl) {
    for (std::size_t i = 0; i < impl.bodies.size(); ++i) {
        const Entity e = impl.bodies[i].entity;
        if (e == kNullEntity) {
            continue;
        }
        const RigidBody2D* b = world.alive(e) ? world.tryGet<RigidBody2D>(e) : nullptr;
        if (!b || b->bodyId != std::int32_t(i)) {
            impl.world.DestroyBody(impl.bodies[i].body);
            impl.bodies.release(std::int32_t(i));
        }
    }
}

/// New bodies, in entity order; then what was set (teleported) or pushed (impulses) onto existing ones.
void addBodiesAndApplyPushes(World& world, Box2DWorld::Impl& impl) {
    world.view<RigidBody2D>().each([&](Entity e, RigidBody2D& b) {
        if (b.bodyId < 0) {
            b.bodyId = addBody(impl, e, b);
            b.teleported = false;
        }
        b2Body& body = *impl.body(b.bodyId);
        if (b.retuned) {
            // a set event changed its mass or material (engine/retune.h); the contacts it is in mixed their
            // friction and restitution when they began, so they mix them again
            const double area = shapeArea2D(b);
            for (b2Fixture* f = body.GetFixtureList(); f; f = f->GetNext()) {
                f->SetFriction(float(b.friction));
                f->SetRestitution(float(b.restitution));
                f->SetDensity(b.dynamic() && area > 0.0 ? float(b.mass / area) : 0.0f);
            }
            for (b2ContactEdge* c = body.GetContactList(); c; c = c->next) {
                c->contact->ResetFriction();
                c->contact->ResetRestitution();
                c->other->SetAwake(true);
            }
            if (b.dynamic()) {
                body.ResetMassData();
                body.SetSleepingAllowed(b.canSleep);
                body.SetAwake(true);
            }
            b.retuned = false;
        }
        if (!b.dynamic()) {
            if (b.teleported) {
                // a static body set elsewhere: whatever rested on it, or sleeps where it now is, wakes
                body.SetTransform(b2(b.position), float(b.angle));
                for (b2Body* other = impl.world.GetBodyList(); other; other = other->GetNext()) {
                    other->SetAwake(true);
                }
                b.teleported = false;
            }
            return;
        }
        if (b.teleported) {
            body.SetTransform(b2(b.position), float(b.angle));
            body.SetLinearVelocity(b2(b.velocity));
            body.SetAngularVelocity(float(b.angularVelocity));
            body.SetAwake(true);
            b.teleported = false;
        }
        if (b.impulse != Vec2{0.0, 0.0} || b.angularImpulse != 0.0) {
            body.ApplyLinearImpulseToCenter(b2(b.impulse), true);
            body.ApplyAngularImpulse(float(b.angularImpulse), true);
            b.impulse = {0.0, 0.0};
            b.angularImpulse = 0.0;
        }
    });
}

/// New joints.
void addJoints(World& world, Box2DWorld::Impl& impl) {
    world.view<Joint>().each([&](Entity e, Joint& j) {
        if (!j.twoD) {
            return;
        }
        RigidBody2D* a = jointBody(world, j.a);
        RigidBody2D* b = j.b == kNullEntity ? nullptr : jointBody(world, j.b);
        if (!a || (j.b != kNullEntity && !b)) {
            j.constraintId = -1; // its joint went with the body, above
            return;
        }
        if (j.constraintId >= 0) {
            return;
        }
        // Box2D measures a joint's angle and travel as its second body's relative to its first: b (or the
        // ground) first, so that limits are a's turn or travel relative to b, as in the Bullet bridge
        b2Joint* joint = makeJoint(impl, j, b ? impl.body(b->bodyId) : impl.ground, impl.body(a->bodyId));
        j.constraintId = impl.joints.take(JointSlot{e, joint});
    });
}

} // namespace

void box2dSyncIn(World& world, const StepContext&) {
    Box2DWorld::Impl* impl = createWorld(world);
    if (!impl) {
        return; // no 2D bodies: no Box2D world
    }
    // the scene's gravity and iterations, which a set event may change during a run
    const SceneDef& scene = world.resource<SceneDef>();
    const b2Vec2 g(float(scene.gravity[0]), float(scene.gravity[1]));
    if (impl->world.GetGravity() != g) {
        impl->world.SetGravity(g);
        for (BodySlot& b : impl->bodies) {
            if (b.body) {
                b.body->SetAwake(true);
            }
        }
    }
    impl->velocityIterations = scene.velocityIterations;
    impl->positionIterations = scene.positionIterations;
    removeDeadJoints(world, *impl);
    removeDeadBodies(world, *impl);
    addBodiesAndApplyPushes(world, *impl);
    addJoints(world, *impl);
}

void box2dStep(World& world, const StepContext& ctx) {
    if (Box2DWorld* bw = world.tryResource<Box2DWorld>()) {
        Box2DWorld::Impl& impl = bw->impl();
        impl.world.Step(float(ctx.dt), impl.velocityIterations, impl.positionIterations);
    }
}

void box2dSyncOut(World& world, const StepContext&) {
    Box2DWorld* bw = world.tryResource<Box2DWorld>();
    if (!bw) {
        return;
    }
    Box2DWorld::Impl& impl = bw->impl();
    world.view<RigidBody2D, Transform>().each([&](Entity, RigidBody2D& b, Transform& t) {
        if (b.bodyId < 0 || !b.dynamic()) {
            return;
        }
        const b2Body& body = *impl.body(b.bodyId);
        b.position = {double(body.GetPosition().x), double(body.GetPosition().y)};
        b.angle = double(body.GetAngle());
        b.velocity = {double(body.GetLinearVelocity().x), double(body.GetLinearVelocity().y)};
        b.angularVelocity = double(body.GetAngularVelocity());
        b.sleeping = !body.IsAwake();
        t.position = {b.position[0], b.position[1], t.position.z};
    });
}

} // namespace tumble
