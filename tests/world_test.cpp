#include "engine/world.h"

#include <gtest/gtest.h>

#include <set>

namespace tumble {
namespace {

struct Position {
    double x = 0.0;
};
struct Velocity {
    double v = 0.0;
};
struct Tag {};
struct Counter {
    int n = 0;
};

TEST(World, CreatedEntitiesAreAliveAndDistinct) {
    World w;
    const Entity a = w.create();
    const Entity b = w.create();
    EXPECT_TRUE(w.alive(a));
    EXPECT_TRUE(w.alive(b));
    EXPECT_NE(a, b);
    EXPECT_EQ(w.size(), 2u);
    EXPECT_FALSE(w.alive(kNullEntity));
}

TEST(World, DestroyedHandleIsStaleAndSlotReuseBumpsGeneration) {
    World w;
    const Entity a = w.create();
    w.emplace<Position>(a, Position{1.0});
    w.destroy(a);
    EXPECT_FALSE(w.alive(a));
    EXPECT_EQ(w.tryGet<Position>(a), nullptr);
    EXPECT_THROW(w.get<Position>(a), StaleEntityError);
    EXPECT_THROW(w.destroy(a), StaleEntityError);
    EXPECT_THROW(w.emplace<Position>(a), StaleEntityError);

    // the slot is reused with a new generation: the old handle stays stale
    const Entity b = w.create();
    EXPECT_EQ(b.index, a.index);
    EXPECT_NE(b.generation, a.generation);
    EXPECT_TRUE(w.alive(b));
    EXPECT_FALSE(w.alive(a));
    EXPECT_FALSE(w.has<Position>(b)) << "a reused slot must not inherit the old components";
}

TEST(World, ComponentsAddGetReplaceRemove) {
    World w;
    const Entity e = w.create();
    EXPECT_FALSE(w.has<Position>(e));
    w.emplace<Position>(e, Position{2.0});
    ASSERT_TRUE(w.has<Position>(e));
    EXPECT_EQ(w.get<Position>(e).x, 2.0);
    w.emplace<Position>(e, Position{3.0}); // replace in place
    EXPECT_EQ(w.get<Position>(e).x, 3.0);
    EXPECT_EQ(w.pool<Position>().size(), 1u);
    EXPECT_THROW(w.get<Velocity>(e), StaleEntityError);
    w.remove<Position>(e);
    EXPECT_FALSE(w.has<Position>(e));
    EXPECT_TRUE(w.alive(e));
}

TEST(World, PoolStaysPackedUnderSwapRemove) {
    World w;
    std::vector<Entity> es;
    for (int i = 0; i < 10; ++i) {
        es.push_back(w.create());
        w.emplace<Position>(es.back(), Position{double(i)});
    }
    w.destroy(es[0]);
    w.destroy(es[5]);
    w.remove<Position>(es[9]);
    const Pool<Position>& p = w.pool<Position>();
    ASSERT_EQ(p.size(), 7u);
    ASSERT_EQ(p.values().size(), p.entities().size());
    // every packed value still belongs to its owner
    for (std::size_t i = 0; i < p.size(); ++i) {
        const Entity owner = p.entities()[i];
        EXPECT_EQ(p.values()[i].x, double(owner.index));
        EXPECT_EQ(&w.get<Position>(owner), &p.values()[i]);
    }
}

TEST(World, ViewJoinsOneToThreeTypes) {
    World w;
    std::set<std::uint32_t> both, all3;
    for (int i = 0; i < 20; ++i) {
        const Entity e = w.create();
        w.emplace<Position>(e, Position{double(i)});
        if (i % 2 == 0) {
            w.emplace<Velocity>(e, Velocity{1.0});
            both.insert(e.index);
        }
        if (i % 4 == 0) {
            w.emplace<Tag>(e);
            all3.insert(e.index);
        }
    }
    EXPECT_EQ(w.view<Position>().count(), 20u);

    std::set<std::uint32_t> seen;
    w.view<Position, Velocity>().each([&](Entity e, Position& p, Velocity& v) {
        seen.insert(e.index);
        p.x += v.v;
    });
    EXPECT_EQ(seen, both);

    seen.clear();
    w.view<const Position, const Velocity, Tag>().each(
        [&](Entity e, const Position&, const Velocity&, Tag&) { seen.insert(e.index); });
    EXPECT_EQ(seen, all3);
}

TEST(World, ConstViewHandsOutConstReferences) {
    World w;
    const Entity e = w.create();
    w.emplace<Position>(e);
    w.view<const Position>().each([](Entity, auto& p) {
        static_assert(std::is_const_v<std::remove_reference_t<decltype(p)>>,
                      "a const view must be read-only");
    });
    w.view<Position>().each(
        [](Entity, auto& p) { static_assert(!std::is_const_v<std::remove_reference_t<decltype(p)>>); });
}

TEST(World, StructuralChangesDuringIterationAreRefused) {
    World w;
    const Entity e = w.create();
    w.emplace<Position>(e);
    w.view<Position>().each([&](Entity x, Position&) {
        EXPECT_THROW(w.destroy(x), WorldLockedError);
        EXPECT_THROW(w.emplace<Velocity>(x), WorldLockedError);
        EXPECT_THROW(w.remove<Position>(x), WorldLockedError);
    });
    // the lock is released after iteration
    EXPECT_NO_THROW(w.emplace<Velocity>(e));
}

TEST(World, CommandsAreAppliedInOrderAtFlush) {
    World w;
    std::vector<Entity> es;
    for (int i = 0; i < 5; ++i) {
        es.push_back(w.create());
        w.emplace<Position>(es.back(), Position{double(i)});
    }
    Entity spawned;
    w.view<Position>().each([&](Entity e, Position& p) {
        if (p.x == 1.0 || p.x == 3.0) {
            w.commands().destroy(e);
        }
        if (p.x == 2.0) {
            spawned = w.commands().spawn();
            w.commands().emplace(spawned, Position{42.0});
            w.commands().emplace(e, Velocity{7.0});
        }
    });
    // nothing structural happened yet, except that the spawned handle exists
    EXPECT_TRUE(w.alive(es[1]));
    EXPECT_TRUE(w.alive(spawned));
    EXPECT_FALSE(w.has<Position>(spawned));
    EXPECT_EQ(w.commands().pending(), 4u);

    w.commands().flush();
    EXPECT_FALSE(w.alive(es[1]));
    EXPECT_FALSE(w.alive(es[3]));
    EXPECT_EQ(w.get<Position>(spawned).x, 42.0);
    EXPECT_EQ(w.get<Velocity>(es[2]).v, 7.0);
    EXPECT_EQ(w.commands().pending(), 0u);
}

TEST(World, QueuedChangesToADestroyedEntityAreDropped) {
    World w;
    const Entity e = w.create();
    w.commands().destroy(e);
    w.commands().destroy(e); // twice: the second is a no-op
    w.commands().emplace(e, Position{1.0});
    EXPECT_NO_THROW(w.commands().flush());
    EXPECT_FALSE(w.alive(e));
}

TEST(World, MoveOnlyComponentsCanBeQueued) {
    World w;
    const Entity e = w.create();
    w.commands().emplace(e, std::make_unique<int>(5));
    w.commands().flush();
    EXPECT_EQ(*w.get<std::unique_ptr<int>>(e), 5);
}

TEST(World, EntitiesListIsInSlotOrder) {
    World w;
    const Entity a = w.create();
    const Entity b = w.create();
    const Entity c = w.create();
    w.destroy(b);
    const Entity d = w.create(); // reuses b's slot
    const std::vector<Entity> list = w.entities();
    ASSERT_EQ(list.size(), 3u);
    EXPECT_EQ(list[0], a);
    EXPECT_EQ(list[1], d);
    EXPECT_EQ(list[2], c);
}

TEST(World, ResourcesAreSingletonsByType) {
    World w;
    EXPECT_EQ(w.tryResource<Counter>(), nullptr);
    EXPECT_THROW(w.resource<Counter>(), std::logic_error);
    w.setResource<Counter>(Counter{3});
    w.resource<Counter>().n += 1;
    EXPECT_EQ(w.resource<Counter>().n, 4);
    w.setResource<Counter>(Counter{0}); // replaced, not duplicated
    EXPECT_EQ(w.resource<Counter>().n, 0);
}

} // namespace
} // namespace tumble
