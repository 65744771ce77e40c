#pragma once
// The same scenes as a Tumble scenario and in the raw engines, built here once for the test that holds the
// bridges to the raw engines' bits (rigid_body_test.cpp) and the benchmark that times them
// (bench/rigid_bench.cpp):
//   a stack of 1 m boxes on a plane, `side` x `side` columns of `layers` boxes, Bullet, 1/60 s steps;
//   a Box2D pyramid of base `base` (rows touching, each offset by half a box), 8/3 iterations.
// Bodies are made in the order the scenario makes them, with the settings the bridges give them.

#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "engine/simulation.h"
#include "systems/bullet_bridge.h"

#include <box2d/box2d.h>
#include <btBulletDynamicsCommon.h>

#include <memory>
#include <string>
#include <vector>

namespace tumble::raw {

constexpr double kDt = 1.0 / 60.0;

/// `sleep`: whether the boxes may sleep; the comparisons with raw Bullet turn it off, as the sleep rule is
/// the bridge's own (bullet_bridge.cpp, keepAwake).
inline std::string stackScene(int side, int layers, bool sleep = true) {
    std::string s = "[scene]\nname = \"stack\"\ndt = 0.016666666666666666\n"
                    "[[entity]]\nname = \"floor\"\n[entity.rigid_body]\nshape = \"plane\"\n";
    for (int i = 0; i < side; ++i) {
        for (int k = 0; k < side; ++k) {
            s += "[[entity]]\nname = \"c" + std::to_string(i) + "_" + std::to_string(k) +
                 "\"\nrepeat = { count = " + std::to_string(layers) +
                 ", offset = [0, 1, 0] }\n[entity.transform]\nposition = [" + std::to_string(i - side / 2) +
                 ", 0.5, " + std::to_string(k - side / 2) +
                 "]\n[entity.rigid_body]\nshape = \"box\"\nmass = 1.0\n" + (sleep ? "" : "sleep = false\n");
        }
    }
    return s;
}

/// The stack in Bullet alone, its boxes never sleeping (as stackScene(side, layers, false) has them).
struct BulletStack {
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world{&dispatcher, &broadphase, &solver, &config};
    btStaticPlaneShape plane{btVector3(0, 1, 0), 0};
    btBoxShape box{btVector3(0.5, 0.5, 0.5)};
    std::vector<std::unique_ptr<btRigidBody>> bodies; ///< the plane first, then the boxes

    BulletStack(int side, int layers) {
        setBulletMaterialRules(); // the same rules as the bridge's, or it would be another simulation
        world.setGravity(btVector3(0, btScalar(-9.81), 0));
        add(&plane, 0, btVector3(0, 0, 0));
        for (int i = 0; i < side; ++i) {
            for (int k = 0; k < side; ++k) {
                for (int j = 0; j < layers; ++j) {
                    add(&box, 1.0,
                        btVector3(btScalar(i - side / 2), btScalar(0.5 + j), btScalar(k - side / 2)));
                }
            }
        }
    }
    ~BulletStack() {
        for (auto& b : bodies) {
            world.removeRigidBody(b.get());
        }
    }
    void add(btCollisionShape* shape, btScalar mass, const btVector3& at) {
        btVector3 inertia(0, 0, 0);
        if (mass > 0) {
            shape->calculateLocalInertia(mass, inertia);
        }
        btRigidBody::btRigidBodyConstructionInfo info(mass, nullptr, shape, inertia);
        info.m_startWorldTransform = btTransform(btQuaternion(0, 0, 0, 1), at);
        info.m_friction = btScalar(0.6);
        info.m_restitution = 0;
        bodies.push_back(std::make_unique<btRigidBody>(info));
        if (mass > 0) {
            bodies.back()->setActivationState(DISABLE_DEACTIVATION);
        }
        world.addRigidBody(bodies.back().get());
    }
    void step() { world.stepSimulation(btScalar(kDt), 0, btScalar(kDt)); }
    /// Every box's position and orientation, in order.
    std::vector<double> state() const {
        std::vector<double> out;
        for (std::size_t i = 1; i < bodies.size(); ++i) {
            const btTransform& t = bodies[i]->getWorldTransform();
            const btQuaternion q = t.getRotation();
            for (btScalar v :
                 {t.getOrigin().x(), t.getOrigin().y(), t.getOrigin().z(), q.x(), q.y(), q.z(), q.w()}) {
                out.push_back(double(v));
            }
        }
        return out;
    }
};

/// Every moving Bullet body's position and orientation in the world, in slot order.
inline std::vector<double> bulletState(Simulation& sim) {
    std::vector<double> out;
    sim.world().view<const RigidBody>().each([&](Entity, const RigidBody& b) {
        if (b.dynamic()) {
            for (double v : {b.position.x, b.position.y, b.position.z, b.orientation.x, b.orientation.y,
                             b.orientation.z, b.orientation.w}) {
                out.push_back(v);
            }
        }
    });
    return out;
}

inline std::string pyramidScene(int base) {
    std::string s = "[scene]\nname = \"pyramid\"\ndt = 0.016666666666666666\n"
                    "[[entity]]\nname = \"ground\"\n[entity.rigid_body_2d]\nshape = \"edge\"\nfrom = [-" +
                    std::to_string(base) + ", 0]\nto = [" + std::to_string(base) + ", 0]\n";
    for (int row = 0; row < base; ++row) {
        const int n = base - row;
        s += "[[entity]]\nname = \"r" + std::to_string(row) + "\"\nrepeat = { count = " + std::to_string(n) +
             ", offset = [1, 0, 0] }\n[entity.transform]\nposition = [" + std::to_string(-0.5 * (n - 1)) +
             ", " + std::to_string(0.5 + row) + ", 0]\n[entity.rigid_body_2d]\nshape = \"box\"\nmass = 1.0\n";
    }
    return s;
}

/// The pyramid in Box2D alone.
struct Box2DPyramid {
    b2World world{b2Vec2(0.0f, -9.81f)};
    std::vector<b2Body*> boxes;

    explicit Box2DPyramid(int base) {
        b2BodyDef worldBody; // the bridge's body for joints to the world, made first
        world.CreateBody(&worldBody);
        b2BodyDef groundDef;
        b2Body* ground = world.CreateBody(&groundDef);
        b2EdgeShape edge;
        edge.SetTwoSided(b2Vec2(float(-base), 0), b2Vec2(float(base), 0));
        b2FixtureDef groundFixture;
        groundFixture.shape = &edge;
        groundFixture.friction = 0.6f;
        ground->CreateFixture(&groundFixture);
        b2PolygonShape box;
        box.SetAsBox(0.5f, 0.5f);
        for (int row = 0; row < base; ++row) {
            const int n = base - row;
            for (int i = 0; i < n; ++i) {
                b2BodyDef def;
                def.type = b2_dynamicBody;
                def.position.Set(float(-0.5 * (n - 1) + i), float(0.5 + row));
                b2Body* body = world.CreateBody(&def);
                b2FixtureDef fixture;
                fixture.shape = &box;
                fixture.density = 1.0f; // 1 kg over the box's 1 m^2, as the bridge spreads it
                fixture.friction = 0.6f;
                body->CreateFixture(&fixture);
                boxes.push_back(body);
            }
        }
    }
    void step() { world.Step(float(kDt), 8, 3); }
    /// Every box's position and angle, in order.
    std::vector<double> state() const {
        std::vector<double> out;
        for (b2Body* b : boxes) {
            out.push_back(double(b->GetPosition().x));
            out.push_back(double(b->GetPosition().y));
            out.push_back(double(b->GetAngle()));
        }
        return out;
    }
};

/// Every moving Box2D body's position and angle in the world, in slot order.
inline std::vector<double> box2dState(Simulation& sim) {
    std::vector<double> out;
    sim.world().view<const RigidBody2D>().each([&](Entity, const RigidBody2D& b) {
        if (b.dynamic()) {
            out.push_back(b.position[0]);
            out.push_back(b.position[1]);
            out.push_back(b.angle);
        }
    });
    return out;
}

} // namespace tumble::raw
