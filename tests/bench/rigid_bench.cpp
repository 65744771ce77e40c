// The rigid-body bridges against the raw engines on the same scenes, in one binary:
//   a stack of 1000 1 m boxes (10 x 10 x 10) on a plane, Bullet, 1/60 s steps (BASELINES.md: ~4.4 ms raw);
//   a Box2D pyramid of base 40 (820 boxes, rows touching and offset by half a box), 8/3 iterations
//   (BASELINES.md: ~2.5 ms raw).
// Each benchmark times the first 120 steps of a fresh scene, one step per iteration; the bridge's run is a
// whole Tumble fixed step (every system, the bridges' copies in and out, the profiler). After the timed
// steps the two runs are compared body by body: the bridge must give the raw engine's bits, or the
// benchmark reports an error.
//   build/tests/bench/tumble_bench --benchmark_filter=Stack\|Pyramid --benchmark_repetitions=5

#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "engine/simulation.h"
#include "systems/builtin.h"
#include "systems/bullet_bridge.h"
#include "tests/bench/bench_support.h"

#include <benchmark/benchmark.h>
#include <box2d/box2d.h>
#include <btBulletDynamicsCommon.h>

#include <memory>
#include <string>
#include <vector>

namespace tumble {
namespace {

constexpr int kSteps = 120;
constexpr double kDt = 1.0 / 60.0;

const Catalog& catalog() {
    return bench::builtinCatalog();
}

std::unique_ptr<Simulation> load(const std::string& text) {
    return std::make_unique<Simulation>(catalog(), "bench.toml", text, std::vector<std::string>{});
}

// ---- the Bullet stack

std::string stackScene() {
    std::string s = "[scene]\nname = \"stack\"\ndt = 0.016666666666666666\n"
                    "[[entity]]\nname = \"floor\"\n[entity.rigid_body]\nshape = \"plane\"\n";
    for (int i = 0; i < 10; ++i) {
        for (int k = 0; k < 10; ++k) {
            s += "[[entity]]\nname = \"c" + std::to_string(i) + "_" + std::to_string(k) +
                 "\"\nrepeat = { count = 10, offset = [0, 1, 0] }\n[entity.transform]\nposition = [" +
                 std::to_string(i - 5) + ", 0.5, " + std::to_string(k - 5) +
                 "]\n[entity.rigid_body]\nshape = \"box\"\nmass = 1.0\n";
        }
    }
    return s;
}

/// The same scene in Bullet alone: bodies added in the same order, with the same settings.
struct RawBullet {
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world{&dispatcher, &broadphase, &solver, &config};
    btStaticPlaneShape plane{btVector3(0, 1, 0), 0};
    btBoxShape box{btVector3(0.5, 0.5, 0.5)};
    std::vector<std::unique_ptr<btRigidBody>> bodies;

    RawBullet() {
        setBulletMaterialRules(); // the same rules as the bridge's, or it would be another simulation
        world.setGravity(btVector3(0, btScalar(-9.81), 0));
        add(&plane, 0, btVector3(0, 0, 0));
        for (int i = 0; i < 10; ++i) {
            for (int k = 0; k < 10; ++k) {
                for (int j = 0; j < 10; ++j) {
                    add(&box, 1.0, btVector3(btScalar(i - 5), btScalar(0.5 + j), btScalar(k - 5)));
                }
            }
        }
    }
    ~RawBullet() {
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
        world.addRigidBody(bodies.back().get());
    }
};

/// Heights of the stack's boxes, in the order both runs made them.
std::vector<double> heights(Simulation& sim) {
    std::vector<double> out;
    sim.world().view<const RigidBody>().each([&](Entity, const RigidBody& b) {
        if (b.dynamic()) {
            out.push_back(b.position.y);
        }
    });
    return out;
}

void BM_BulletStackRaw(benchmark::State& state) {
    RawBullet raw;
    for (auto _ : state) {
        raw.world.stepSimulation(btScalar(kDt), 0, btScalar(kDt));
    }
}
BENCHMARK(BM_BulletStackRaw)->Unit(benchmark::kMillisecond)->Iterations(kSteps);

void BM_BulletStackBridge(benchmark::State& state) {
    auto sim = load(stackScene());
    for (auto _ : state) {
        sim->runFrame();
    }
    RawBullet raw;
    for (int i = 0; i < kSteps; ++i) {
        raw.world.stepSimulation(btScalar(kDt), 0, btScalar(kDt));
    }
    std::vector<double> expected;
    for (std::size_t i = 1; i < raw.bodies.size(); ++i) {
        expected.push_back(raw.bodies[i]->getWorldTransform().getOrigin().y());
    }
    if (heights(*sim) != expected) {
        state.SkipWithError("the bridge did not give raw Bullet's bits");
    }
}
BENCHMARK(BM_BulletStackBridge)->Unit(benchmark::kMillisecond)->Iterations(kSteps);

// ---- the Box2D pyramid

constexpr int kBase = 40;

std::string pyramidScene() {
    std::string s =
        "[scene]\nname = \"pyramid\"\ndt = 0.016666666666666666\n"
        "[[entity]]\nname = \"ground\"\n[entity.rigid_body_2d]\nshape = \"edge\"\nfrom = [-40, 0]\n"
        "to = [40, 0]\n";
    for (int row = 0; row < kBase; ++row) {
        const int n = kBase - row;
        s += "[[entity]]\nname = \"r" + std::to_string(row) + "\"\nrepeat = { count = " + std::to_string(n) +
             ", offset = [1, 0, 0] }\n[entity.transform]\nposition = [" + std::to_string(-0.5 * (n - 1)) +
             ", " + std::to_string(0.5 + row) + ", 0]\n[entity.rigid_body_2d]\nshape = \"box\"\nmass = 1.0\n";
    }
    return s;
}

struct RawBox2D {
    b2World world{b2Vec2(0.0f, -9.81f)};
    std::vector<b2Body*> boxes;

    RawBox2D() {
        b2BodyDef worldBody; // the bridge's body for joints to the world, made first
        world.CreateBody(&worldBody);
        b2BodyDef groundDef;
        b2Body* ground = world.CreateBody(&groundDef);
        b2EdgeShape edge;
        edge.SetTwoSided(b2Vec2(-40, 0), b2Vec2(40, 0));
        b2FixtureDef groundFixture;
        groundFixture.shape = &edge;
        groundFixture.friction = 0.6f;
        ground->CreateFixture(&groundFixture);
        b2PolygonShape box;
        box.SetAsBox(0.5f, 0.5f);
        for (int row = 0; row < kBase; ++row) {
            const int n = kBase - row;
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
};

void BM_Box2DPyramidRaw(benchmark::State& state) {
    RawBox2D raw;
    for (auto _ : state) {
        raw.world.Step(float(kDt), 8, 3);
    }
}
BENCHMARK(BM_Box2DPyramidRaw)->Unit(benchmark::kMillisecond)->Iterations(kSteps);

void BM_Box2DPyramidBridge(benchmark::State& state) {
    auto sim = load(pyramidScene());
    for (auto _ : state) {
        sim->runFrame();
    }
    RawBox2D raw;
    for (int i = 0; i < kSteps; ++i) {
        raw.world.Step(float(kDt), 8, 3);
    }
    std::vector<double> expected, got;
    for (b2Body* b : raw.boxes) {
        expected.push_back(double(b->GetPosition().y));
    }
    sim->world().view<const RigidBody2D>().each([&](Entity, const RigidBody2D& b) {
        if (b.dynamic()) {
            got.push_back(b.position[1]);
        }
    });
    if (got != expected) {
        state.SkipWithError("the bridge did not give raw Box2D's bits");
    }
}
BENCHMARK(BM_Box2DPyramidBridge)->Unit(benchmark::kMillisecond)->Iterations(kSteps);

} // namespace
} // namespace tumble
