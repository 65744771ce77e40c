#pragma once
// Headless OpenGL ES 3 through EGL, with no window: on a machine with a GPU the device platform
// (EGL_EXT_platform_device), elsewhere Mesa's surfaceless platform (llvmpipe, on the CPU). Drawing goes
// into an offscreen framebuffer whose pixels are read back for PNG frames. When no EGL display can be had,
// construction throws RenderUnavailable with a message that suggests --no-render.

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace tumble {

/// No headless GL could be set up here.
struct RenderUnavailable : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// An EGL display and a current OpenGL ES 3 context with no surface.
class GlContext {
public:
    GlContext();
    ~GlContext();
    GlContext(const GlContext&) = delete;
    GlContext& operator=(const GlContext&) = delete;

    /// "OpenGL ES 3.2 Mesa ... | llvmpipe ..." and the EGL platform used.
    const std::string& description() const { return m_description; }

private:
    void* m_display = nullptr;
    void* m_context = nullptr;
    std::string m_description;
};

/// An offscreen RGBA8 colour + depth framebuffer.
class Framebuffer {
public:
    Framebuffer(int width, int height);
    ~Framebuffer();
    Framebuffer(const Framebuffer&) = delete;
    Framebuffer& operator=(const Framebuffer&) = delete;

    void bind() const;
    unsigned id() const { return m_fbo; }
    int width() const { return m_width; }
    int height() const { return m_height; }
    /// The pixels, RGBA, top row first.
    void read(std::vector<std::uint8_t>& rgba) const;

private:
    int m_width;
    int m_height;
    unsigned m_fbo = 0;
    unsigned m_color = 0;
    unsigned m_depth = 0;
};

/// Compiles and links a program; throws std::runtime_error with the GL log on failure.
unsigned compileProgram(const std::string& vertexSource, const std::string& fragmentSource,
                        const std::string& name);

/// Writes RGBA pixels (top row first) as a PNG; throws std::runtime_error on failure.
void writePng(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgba);

/// The folder that holds shaders and meshes: $TUMBLE_ASSETS, else assets/ beside or above the executable,
/// else the source tree's assets/.
std::string assetDirectory();

} // namespace tumble
