#include "engine/schedule.h"

#include <gtest/gtest.h>

#include <functional>
#include <string>

namespace tumble {
namespace {

struct Marker {};
struct Position {
    double x = 0;
};
struct Velocity {
    double v = 0;
};
struct Clock {
    double t = 0;
};

TEST(Schedule, RunsAPhaseInRegistrationOrderAndOnlyThatPhase) {
    Profiler prof;
    Schedule s(prof);
    std::vector<std::string> ran;
    s.add(
        Phase::Fixed, "b", [&](World&, const StepContext&) { ran.push_back("b"); }, Access::everything());
    s.add(
        Phase::Fixed, "a", [&](World&, const StepContext&) { ran.push_back("a"); }, Access::everything());
    s.add(
        Phase::Frame, "render", [&](World&, const StepContext&) { ran.push_back("render"); },
        Access::everything());
    s.add(
        Phase::Fixed, "c", [&](World&, const StepContext&) { ran.push_back("c"); }, Access::everything());
    World w;
    s.run(Phase::Fixed, w, StepContext{});
    EXPECT_EQ(ran, (std::vector<std::string>{"b", "a", "c"}));
    EXPECT_EQ(s.names(Phase::Fixed), (std::vector<std::string>{"b", "a", "c"}));
    EXPECT_EQ(s.names(Phase::Frame), (std::vector<std::string>{"render"}));
}

TEST(Schedule, DuplicateNamesAreRefused) {
    Profiler prof;
    Schedule s(prof);
    s.add(
        Phase::Fixed, "springs", [](World&, const StepContext&) {}, Access::everything());
    EXPECT_THROW(s.add(
                     Phase::Frame, "springs", [](World&, const StepContext&) {}, Access::everything()),
                 std::logic_error);
}

TEST(Schedule, QueuedChangesApplyAtTheEndOfThePhase) {
    Profiler prof;
    Schedule s(prof);
    World w;
    const Entity e = w.create();
    bool seenInSamePhase = true;
    s.add(
        Phase::Fixed, "spawner",
        [&](World& world, const StepContext&) { world.commands().emplace(e, Marker{}); },
        Access::everything());
    s.add(
        Phase::Fixed, "observer",
        [&](World& world, const StepContext&) { seenInSamePhase = world.has<Marker>(e); },
        Access::everything());
    s.run(Phase::Fixed, w, StepContext{});
    EXPECT_FALSE(seenInSamePhase) << "a change queued in a phase is not visible until the phase ends";
    EXPECT_TRUE(w.has<Marker>(e));
}

TEST(Schedule, DestroyRequestedDuringIterationAppliesAtTheEndOfThePhase) {
    Profiler prof;
    Schedule s(prof);
    World w;
    std::vector<Entity> es;
    for (int i = 0; i < 4; ++i) {
        es.push_back(w.create());
        w.emplace<Marker>(es.back());
    }
    std::size_t seenByLaterSystem = 0;
    s.add(
        Phase::Fixed, "reaper",
        [](World& world, const StepContext&) {
            world.view<Marker>().each([&world](Entity e, Marker&) { world.commands().destroy(e); });
        },
        Access::everything());
    s.add(
        Phase::Fixed, "counter",
        [&](World& world, const StepContext&) { seenByLaterSystem = world.view<Marker>().count(); },
        Access::everything());
    s.run(Phase::Fixed, w, StepContext{});
    EXPECT_EQ(seenByLaterSystem, 4u) << "later systems of the phase still see the entities";
    EXPECT_EQ(w.size(), 0u) << "and they are gone when the phase ends";
    for (Entity e : es) {
        EXPECT_FALSE(w.alive(e));
    }
}

TEST(Schedule, EverySystemAndPhaseIsTimed) {
    Profiler prof;
    Schedule s(prof);
    s.add(
        Phase::Fixed, "one", [](World&, const StepContext&) {}, Access::everything());
    s.add(
        Phase::Fixed, "two", [](World&, const StepContext&) {}, Access::everything());
    World w;
    for (int i = 0; i < 5; ++i) {
        s.run(Phase::Fixed, w, StepContext{});
    }
    int timedSystems = 0;
    for (const SlotStats& st : prof.slotStats()) {
        if (st.name == "one" || st.name == "two" || st.name == "phase:fixed") {
            EXPECT_EQ(st.calls, 5u) << st.name;
            timedSystems += !st.isPhase;
        }
    }
    EXPECT_EQ(timedSystems, 2);
}

// a system that strays outside its declaration is stopped at the first view, get or resource; written
// types must be declared written, read ones either way, and outside a system nothing is checked
TEST(Schedule, ASystemTouchingWhatItDidNotDeclareFails) {
    Profiler prof;
    World w;
    const Entity e = w.create();
    w.emplace<Position>(e);
    w.emplace<Velocity>(e);
    w.setResource<Clock>();
    auto runs = [&](Access access, std::function<void(World&)> body) {
        Schedule s(prof);
        s.add(
            Phase::Fixed, "probe", [&](World& world, const StepContext&) { body(world); }, std::move(access));
        try {
            s.run(Phase::Fixed, w, StepContext{});
            return std::string();
        } catch (const AccessError& err) {
            return std::string(err.what());
        }
    };
    const Access readsPosition = accessOf<Reads<Position>>();
    const Access movesPosition = accessOf<Reads<Velocity, Clock>, Writes<Position>>();
    EXPECT_EQ(runs(readsPosition, [](World& world) { world.view<const Position>().count(); }), "");
    EXPECT_NE(runs(readsPosition, [](World& world) { world.view<Position>().count(); }), "");
    EXPECT_NE(runs(readsPosition, [](World& world) { world.view<const Velocity>().count(); }), "");
    EXPECT_NE(runs(readsPosition, [](World& world) { world.view<const Position, const Velocity>().count(); }),
              "");
    EXPECT_NE(runs(readsPosition, [&](World& world) { world.get<Velocity>(e); }), "");
    EXPECT_NE(runs(readsPosition, [&](World& world) { world.tryGet<Velocity>(e); }), "");
    EXPECT_NE(runs(readsPosition, [](World& world) { world.tryResource<Clock>(); }), "");
    EXPECT_EQ(runs(movesPosition,
                   [](World& world) {
                       const double t = world.resource<Clock>().t;
                       world.view<Position, const Velocity>().each(
                           [t](Entity, Position& p, const Velocity& v) { p.x += v.v * t; });
                   }),
              "");
    // the message names the system, the type and what to do
    const std::string message = runs(readsPosition, [](World& world) { world.view<Velocity>().count(); });
    EXPECT_NE(message.find("'probe'"), std::string::npos) << message;
    EXPECT_NE(message.find("Velocity"), std::string::npos) << message;
    EXPECT_NE(message.find("Writes"), std::string::npos) << message;
    // after the phase, and outside any system, the world is open again
    EXPECT_NO_THROW(w.view<Velocity>().count());
    // an exclusive system may touch anything
    EXPECT_EQ(runs(Access::everything(), [&](World& world) { world.get<Velocity>(e).v = 1; }), "");
}

TEST(Access, ConflictsWhenOneWritesWhatTheOtherTouches) {
    const Access readsBoth = accessOf<Reads<Position, Velocity>>();
    const Access readsPosition = accessOf<Reads<Position>>();
    const Access writesVelocity = accessOf<Reads<>, Writes<Velocity>>();
    const Access writesClock = accessOf<Reads<>, Writes<Clock>>();
    EXPECT_FALSE(readsBoth.conflictsWith(readsPosition));
    EXPECT_TRUE(readsBoth.conflictsWith(writesVelocity));
    EXPECT_TRUE(writesVelocity.conflictsWith(readsBoth));
    EXPECT_FALSE(readsPosition.conflictsWith(writesVelocity));
    EXPECT_FALSE(writesVelocity.conflictsWith(writesClock));
    EXPECT_TRUE(writesClock.conflictsWith(writesClock));
    EXPECT_TRUE(Access::everything().conflictsWith(readsPosition));
    EXPECT_TRUE(readsBoth.reads[1].name.ends_with("Velocity")) << readsBoth.reads[1].name;
}

} // namespace
} // namespace tumble
