#pragma once
// Tumble as a library (CONTRACT.md, "Embedding"): one scenario running in one world, stepped by the caller.
// This header is the whole public C++ API; it needs nothing but the standard library and tumble/errors.h,
// and links as the target tumble::tumble (`find_package(tumble CONFIG)`).
//
//     tumble::Sandbox sim("rope", {"scene.dt=0.01"}, 1); // a demo's name or a .toml path; throws
//     sim.step(60);                                      // frames, each exactly the scene's substeps
//     std::uint64_t h = sim.hash();                      // the dump's "hash" of this frame
//
// Results are bit-identical to `tumble run` with the same scenario and overrides, for any thread count:
// a Sandbox stepped 60 frames has the state `tumble run SCENARIO --frames 60` ends with.

#include "tumble/errors.h"

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace tumble {

/// One scenario in one world; see the header comment. Not copyable; movable (a moved-from Sandbox throws
/// std::logic_error from every call). One thread at a time: a Sandbox is not locked (its steps use the
/// worker threads it was given; the Python module locks each Sandbox itself).
class Sandbox {
public:
    /// Loads a demo (by name) or a scenario file, with `--set` overrides ("KEY=VALUE"), stepping on
    /// `threads` threads (0: $TUMBLE_THREADS, else every hardware thread; else 1 to 256). Throws
    /// ScenarioError with the command line's message for bad input, std::invalid_argument for a thread
    /// count out of range.
    explicit Sandbox(const std::string& scenario, const std::vector<std::string>& sets = {}, int threads = 0);
    ~Sandbox();
    Sandbox(Sandbox&&) noexcept;
    Sandbox& operator=(Sandbox&&) noexcept;
    Sandbox(const Sandbox&) = delete;
    Sandbox& operator=(const Sandbox&) = delete;

    /// Runs `frames` frames (each the scene's `substeps` fixed steps), applying the scenario's events and
    /// those given to apply() as they fall due. Problems met on the way (a network that blew up) are in
    /// failures(), as the command line would print them. Throws std::invalid_argument if frames < 0.
    void step(int frames = 1);

    std::uint64_t frame() const; ///< frames run
    double time() const;         ///< simulated time, s
    double dt() const;           ///< the fixed step, s

    /// Every named entity whose state the dump lists, and its kind as the dump names it ("springs",
    /// "particles", "rigid", "rigid2d", "water", "air", "fem", ...; kinds of several components '+'-joined).
    std::map<std::string, std::string> entities() const;

    /// An entity's positions and velocities as the dump lists them (a mass, node, particle or body per
    /// row; a 2D body's rows have z = 0). Throws ScenarioError for an unknown entity or one without them.
    std::vector<std::array<double, 3>> x(const std::string& entity) const;
    std::vector<std::array<double, 3>> v(const std::string& entity) const;
    /// 3, or 2 for a 2D body (its rows' z is 0).
    int dimensions(const std::string& entity) const;

    /// Applies one of the scenario's actions (as an [[event]] or a line of --input) at the start of the
    /// next step: impulse, set_velocity, push, disturb, emit, ... `value` is the action's number(s),
    /// `position` (and `radius`, `amount`) as the action takes them. Throws ScenarioError when the entity,
    /// the action or its values do not fit, with the message an [[event]] would get (every number finite
    /// and within +-1e9, at most 4096 of them in `value`, as --input takes them).
    void apply(const std::string& entity, const std::string& action, const std::vector<double>& value = {},
               std::optional<std::array<double, 3>> position = std::nullopt,
               std::optional<double> radius = std::nullopt, std::optional<double> amount = std::nullopt);
    /// Applies a `set` event: KEY=VALUE as --set takes it, at the start of the next step.
    void set(const std::string& keyValue);

    /// The 64-bit state hash of this frame (the dump's "hash"; a replay's per-frame hash).
    std::uint64_t hash() const;
    /// This frame's state as one dump line (JSON, CONTRACT.md "State dump"), without the line break.
    std::string dump() const;
    /// The budget summary so far (JSON, CONTRACT.md "Budget summary").
    std::string profile() const;
    /// Messages of problems met while stepping (a blow-up), in order.
    std::vector<std::string> failures() const;

    /// Records a replay to `path` from here on: only before the first step (a replay starts at frame 0).
    /// Every step() after writes its frames; the file is finished when the Sandbox is destroyed or
    /// finishRecording() is called. Throws ScenarioError if steps have run or a recording is already under
    /// way (finish it first), std::runtime_error if the file cannot be written.
    void record(const std::string& path);
    void finishRecording();

private:
    struct State;
    std::unique_ptr<State> m;
    State& live() const; ///< *m, or std::logic_error for a moved-from Sandbox
};

/// Replays a replay file and compares every frame's state hash with the recording, as `tumble replay FILE
/// --verify` does: returns an empty string when every frame matches, else what diverged first (frame,
/// entity, kind of state; or that its run stopped early), printing no verdict. Throws ReplayError for a
/// file that cannot be read, std::invalid_argument for `threads` out of range. Runs on `threads` threads
/// (0 as for Sandbox). A failure the recording met too (a blow-up) is not a divergence; an interrupt
/// (SIGINT or SIGTERM, whose handlers are put back after) is, as "stopped before its end".
std::string verifyReplay(const std::string& path, int threads = 0);

} // namespace tumble
