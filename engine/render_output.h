#pragma once
// What a run asks of the renderer, as a world resource the command line fills: whether to draw at all,
// where PNG frames go and which frames to keep. The renderer (a system) reads it and lists what it wrote.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace tumble {

/// Rendering requests of a run, and what came of them.
struct RenderOutput {
    bool enabled = false;             ///< false: no GL context is made (--no-render)
    std::string directory;            ///< where frame_NNNNN.png files go
    std::uint64_t pngEvery = 0;       ///< write every K frames; 0: only the last frame
    std::uint64_t lastFrame = 0;      ///< the run's final frame number (always written)
    std::vector<std::string> written; ///< PNG files written so far
    std::string device;               ///< the GL version, renderer and EGL platform used
    /// When set, every rendered frame's pixels (RGBA, top row first) go here (the video encoder).
    std::function<void(const std::vector<std::uint8_t>& rgba)> video;
};

} // namespace tumble
