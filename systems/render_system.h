#pragma once
// The renderer: a frame-phase system that draws the world headlessly (app/gl_context.h) and writes PNG
// frames. It only reads components, so rendering never changes the simulation or its hash.
// Reads: SceneDef (camera, image size), RenderOutput, Transform, RigidBody, RigidBody2D, SpringNetwork,
// ParticleEmitter, Air, RenderHistory, PoseHistory. Writes: RenderOutput (the files written). Phase: frame;
// and, first in the fixed phase while rendering, `render_history`, which keeps each spring network's
// positions and each moving body's pose before the step (RenderHistory, PoseHistory), so that a frame
// falling between two steps is drawn between them (StepContext::alpha).
//
// What it draws: rigid bodies as lit meshes in their pose (a plane as a gridded ground; 2D bodies as slabs
// half a metre deep about their entity's z; hulls and meshes flat-shaded), cloth and soft bodies as
// lit surfaces with per-vertex normals (cloth two-sided), other spring networks (springs, ropes) as lines
// with their masses as small lit balls (instanced), and particles as round, blended camera-facing quads
// (instanced) sized in metres and coloured over their life; water see-through after everything opaque and
// the sky gradient. The key light (from above and behind the camera unless [render] light_direction says)
// casts shadows through a shadow map; ambient light comes from the sky and the ground (a hemisphere);
// colours are lit in linear light and written as sRGB ([render] gamma).

#include "engine/catalog.h"
#include "engine/render_output.h"
#include "engine/scene.h"
#include "engine/step_context.h"
#include "engine/world.h"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace tumble {

/// Draws the world into the offscreen framebuffer, and writes a PNG when this frame is one to keep.
void renderWorld(World& world, const StepContext& ctx);

/// Reads back the last drawn image (RGBA, top row first); false if nothing was drawn yet.
bool lastImage(World& world, int& width, int& height, std::vector<std::uint8_t>& rgba);

/// Copies the last drawn image into the current context's window (framebuffer 0) of width x height pixels;
/// false if nothing was drawn yet.
bool presentImage(World& world, int width, int height);

/// The camera's view-projection matrix (column-major), as the renderer uses it: the scene's camera and image
/// size, or the output's when it sets them.
std::array<float, 16> viewProjection(const SceneDef& scene, const RenderOutput* output = nullptr);

/// Keeps each spring network's positions and each moving body's pose before the step (the
/// `render_history` system, first in the fixed phase while rendering).
void rememberPositions(World& world, const StepContext& ctx);

/// The GL objects the renderer keeps between frames (a world resource, private to it).
struct Renderer;

// ---- the GL helpers the renderer draws with (and the viewer and the render benchmark with it)

/// An offscreen RGBA8 colour + depth framebuffer.
class Framebuffer {
public:
    /// `samples` above 1: colour and depth multisampled (as many samples as asked, at most the GL's
    /// GL_MAX_SAMPLES), resolved into a plain colour buffer whenever the image is read.
    Framebuffer(int width, int height, int samples = 1);
    ~Framebuffer();
    Framebuffer(const Framebuffer&) = delete;
    Framebuffer& operator=(const Framebuffer&) = delete;

    /// Binds it for drawing, with its viewport.
    void bind() const;
    /// The framebuffer drawn into (multisampled when samples() > 1).
    unsigned id() const { return m_fbo; }
    int width() const { return m_width; }
    int height() const { return m_height; }
    int samples() const { return m_samples; }
    /// A single-sampled framebuffer holding what was drawn: the multisampled one resolved into its own
    /// colour buffer (each pixel the mean of its samples), or the one drawn into when it has one sample.
    unsigned resolved() const;
    /// The pixels, RGBA, top row first (resolved).
    void read(std::vector<std::uint8_t>& rgba) const;

private:
    /// Deletes whatever GL objects were made (names of 0 are skipped by GL).
    void release();

    int m_width;
    int m_height;
    int m_samples = 1;
    unsigned m_fbo = 0;
    unsigned m_color = 0;
    unsigned m_depth = 0;
    unsigned m_resolveFbo = 0; ///< with samples() > 1: the resolved colour's framebuffer
    unsigned m_resolveColor = 0;
};

/// Compiles and links a program; throws std::runtime_error with the GL log on failure.
unsigned compileProgram(const std::string& vertexSource, const std::string& fragmentSource,
                        const std::string& name);

/// The shader assets/shaders/`file` with `text` (lines of #define, say) put in after its #version line.
std::string withDefines(const std::string& file, const std::string& text);

/// The shader assets/shaders/`file` with `defines` (lines of #define: GAMMA, SHADOWS, WATER) and look.glsl
/// (colour spaces, the sky) put in after its #version line, as the mesh program's fragment shader and the
/// sky's vertex shader take it.
std::string withLook(const std::string& file, const std::string& defines = "");

/// Writes RGBA pixels (top row first) as a PNG; throws std::runtime_error on failure.
void writePng(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgba);

} // namespace tumble
