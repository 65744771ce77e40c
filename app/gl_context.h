#pragma once
// Headless OpenGL ES 3 through EGL, with no window: on a machine with a GPU the device platform
// (EGL_EXT_platform_device), elsewhere Mesa's surfaceless platform (llvmpipe, on the CPU). Drawing goes
// into the renderer's offscreen framebuffer (systems/render_system.h), whose pixels are read back for PNG
// frames. When no EGL display can be had, construction throws RenderUnavailable with a message that
// suggests --no-render.

#include "engine/render_output.h"

#include <memory>
#include <stdexcept>
#include <string>

namespace tumble {

/// No headless GL could be set up here.
struct RenderUnavailable : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// An EGL display and an OpenGL ES 3 context with no surface, current once made.
class GlContext : public RenderContext {
public:
    GlContext();
    ~GlContext() override;
    GlContext(const GlContext&) = delete;
    GlContext& operator=(const GlContext&) = delete;

    /// "OpenGL ES 3.2 Mesa ... | llvmpipe ..." and the EGL platform used.
    const std::string& description() const { return m_description; }
    /// Makes it current again (another context may have been made current since, in this thread).
    void makeCurrent() override;

private:
    void* m_display = nullptr;
    void* m_context = nullptr;
    std::string m_description;
};

/// Opens a headless context (GlContext) and makes it current; `device` gets its description. The holder
/// keeps it open: this is what a run hands the renderer as RenderOutput::openContext.
std::shared_ptr<RenderContext> openHeadlessContext(std::string& device);

} // namespace tumble
