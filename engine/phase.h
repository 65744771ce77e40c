#pragma once
// The three phases of a frame, in the order the schedule runs them.

#include <cstdint>
#include <string_view>

namespace tumble {

/// input: events and replays; fixed: everything that advances physics (once per fixed step);
/// frame: interpolation, render and outputs (once per frame).
enum class Phase : std::uint8_t { Input, Fixed, Frame };

constexpr std::string_view phaseName(Phase p) {
    switch (p) {
    case Phase::Input:
        return "input";
    case Phase::Fixed:
        return "fixed";
    case Phase::Frame:
        return "frame";
    }
    return "?";
}

} // namespace tumble
