#include "engine/schedule.h"

#include <gtest/gtest.h>

namespace tumble {
namespace {

struct Marker {};

TEST(Schedule, RunsAPhaseInRegistrationOrderAndOnlyThatPhase) {
    Profiler prof;
    Schedule s(prof);
    std::vector<std::string> ran;
    s.add(Phase::Fixed, "b", [&](World&, const StepContext&) { ran.push_back("b"); });
    s.add(Phase::Fixed, "a", [&](World&, const StepContext&) { ran.push_back("a"); });
    s.add(Phase::Frame, "render", [&](World&, const StepContext&) { ran.push_back("render"); });
    s.add(Phase::Fixed, "c", [&](World&, const StepContext&) { ran.push_back("c"); });
    World w;
    s.run(Phase::Fixed, w, StepContext{});
    EXPECT_EQ(ran, (std::vector<std::string>{"b", "a", "c"}));
    EXPECT_EQ(s.names(Phase::Fixed), (std::vector<std::string>{"b", "a", "c"}));
    EXPECT_EQ(s.names(Phase::Frame), (std::vector<std::string>{"render"}));
}

TEST(Schedule, DuplicateNamesAreRefused) {
    Profiler prof;
    Schedule s(prof);
    s.add(Phase::Fixed, "springs", [](World&, const StepContext&) {});
    EXPECT_THROW(s.add(Phase::Frame, "springs", [](World&, const StepContext&) {}), std::logic_error);
}

TEST(Schedule, QueuedChangesApplyAtTheEndOfThePhase) {
    Profiler prof;
    Schedule s(prof);
    World w;
    const Entity e = w.create();
    bool seenInSamePhase = true;
    s.add(Phase::Fixed, "spawner",
          [&](World& world, const StepContext&) { world.commands().emplace(e, Marker{}); });
    s.add(Phase::Fixed, "observer",
          [&](World& world, const StepContext&) { seenInSamePhase = world.has<Marker>(e); });
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
    s.add(Phase::Fixed, "reaper", [](World& world, const StepContext&) {
        world.view<Marker>().each([&world](Entity e, Marker&) { world.commands().destroy(e); });
    });
    s.add(Phase::Fixed, "counter",
          [&](World& world, const StepContext&) { seenByLaterSystem = world.view<Marker>().count(); });
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
    s.add(Phase::Fixed, "one", [](World&, const StepContext&) {});
    s.add(Phase::Fixed, "two", [](World&, const StepContext&) {});
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

} // namespace
} // namespace tumble
