// The run loop's pieces (app/run_loop.h): StopSignal's handlers, and what it puts back.

#include "app/run_loop.h"

#include <gtest/gtest.h>

#include <atomic>
#include <csignal>
#include <memory>

namespace tumble {
namespace {

std::atomic<int> g_caught{0};

extern "C" void countSignal(int) {
    g_caught.fetch_add(1);
}

/// The handler SIGINT has now.
void (*handlerOf(int signal))(int) {
    struct sigaction now {};
    ::sigaction(signal, nullptr, &now);
    return now.sa_handler;
}

// Two runs whose StopSignals overlap and end out of order (two Python threads each verifying a replay): a
// signal asks both to stop, and when both have ended the program's own handlers are back. Seen to fail
// with each StopSignal putting back what it found: the first to start ended first, and the second then put
// back what it had found, the first's, which is ours (Ctrl-C then never reached the program).
TEST(StopSignal, RunsThatOverlapPutBackTheProgramsHandlersWhicheverEndsLast) {
    struct sigaction own {
    }, before{}, beforeTerm{};
    own.sa_handler = countSignal;
    sigemptyset(&own.sa_mask);
    ::sigaction(SIGINT, &own, &before);
    ::sigaction(SIGTERM, &own, &beforeTerm);
    {
        auto first = std::make_unique<StopSignal>();
        const StopSignal second;
        EXPECT_NE(handlerOf(SIGINT), countSignal);
        EXPECT_FALSE(second.requested());
        std::raise(SIGINT);
        EXPECT_TRUE(first->requested());
        EXPECT_TRUE(second.requested());
        first.reset(); // the first to start ends first
        EXPECT_EQ(g_caught.load(), 0);
    }
    EXPECT_EQ(handlerOf(SIGINT), countSignal);
    EXPECT_EQ(handlerOf(SIGTERM), countSignal);
    std::raise(SIGINT);
    EXPECT_EQ(g_caught.load(), 1);
    // a run after them starts with no stop asked
    {
        const StopSignal later;
        EXPECT_FALSE(later.requested());
    }
    ::sigaction(SIGINT, &before, nullptr);
    ::sigaction(SIGTERM, &beforeTerm, nullptr);
}

} // namespace
} // namespace tumble
