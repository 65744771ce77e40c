#pragma once
// What a run asks of the renderer, as a world resource the command line fills: whether to draw at all,
// where PNG frames go and which frames to keep. The renderer (a system) reads it and lists what it wrote.

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace tumble {

/// A GL context a run opens for the renderer (app/gl_context.h's headless one), open while held. Several
/// may be open in one thread, a simulation's each: the renderer makes its own current before it draws,
/// reads back or frees anything.
class RenderContext {
public:
    virtual ~RenderContext() = default;
    /// Makes it the calling thread's current context (nothing to do when it is already).
    virtual void makeCurrent() = 0;
};

/// Rendering requests of a run, and what came of them.
struct RenderOutput {
    bool enabled = false;             ///< false: no GL context is made (--no-render)
    std::string directory;            ///< where frame_NNNNN.png files go
    std::uint64_t pngEvery = 0;       ///< write every K frames; 0: only the last frame
    std::uint64_t lastFrame = 0;      ///< the run's final frame number (always written)
    std::vector<std::string> written; ///< PNG files written so far
    std::string device;               ///< the GL version, renderer and EGL platform used
    // a live window (tumble view) asks for more: its own GL context, its size and camera, and wireframe
    bool externalContext = false; ///< a GL ES 3 context is already current: draw with it, make none
    /// Otherwise the renderer opens one with this on its first frame (the run's choice: app/gl_context.h's
    /// headless EGL context); it fills the device description and keeps the context open while held.
    std::function<std::shared_ptr<RenderContext>(std::string& device)> openContext;
    int width = 0, height = 0; ///< the image size; 0: the scene's [render] size
    bool cameraSet = false;    ///< eye and target below replace the scene's camera
    std::array<double, 3> eye{}, target{};
    bool wireframe = false; ///< spring networks as springs and masses, cloth included
    bool keepFrames = true; ///< false: never write PNG frames (the window shows them)
    /// When set, every rendered frame's pixels (RGBA, top row first) go here (the video encoder).
    std::function<void(const std::vector<std::uint8_t>& rgba)> video;
};

} // namespace tumble
