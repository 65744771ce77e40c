#include "systems/render_system.h"

#include "components/particles.h"
#include "components/render_history.h"
#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "components/spring_network.h"
#include "components/water.h"
#include "engine/assets.h"
#include "engine/parallel.h"
#include "engine/render_output.h"
#include "engine/scene.h"
#include "engine/transform.h"
#include "systems/render_air.h"

#include <Eigen/Dense>
#include <GLES3/gl3.h>
#include <stb/stb_image_write.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <sstream>
#include <tuple>

namespace tumble {

namespace {

/// A renderbuffer of `format`, multisampled when samples > 1, attached to the bound framebuffer.
unsigned attachRenderbuffer(GLenum format, GLenum attachment, int width, int height, int samples) {
    GLuint id = 0;
    glGenRenderbuffers(1, &id);
    glBindRenderbuffer(GL_RENDERBUFFER, id);
    if (samples > 1) {
        glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, format, width, height);
    } else {
        glRenderbufferStorage(GL_RENDERBUFFER, format, width, height);
    }
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, attachment, GL_RENDERBUFFER, id);
    return id;
}

void checkComplete(int width, int height, int samples) {
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
        throw std::runtime_error("the offscreen framebuffer is incomplete (" + std::to_string(width) + " x " +
                                 std::to_string(height) + ", " + std::to_string(samples) + " samples)");
    }
}

} // namespace

Framebuffer::Framebuffer(int width, int height, int samples) : m_width(width), m_height(height) {
    GLint most = 1;
    glGetIntegerv(GL_MAX_SAMPLES, &most);
    m_samples = std::max(1, std::min(samples, int(most)));
    try {
        glGenFramebuffers(1, &m_fbo);
        glBindFramebuffer(GL_FRAMEBUFFER, m_fbo);
        m_color = attachRenderbuffer(GL_RGBA8, GL_COLOR_ATTACHMENT0, width, height, m_samples);
        m_depth = attachRenderbuffer(GL_DEPTH_COMPONENT24, GL_DEPTH_ATTACHMENT, width, height, m_samples);
        checkComplete(width, height, m_samples);
        if (m_samples > 1) {
            glGenFramebuffers(1, &m_resolveFbo);
            glBindFramebuffer(GL_FRAMEBUFFER, m_resolveFbo);
            m_resolveColor = attachRenderbuffer(GL_RGBA8, GL_COLOR_ATTACHMENT0, width, height, 1);
            checkComplete(width, height, 1);
        }
    } catch (...) {
        release(); // no destructor runs for an object whose constructor throws
        throw;
    }
}

Framebuffer::~Framebuffer() {
    release();
}

void Framebuffer::release() {
    glDeleteRenderbuffers(1, &m_depth);
    glDeleteRenderbuffers(1, &m_color);
    glDeleteFramebuffers(1, &m_fbo);
    if (m_resolveFbo) {
        glDeleteRenderbuffers(1, &m_resolveColor);
        glDeleteFramebuffers(1, &m_resolveFbo);
    }
}

void Framebuffer::bind() const {
    glBindFramebuffer(GL_FRAMEBUFFER, m_fbo);
    glViewport(0, 0, m_width, m_height);
}

unsigned Framebuffer::resolved() const {
    if (m_samples <= 1) {
        return m_fbo;
    }
    glBindFramebuffer(GL_READ_FRAMEBUFFER, m_fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, m_resolveFbo);
    glBlitFramebuffer(0, 0, m_width, m_height, 0, 0, m_width, m_height, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    return m_resolveFbo;
}

void Framebuffer::read(std::vector<std::uint8_t>& rgba) const {
    glBindFramebuffer(GL_FRAMEBUFFER, resolved());
    const std::size_t row = std::size_t(m_width) * 4;
    rgba.resize(row * std::size_t(m_height));
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, m_width, m_height, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
    // GL's rows run bottom-up; images run top-down
    for (int y = 0; y < m_height / 2; ++y) {
        std::uint8_t* a = rgba.data() + std::size_t(y) * row;
        std::swap_ranges(a, a + row, rgba.data() + std::size_t(m_height - 1 - y) * row);
    }
}

unsigned compileProgram(const std::string& vertexSource, const std::string& fragmentSource,
                        const std::string& name) {
    auto compile = [&](GLenum kind, const std::string& source) {
        const GLuint shader = glCreateShader(kind);
        const char* text = source.c_str();
        glShaderSource(shader, 1, &text, nullptr);
        glCompileShader(shader);
        GLint ok = 0;
        glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
        if (!ok) {
            char log[2048];
            glGetShaderInfoLog(shader, sizeof log, nullptr, log);
            throw std::runtime_error("shader " + name + (kind == GL_VERTEX_SHADER ? ".vert" : ".frag") +
                                     " does not compile: " + log);
        }
        return shader;
    };
    const GLuint vs = compile(GL_VERTEX_SHADER, vertexSource),
                 fs = compile(GL_FRAGMENT_SHADER, fragmentSource);
    const GLuint program = glCreateProgram();
    glAttachShader(program, vs);
    glAttachShader(program, fs);
    glLinkProgram(program);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = 0;
    glGetProgramiv(program, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[2048];
        glGetProgramInfoLog(program, sizeof log, nullptr, log);
        throw std::runtime_error("shader program " + name + " does not link: " + log);
    }
    return program;
}

void writePng(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgba) {
    namespace fs = std::filesystem;
    const fs::path p(path);
    if (p.has_parent_path()) {
        std::error_code ec;
        fs::create_directories(p.parent_path(), ec);
    }
    if (!stbi_write_png(path.c_str(), width, height, 4, rgba.data(), width * 4)) {
        throw std::runtime_error("cannot write " + path);
    }
}

namespace {

using Mat4 = std::array<float, 16>; // column-major, as GL takes it

Mat4 multiply(const Mat4& a, const Mat4& b) {
    Mat4 r{};
    for (int c = 0; c < 4; ++c) {
        for (int row = 0; row < 4; ++row) {
            float s = 0.0f;
            for (int k = 0; k < 4; ++k) {
                s += a[std::size_t(k * 4 + row)] * b[std::size_t(c * 4 + k)];
            }
            r[std::size_t(c * 4 + row)] = s;
        }
    }
    return r;
}

Mat4 lookAt(const Vec3& eye, const Vec3& target) {
    Vec3 f = target - eye;
    f = f * (1.0 / length(f));
    Vec3 up{0.0, 1.0, 0.0};
    if (std::abs(dot(f, up)) > 0.999) {
        up = {0.0, 0.0, -1.0};
    }
    Vec3 s = cross(f, up);
    s = s * (1.0 / length(s));
    const Vec3 u = cross(s, f);
    return {float(s.x),          float(u.x),          float(-f.x),        0.0f,
            float(s.y),          float(u.y),          float(-f.y),        0.0f,
            float(s.z),          float(u.z),          float(-f.z),        0.0f,
            float(-dot(s, eye)), float(-dot(u, eye)), float(dot(f, eye)), 1.0f};
}

Mat4 perspective(double fovDeg, double aspect, double nearPlane, double farPlane) {
    const double f = 1.0 / std::tan(fovDeg * std::numbers::pi / 360.0);
    Mat4 m{};
    m[0] = float(f / aspect);
    m[5] = float(f);
    m[10] = float((farPlane + nearPlane) / (nearPlane - farPlane));
    m[11] = -1.0f;
    m[14] = float(2.0 * farPlane * nearPlane / (nearPlane - farPlane));
    return m;
}

/// An orthographic projection of the box [x0, x1] x [y0, y1] x [-far, -near] of the view's frame.
Mat4 orthographic(double x0, double x1, double y0, double y1, double nearPlane, double farPlane) {
    Mat4 m{};
    m[0] = float(2.0 / (x1 - x0));
    m[5] = float(2.0 / (y1 - y0));
    m[10] = float(-2.0 / (farPlane - nearPlane));
    m[12] = float(-(x1 + x0) / (x1 - x0));
    m[13] = float(-(y1 + y0) / (y1 - y0));
    m[14] = float(-(farPlane + nearPlane) / (farPlane - nearPlane));
    m[15] = 1.0f;
    return m;
}

/// Translation, then a per-axis scale (and, for planes, a basis whose y is the normal).
Mat4 model(const Vec3& at, const Vec3& scale, const Vec3& xAxis = {1, 0, 0}, const Vec3& yAxis = {0, 1, 0},
           const Vec3& zAxis = {0, 0, 1}) {
    return {float(xAxis.x * scale.x),
            float(xAxis.y * scale.x),
            float(xAxis.z * scale.x),
            0.0f,
            float(yAxis.x * scale.y),
            float(yAxis.y * scale.y),
            float(yAxis.z * scale.y),
            0.0f,
            float(zAxis.x * scale.z),
            float(zAxis.y * scale.z),
            float(zAxis.z * scale.z),
            0.0f,
            float(at.x),
            float(at.y),
            float(at.z),
            1.0f};
}

std::string readText(const std::string& path) {
    std::ifstream in(path);
    if (!in) {
        throw std::runtime_error("cannot read the shader " + path +
                                 " (set TUMBLE_ASSETS to the assets folder)");
    }
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

} // namespace

std::string withDefines(const std::string& file, const std::string& text) {
    const std::string source = readText(assetDirectory() + "/shaders/" + file);
    const std::size_t line = source.find('\n');
    if (line == std::string::npos) {
        return source + "\n" + text;
    }
    return source.substr(0, line + 1) + text + source.substr(line + 1);
}

std::string withLook(const std::string& file, const std::string& defines) {
    return withDefines(file, defines + readText(assetDirectory() + "/shaders/look.glsl"));
}

namespace {

/// A static mesh on the GPU: interleaved position and normal, drawn as triangles.
struct Mesh {
    GLuint vao = 0, vbo = 0;
    GLsizei vertices = 0;
};

/// A vertex array over a new buffer of interleaved positions and normals (attributes 0 and 1), left bound.
void makePositionNormalArray(GLuint& vao, GLuint& vbo) {
    glGenVertexArrays(1, &vao);
    glGenBuffers(1, &vbo);
    glBindVertexArray(vao);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), nullptr);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float),
                          reinterpret_cast<void*>(3 * sizeof(float)));
}

/// Turns each triangle of `positionNormal` (six floats a corner: position, normal; three corners a
/// triangle) to wind counter-clockwise seen from the side its corners' normals point to: from outside, for
/// a closed shape, so that its back faces can be culled. A degenerate triangle is left as it is.
void windOutward(std::vector<float>& positionNormal) {
    for (std::size_t t = 0; t + 18 <= positionNormal.size(); t += 18) {
        const float* v = positionNormal.data() + t;
        const Vec3 a{v[0], v[1], v[2]}, b{v[6], v[7], v[8]}, c{v[12], v[13], v[14]};
        const Vec3 n{v[3] + v[9] + v[15], v[4] + v[10] + v[16], v[5] + v[11] + v[17]};
        if (dot(cross(b - a, c - a), n) < 0.0) {
            std::swap_ranges(positionNormal.begin() + std::ptrdiff_t(t + 6),
                             positionNormal.begin() + std::ptrdiff_t(t + 12),
                             positionNormal.begin() + std::ptrdiff_t(t + 12));
        }
    }
}

Mesh upload(std::vector<float> positionNormal) {
    windOutward(positionNormal);
    Mesh m;
    makePositionNormalArray(m.vao, m.vbo);
    glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(positionNormal.size() * sizeof(float)), positionNormal.data(),
                 GL_STATIC_DRAW);
    m.vertices = GLsizei(positionNormal.size() / 6);
    return m;
}

void pushVertex(std::vector<float>& out, const Vec3& p, const Vec3& n) {
    out.insert(out.end(), {float(p.x), float(p.y), float(p.z), float(n.x), float(n.y), float(n.z)});
}

/// Writes a vertex (position and normal) at `out`, six floats.
void putVertex(float* out, const Vec3& p, const Vec3& n) {
    const float v[6] = {float(p.x), float(p.y), float(p.z), float(n.x), float(n.y), float(n.z)};
    std::copy(v, v + 6, out);
}

/// Items per chunk when the renderer streams vertices over threads (each chunk writes its own vertices).
constexpr std::size_t kVertexGrain = 8192;

/// A unit sphere (radius 1) from latitude-longitude quads.
std::vector<float> sphereMesh(int slices = 32, int stacks = 16) {
    std::vector<float> out;
    auto at = [&](int i, int j) {
        const double theta = std::numbers::pi * j / stacks, phi = 2.0 * std::numbers::pi * i / slices;
        return Vec3{std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)};
    };
    for (int j = 0; j < stacks; ++j) {
        for (int i = 0; i < slices; ++i) {
            const Vec3 a = at(i, j), b = at(i + 1, j), c = at(i + 1, j + 1), d = at(i, j + 1);
            for (const Vec3& p : {a, c, b, a, d, c}) {
                pushVertex(out, p, p);
            }
        }
    }
    return out;
}

/// A unit cube (half extents 1).
std::vector<float> cubeMesh() {
    std::vector<float> out;
    for (int axis = 0; axis < 3; ++axis) {
        for (double sign : {-1.0, 1.0}) {
            Vec3 n, u, v;
            (axis == 0 ? n.x : axis == 1 ? n.y : n.z) = sign;
            (axis == 0 ? u.y : axis == 1 ? u.z : u.x) = 1.0;
            v = cross(n, u);
            const Vec3 c = n;
            const Vec3 p[4] = {c - u - v, c + u - v, c + u + v, c - u + v};
            for (int k : {0, 1, 2, 0, 2, 3}) {
                pushVertex(out, p[k], n);
            }
        }
    }
    return out;
}

/// A unit cylinder: radius 1, from y = -1 to 1, with caps.
std::vector<float> cylinderMesh(int slices = 32) {
    std::vector<float> out;
    for (int i = 0; i < slices; ++i) {
        const double a = 2.0 * std::numbers::pi * i / slices, b = 2.0 * std::numbers::pi * (i + 1) / slices;
        const Vec3 na{std::cos(a), 0, std::sin(a)}, nb{std::cos(b), 0, std::sin(b)};
        const Vec3 up{0, 1, 0};
        for (const auto& [p, n] : {std::pair{na - up, na}, std::pair{nb + up, nb}, std::pair{nb - up, nb},
                                   std::pair{na - up, na}, std::pair{na + up, na}, std::pair{nb + up, nb}}) {
            pushVertex(out, p, n);
        }
        for (double s : {-1.0, 1.0}) {
            const Vec3 c{0, s, 0};
            for (const Vec3& p : {c, na + c, nb + c}) {
                pushVertex(out, p, c);
            }
        }
    }
    return out;
}

} // namespace

/// Everything GL the renderer keeps between frames.
struct Renderer {
    /// the headless context the run opened for us (none in a window), made current before each use: other
    /// simulations in this thread may have made theirs current since
    std::shared_ptr<RenderContext> context;
    std::unique_ptr<Framebuffer> target;
    GLuint meshProgram = 0, flatProgram = 0, particleProgram = 0;
    GLuint depthProgram = 0; ///< mesh.vert with a fragment shader that writes nothing: the shadow map's pass
    GLuint skyProgram = 0;   ///< the sky gradient: its texture, filtered
    GLuint skyTexelsProgram = 0; ///< the sky's texture: the gradient at the centre of every 4 x 4 pixels
    /// look.glsl's uniforms in the mesh and sky programs
    struct LookUniforms {
        GLint zenith = -1, horizon = -1, nadir = -1;
    } meshLook, skyLook;
    struct {
        GLint inverseViewProjection = -1, eye = -1, texelToNdc = -1; ///< the texels' program
        GLint texture = -1, pixelToUv = -1;                          ///< the sky's program
    } sky;
    /// The sky's texture (a texel for every 4 x 4 pixels of the target), its framebuffer, its size in
    /// texels, and what it was last drawn for (the camera, the look and the target's size): drawn again
    /// only when one of those changes.
    GLuint skyTexture = 0, skyFbo = 0;
    int skyWidth = 0, skyHeight = 0;
    /// (the inverse view-projection, 16 floats; the eye and the look's three colours, 12; the size, 2)
    std::optional<std::array<float, 30>> skyDrawnFor;
    /// Uniform locations, looked up once when the programs are linked.
    struct MeshUniforms {
        GLint viewProjection = -1, model = -1, colour = -1, lightDir = -1, eye = -1;
        GLint key = -1, skyLight = -1, groundLight = -1;
    } mesh;
    MeshUniforms depth; ///< the depth program's (only its matrices exist there: the others are -1)
    GLint flatViewProjection = -1;
    struct {
        GLint viewProjection = -1, right = -1, up = -1;
    } particle;
    /// The key light's shadow map (made at the first frame that has a caster) and the mesh program's
    /// uniforms that read it.
    GLuint shadowFbo = 0, shadowMap = 0;
    struct ShadowUniforms {
        GLint map = -1, lightViewProjection = -1;
    } shadow;
    /// mesh.frag compiled for water or a ground plane: a program and its uniforms, swapped with the mesh
    /// program's to draw
    struct LitProgram {
        GLuint id = 0;
        MeshUniforms mesh;
        ShadowUniforms shadow;
        LookUniforms look;
        /// a ground program's colours (mesh.frag's GROUND): lit, in shadow, and the written colour's
        /// quadratic in the grid's cover
        struct {
            GLint lit = -1, shade = -1, cover0 = -1, cover1 = -1, cover2 = -1;
        } ground;
    };
    LitProgram water;
    /// Ground planes (with their grid): `ground` where the shadow map reaches (with its lookups when the
    /// scene has shadows), `groundOffMap` beyond it, where every lookup would read lit (no SHADOWS)
    LitProgram ground, groundOffMap;
    Mesh sphere, cube, cylinder;
    Mesh ball;                ///< a coarse sphere, drawn once per mass (instanced)
    GLuint ballInstances = 0; ///< per mass: offset and radius
    GLuint clothVao = 0, clothVbo = 0, flatVao = 0, flatVbo = 0;
    GLuint groundVao = 0, groundVbo = 0;     ///< a ground plane's cells (position + normal), made per draw
    GLuint skyVao = 0;                       ///< no attributes: the sky's triangle comes from gl_VertexID
    GLuint particleVao = 0, particleVbo = 0; ///< per particle: centre, colour, size (instanced quads)
    std::vector<float> instances;            ///< scratch: ball instances
    std::vector<float> clothVertices;        ///< scratch: position + normal per corner
    std::vector<float> groundVertices;       ///< scratch: a ground plane's cells, the shadow map's first
    std::vector<Vec3> normals;               ///< scratch: per-mass normals of a cloth
    std::vector<Vec3> positions;             ///< scratch: a network's masses between two steps
    std::vector<FlatVertex> flat;            ///< scratch: line vertices or particle instances
    std::vector<std::uint8_t> pixels;        ///< the last image read back
    std::map<const ShapeMesh*, Mesh> shapeMeshes; ///< convex hulls and meshes, uploaded once
    SmokePass smoke;                              ///< the air grids' smoke
    bool gamma =
        false; ///< lights in linear light (GAMMA compiled in): colours are decoded from sRGB when set
    bool drawn = false;
    bool live = false; ///< a context is current and the objects below were made in it

    /// Makes the context the objects below were made in current, when the run opened it for us (a
    /// window's is current already).
    void makeCurrent() const {
        if (context) {
            context->makeCurrent();
        }
    }

    Renderer() = default;
    Renderer(const Renderer&) = delete;
    Renderer& operator=(const Renderer&) = delete;
    /// Frees the GL objects while their context is current: a window's context (tumble view) outlives
    /// the simulations it draws, one after another on each reset. The target goes before the context.
    ~Renderer() {
        if (!live) {
            return; // no context was had: nothing was made
        }
        try {
            makeCurrent();
        } catch (const std::exception&) {
            // not freed in whichever context is current (names there are another's objects): they go with
            // their own context, and the target's wrapper is let go unfreed (a destructor must not throw)
            static_cast<void>(target.release());
            return;
        }
        target.reset();
        smoke.release();
        glDeleteTextures(1, &shadowMap);
        glDeleteFramebuffers(1, &shadowFbo);
        glDeleteTextures(1, &skyTexture);
        glDeleteFramebuffers(1, &skyFbo);
        for (GLuint program : {meshProgram, flatProgram, particleProgram, depthProgram, skyProgram,
                               skyTexelsProgram, water.id, ground.id, groundOffMap.id}) {
            glDeleteProgram(program);
        }
        std::vector<Mesh> meshes{sphere, cube, cylinder, ball};
        for (const auto& [shape, uploaded] : shapeMeshes) {
            meshes.push_back(uploaded);
        }
        for (const Mesh& m : meshes) {
            glDeleteBuffers(1, &m.vbo);
            glDeleteVertexArrays(1, &m.vao);
        }
        for (GLuint vao : {clothVao, flatVao, particleVao, skyVao, groundVao}) {
            glDeleteVertexArrays(1, &vao);
        }
        for (GLuint buffer : {ballInstances, clothVbo, flatVbo, particleVbo, groundVbo}) {
            glDeleteBuffers(1, &buffer);
        }
    }
};

namespace {

Renderer::LookUniforms lookUniforms(GLuint program) {
    return {glGetUniformLocation(program, "uZenith"), glGetUniformLocation(program, "uHorizon"),
            glGetUniformLocation(program, "uNadir")};
}

/// A program compiled from mesh.frag: its uniforms.
Renderer::LitProgram litProgram(GLuint program) {
    auto at = [&](const char* name) { return glGetUniformLocation(program, name); };
    return {program,
            {at("uViewProjection"), at("uModel"), at("uColor"), at("uLightDir"), at("uEye"), at("uKey"),
             at("uSkyLight"), at("uGroundLight")},
            {at("uShadowMap"), at("uLightViewProjection")},
            lookUniforms(program),
            {at("uGroundLit"), at("uGroundShade"), at("uCover0"), at("uCover1"), at("uCover2")}};
}

/// Puts `other` in the mesh program's place (the draws use r.meshProgram's uniforms), and back again.
void swapLit(Renderer& r, Renderer::LitProgram& other) {
    std::swap(r.meshProgram, other.id);
    std::swap(r.mesh, other.mesh);
    std::swap(r.shadow, other.shadow);
    std::swap(r.meshLook, other.look);
}

double srgbToLinear(double c) {
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

/// look.glsl's encode on the CPU: with gamma, a colour lit in linear light as written (the sRGB curve,
/// clamped to [0, 1]); without, as it is.
Vec3 encodeColour(const Vec3& c, bool gamma) {
    if (!gamma) {
        return c;
    }
    auto curve = [](double v) {
        v = std::clamp(v, 0.0, 1.0);
        return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
    };
    return {curve(c.x), curve(c.y), curve(c.z)};
}

/// The mesh program's colour (given in sRGB), in the space this frame lights in.
void setColour(const Renderer& r, const std::array<float, 4>& rgba) {
    std::array<float, 4> c = rgba;
    if (r.gamma) {
        for (int k = 0; k < 3; ++k) {
            c[k] = float(srgbToLinear(c[k]));
        }
    }
    glUniform4fv(r.mesh.colour, 1, c.data());
}

void setupFlatAttributes() {
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(FlatVertex), nullptr);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 4, GL_FLOAT, GL_FALSE, sizeof(FlatVertex),
                          reinterpret_cast<void*>(3 * sizeof(float)));
    glEnableVertexAttribArray(2);
    glVertexAttribPointer(2, 1, GL_FLOAT, GL_FALSE, sizeof(FlatVertex),
                          reinterpret_cast<void*>(7 * sizeof(float)));
}

Renderer& renderer(World& world, const SceneDef& scene, RenderOutput& output) {
    if (auto* r = world.tryResource<Renderer>()) {
        r->makeCurrent();
        return *r;
    }
    Renderer& r = world.setResource<Renderer>();
    if (output.externalContext) {
        output.device = std::string(reinterpret_cast<const char*>(glGetString(GL_VERSION))) + " | " +
                        reinterpret_cast<const char*>(glGetString(GL_RENDERER)) + " | a window's context";
    } else if (output.openContext) {
        r.context = output.openContext(output.device);
    } else {
        throw std::logic_error("renderer: rendering is on but the run gave neither a current GL context nor "
                               "RenderOutput::openContext");
    }
    r.live = true;
    r.target = std::make_unique<Framebuffer>(output.width > 0 ? output.width : scene.renderWidth,
                                             output.height > 0 ? output.height : scene.renderHeight,
                                             scene.renderSamples);
    const std::string shaders = assetDirectory() + "/shaders/";
    // the look's switch is compiled in (see look.glsl): a renderer draws one scene's look
    r.gamma = scene.renderGamma;
    const std::string gamma = r.gamma ? "#define GAMMA\n" : "";
    const std::string shadows = scene.renderShadows ? "#define SHADOWS\n" : "";
    const std::string vertex = withDefines("mesh.vert", shadows);
    r.meshProgram = compileProgram(vertex, withLook("mesh.frag", gamma + shadows), "mesh");
    r.water = litProgram(
        compileProgram(vertex, withLook("mesh.frag", gamma + shadows + "#define WATER\n"), "water"));
    r.ground = litProgram(
        compileProgram(vertex, withLook("mesh.frag", gamma + shadows + "#define GROUND\n"), "ground"));
    r.groundOffMap = litProgram(compileProgram(withDefines("mesh.vert", ""),
                                               withLook("mesh.frag", gamma + "#define GROUND\n"),
                                               "ground off the shadow map"));
    r.skyProgram = compileProgram(readText(shaders + "sky.vert"), readText(shaders + "sky.frag"), "sky");
    r.skyTexelsProgram =
        compileProgram(readText(shaders + "sky.vert"), withLook("sky_texels.frag", gamma), "sky texels");
    r.skyLook = lookUniforms(r.skyTexelsProgram);
    r.sky = {glGetUniformLocation(r.skyTexelsProgram, "uInverseViewProjection"),
             glGetUniformLocation(r.skyTexelsProgram, "uEye"),
             glGetUniformLocation(r.skyTexelsProgram, "uTexelToNdc"),
             glGetUniformLocation(r.skyProgram, "uSky"), glGetUniformLocation(r.skyProgram, "uPixelToUv")};
    glGenVertexArrays(1, &r.skyVao);
    r.flatProgram = compileProgram(readText(shaders + "flat.vert"), readText(shaders + "flat.frag"), "flat");
    r.depthProgram =
        compileProgram(readText(shaders + "mesh.vert"), readText(shaders + "depth.frag"), "depth");
    r.depth.viewProjection = glGetUniformLocation(r.depthProgram, "uViewProjection");
    r.depth.model = glGetUniformLocation(r.depthProgram, "uModel");
    r.sphere = upload(sphereMesh());
    r.cube = upload(cubeMesh());
    r.cylinder = upload(cylinderMesh());
    r.ball = upload(sphereMesh(12, 6));
    glBindVertexArray(r.ball.vao);
    glGenBuffers(1, &r.ballInstances);
    glBindBuffer(GL_ARRAY_BUFFER, r.ballInstances);
    glEnableVertexAttribArray(2);
    glVertexAttribPointer(2, 4, GL_FLOAT, GL_FALSE, 4 * sizeof(float), nullptr);
    glVertexAttribDivisor(2, 1);
    r.particleProgram =
        compileProgram(readText(shaders + "particle.vert"), readText(shaders + "particle.frag"), "particle");
    r.smoke.make(readText(shaders + "smoke.vert"), readText(shaders + "smoke.frag"));
    Renderer::LitProgram lit = litProgram(r.meshProgram);
    r.mesh = lit.mesh;
    r.shadow = lit.shadow;
    r.meshLook = lit.look;
    r.flatViewProjection = glGetUniformLocation(r.flatProgram, "uViewProjection");
    r.particle = {glGetUniformLocation(r.particleProgram, "uViewProjection"),
                  glGetUniformLocation(r.particleProgram, "uRight"),
                  glGetUniformLocation(r.particleProgram, "uUp")};
    glGenVertexArrays(1, &r.particleVao);
    glGenBuffers(1, &r.particleVbo);
    glBindVertexArray(r.particleVao);
    glBindBuffer(GL_ARRAY_BUFFER, r.particleVbo);
    setupFlatAttributes();
    for (GLuint a : {0u, 1u, 2u}) {
        glVertexAttribDivisor(a, 1);
    }
    makePositionNormalArray(r.clothVao, r.clothVbo);
    makePositionNormalArray(r.groundVao, r.groundVbo);
    glGenVertexArrays(1, &r.flatVao);
    glGenBuffers(1, &r.flatVbo);
    glBindVertexArray(r.flatVao);
    glBindBuffer(GL_ARRAY_BUFFER, r.flatVbo);
    setupFlatAttributes();
    return r;
}

/// Colour of the n-th drawn thing: a small fixed palette.
std::array<float, 4> palette(std::size_t n) {
    static const std::array<std::array<float, 4>, 6> colours = {{{0.85f, 0.33f, 0.25f, 1.0f},
                                                                 {0.25f, 0.55f, 0.85f, 1.0f},
                                                                 {0.95f, 0.75f, 0.25f, 1.0f},
                                                                 {0.40f, 0.75f, 0.40f, 1.0f},
                                                                 {0.70f, 0.45f, 0.80f, 1.0f},
                                                                 {0.90f, 0.55f, 0.35f, 1.0f}}};
    return colours[n % colours.size()];
}

/// Where a network's masses are drawn: between the positions before and after the last fixed step, at
/// `alpha` (1: after it, as headless runs draw every frame).
const std::vector<Vec3>& drawnPositions(const World& world, Entity e, const SpringNetwork& net, double alpha,
                                        std::vector<Vec3>& scratch, WorkerPool& pool) {
    const RenderHistory* history = world.tryGet<RenderHistory>(e);
    if (alpha >= 1.0 || !history || history->previous.size() != net.x.size()) {
        return net.x;
    }
    scratch.resize(net.x.size());
    pool.forEach(net.x.size(), kVertexGrain, [&](std::size_t i) {
        scratch[i] = history->previous[i] + (net.x[i] - history->previous[i]) * alpha;
    });
    return scratch;
}

/// A mesh for a convex hull or a static mesh, flat-shaded: uploaded once per mesh and kept.
const Mesh& shapeMesh(Renderer& r, const ShapeMesh& m) {
    auto found = r.shapeMeshes.find(&m);
    if (found != r.shapeMeshes.end()) {
        return found->second;
    }
    std::vector<float> triangles;
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
        for (std::uint32_t i : m.triangles[t]) {
            pushVertex(triangles, m.vertices[i], m.faceNormals[t]);
        }
    }
    return r.shapeMeshes.emplace(&m, upload(triangles)).first->second;
}

/// A 2D polygon extruded along z (half depth 1), flat-shaded; made for each draw (2D polygons are few).
std::vector<float> prismMesh(const std::vector<Vec2>& v) {
    std::vector<float> out;
    const std::size_t n = v.size();
    for (double z : {-1.0, 1.0}) {
        for (std::size_t k = 1; k + 1 < n; ++k) {
            for (std::size_t i : {std::size_t(0), k, k + 1}) {
                pushVertex(out, {v[i][0], v[i][1], z}, {0.0, 0.0, z});
            }
        }
    }
    for (std::size_t i = 0; i < n; ++i) {
        const Vec2& a = v[i];
        const Vec2& b = v[(i + 1) % n];
        Vec3 normal{b[1] - a[1], a[0] - b[0], 0.0};
        normal = normal * (1.0 / length(normal));
        const Vec3 p[4] = {{a[0], a[1], -1.0}, {b[0], b[1], -1.0}, {b[0], b[1], 1.0}, {a[0], a[1], 1.0}};
        for (int k : {0, 1, 2, 0, 2, 3}) {
            pushVertex(out, p[k], normal);
        }
    }
    return out;
}

/// A body's pose as drawn: between its pose before and after the last fixed step, at `alpha`.
void drawnPose(const World& world, Entity e, double alpha, Vec3& position, Quat& orientation) {
    const PoseHistory* before = alpha < 1.0 ? world.tryGet<PoseHistory>(e) : nullptr;
    if (!before) {
        return;
    }
    position = before->position + (position - before->position) * alpha;
    // normalised linear blend of the quaternions, taken the short way round
    const Quat& a = before->orientation;
    const double sign =
        a.x * orientation.x + a.y * orientation.y + a.z * orientation.z + a.w * orientation.w < 0.0 ? -1.0
                                                                                                    : 1.0;
    Quat q{a.x + (sign * orientation.x - a.x) * alpha, a.y + (sign * orientation.y - a.y) * alpha,
           a.z + (sign * orientation.z - a.z) * alpha, a.w + (sign * orientation.w - a.w) * alpha};
    const double n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    orientation = {q.x / n, q.y / n, q.z / n, q.w / n};
}

/// An edge is drawn 4 cm wide, to be seen (it collides as a 1 cm strip: components/rigid_body_2d.h).
constexpr double kEdgeDrawnHalfWidth = 0.02;

/// The rigid bodies, 3D and 2D, with the mesh program as it stands, but the ground planes (drawGround: they
/// cast no shadow, and are drawn after everything else opaque).
void drawColliders(World& world, Renderer& r, double alpha) {
    const GLint modelLoc = r.mesh.model;
    auto draw = [&](const Mesh& m, const Mat4& transform, const std::array<float, 4>& colour) {
        glUniformMatrix4fv(modelLoc, 1, GL_FALSE, transform.data());
        setColour(r, colour);
        glBindVertexArray(m.vao);
        glDrawArrays(GL_TRIANGLES, 0, m.vertices);
    };
    // a closed shape's back faces culled (its meshes are wound outward: windOutward): with multisampling
    // llvmpipe shades every fragment of a draw, hidden or not (neither its early depth test nor
    // layout(early_fragment_tests) spares one), so the back faces cost as much as the faces seen
    // (`tumble run avalanche`, render p50 with shadows and 4 samples: 25.6-27.8 -> 20.5-22.7 ms)
    glEnable(GL_CULL_FACE);
    world.view<const RigidBody>().each([&](Entity e, const RigidBody& body) {
        RigidBody b = body; // the pose as drawn
        drawnPose(world, e, alpha, b.position, b.orientation);
        const std::array<float, 4> stone{float(b.color.x), float(b.color.y), float(b.color.z), 1.0f};
        // the body's frame: its axes in world space
        const Vec3 ax = rotate(b.orientation, {1, 0, 0}), ay = rotate(b.orientation, {0, 1, 0}),
                   az = rotate(b.orientation, {0, 0, 1});
        auto placed = [&](const Vec3& at, const Vec3& scale) { return model(at, scale, ax, ay, az); };
        switch (b.shape) {
        case ShapeKind::Plane:
            break;
        case ShapeKind::Sphere:
            draw(r.sphere, placed(b.position, {b.radius, b.radius, b.radius}), stone);
            break;
        case ShapeKind::Box:
            draw(r.cube, placed(b.position, b.halfExtents), stone);
            break;
        case ShapeKind::Cylinder:
            draw(r.cylinder, placed(b.position, {b.radius, 0.5 * b.height, b.radius}), stone);
            break;
        case ShapeKind::Capsule:
            draw(r.cylinder, placed(b.position, {b.radius, 0.5 * b.height, b.radius}), stone);
            for (double s : {-0.5, 0.5}) {
                draw(r.sphere, placed(b.toWorld({0, s * b.height, 0}), {b.radius, b.radius, b.radius}),
                     stone);
            }
            break;
        case ShapeKind::Convex:
            draw(shapeMesh(r, *b.mesh), placed(b.position, {1, 1, 1}), stone);
            break;
        case ShapeKind::Mesh: // a triangle mesh need not be closed: both sides drawn
            glDisable(GL_CULL_FACE);
            draw(shapeMesh(r, *b.mesh), placed(b.position, {1, 1, 1}), stone);
            glEnable(GL_CULL_FACE);
            break;
        }
    });
    world.view<const RigidBody2D, const Transform>().each([&](Entity e, const RigidBody2D& b,
                                                              const Transform& t) {
        const std::array<float, 4> colour{float(b.color.x), float(b.color.y), float(b.color.z), 1.0f};
        Quat q = aboutZ(b.angle);
        Vec3 at{b.position[0], b.position[1], t.position.z};
        drawnPose(world, e, alpha, at, q);
        const Vec3 ax = rotate(q, {1, 0, 0}), ay = rotate(q, {0, 1, 0});
        switch (b.shape) {
        case Shape2DKind::Box:
            draw(r.cube, model(at, {b.halfExtents[0], b.halfExtents[1], kSlabHalfDepth}, ax, ay), colour);
            break;
        case Shape2DKind::Circle:
            // the unit cylinder stands along y: lay it along z
            draw(r.cylinder, model(at, {b.radius, kSlabHalfDepth, b.radius}, ax, {0, 0, 1}, -ay), colour);
            break;
        case Shape2DKind::Polygon: {
            const Mesh prism = upload(prismMesh(b.vertices));
            draw(prism, model(at, {1, 1, kSlabHalfDepth}, ax, ay), colour);
            glDeleteBuffers(1, &prism.vbo);
            glDeleteVertexArrays(1, &prism.vao);
            break;
        }
        case Shape2DKind::Edge: {
            const Vec3 from = at + ax * b.from[0] + ay * b.from[1], to = at + ax * b.to[0] + ay * b.to[1];
            const Vec3 along = to - from;
            const double len = length(along);
            const Vec3 ex = along * (1.0 / len), ey = cross({0, 0, 1}, ex);
            draw(r.cube, model((from + to) * 0.5, {0.5 * len, kEdgeDrawnHalfWidth, kSlabHalfDepth}, ex, ey),
                 colour);
            break;
        }
        }
    });
    glDisable(GL_CULL_FACE);
}

/// Draws r.clothVertices (position and normal per corner, in world space) as lit triangles of one colour.
void drawSurfaceVertices(Renderer& r, const std::array<float, 4>& colour) {
    const Mat4 identity = model({0, 0, 0}, {1, 1, 1});
    glUniformMatrix4fv(r.mesh.model, 1, GL_FALSE, identity.data());
    setColour(r, colour);
    glBindVertexArray(r.clothVao);
    glBindBuffer(GL_ARRAY_BUFFER, r.clothVbo);
    glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(r.clothVertices.size() * sizeof(float)), r.clothVertices.data(),
                 GL_STREAM_DRAW);
    glDrawArrays(GL_TRIANGLES, 0, GLsizei(r.clothVertices.size() / 6));
}

/// A water surface: its height field as a lit, two-sided surface with normals from the slopes; its rows'
/// vertices written over threads.
void drawWater(const Water& w, Renderer& r, WorkerPool& pool) {
    auto at = [&](int i, int k) {
        return Vec3{w.nodeX(i), w.centre.y + w.h[std::size_t(k) * w.nx + i], w.nodeZ(k)};
    };
    auto normal = [&](int i, int k) {
        const int i0 = std::max(i - 1, 0), i1 = std::min(i + 1, w.nx - 1);
        const int k0 = std::max(k - 1, 0), k1 = std::min(k + 1, w.nz - 1);
        const double sx =
            (w.h[std::size_t(k) * w.nx + i1] - w.h[std::size_t(k) * w.nx + i0]) / (w.dx() * (i1 - i0));
        const double sz =
            (w.h[std::size_t(k1) * w.nx + i] - w.h[std::size_t(k0) * w.nx + i]) / (w.dz() * (k1 - k0));
        const Vec3 n{-sx, 1.0, -sz};
        return n * (1.0 / length(n));
    };
    // two triangles a cell, six vertices of six floats
    const std::size_t perRow = std::size_t(w.nx - 1) * 36;
    r.clothVertices.resize(perRow * std::size_t(w.nz - 1));
    pool.forEach(std::size_t(w.nz - 1), std::max<std::size_t>(1, kVertexGrain / std::size_t(w.nx)),
                 [&](std::size_t row) {
                     const int k = int(row);
                     float* out = r.clothVertices.data() + row * perRow;
                     for (int i = 0; i + 1 < w.nx; ++i) {
                         for (const auto& [di, dk] : {std::pair{0, 0}, std::pair{0, 1}, std::pair{1, 1},
                                                      std::pair{0, 0}, std::pair{1, 1}, std::pair{1, 0}}) {
                             putVertex(out, at(i + di, k + dk), normal(i + di, k + dk));
                             out += 6;
                         }
                     }
                 });
    // alpha: how much of what lies below the water's own colour covers, seen head on
    drawSurfaceVertices(r, {0.20f, 0.45f, 0.75f, 0.45f});
}

/// A network with surface triangles (cloth, the outside of a soft body), lit, with smooth normals.
void drawSurface(const SpringNetwork& net, const std::vector<Vec3>& x, Renderer& r,
                 const std::array<float, 4>& colour, WorkerPool& pool) {
    // per-mass normals: the area-weighted sum of the triangles around it, then unit length
    r.normals.assign(x.size(), Vec3{});
    for (const auto& t : net.triangles) {
        const Vec3 n = cross(x[t[1]] - x[t[0]], x[t[2]] - x[t[0]]);
        for (std::uint32_t i : t) {
            r.normals[i] += n;
        }
    }
    pool.forEach(x.size(), kVertexGrain, [&](std::size_t i) {
        const double len = length(r.normals[i]);
        r.normals[i] = len > 0 ? r.normals[i] * (1.0 / len) : Vec3{0, 0, 1};
    });
    // three vertices a triangle, written over threads
    r.clothVertices.resize(net.triangles.size() * 18);
    pool.forEach(net.triangles.size(), kVertexGrain, [&](std::size_t k) {
        float* out = r.clothVertices.data() + k * 18;
        for (std::uint32_t i : net.triangles[k]) {
            putVertex(out, x[i], r.normals[i]);
            out += 6;
        }
    });
    drawSurfaceVertices(r, colour);
}

void drawLines(Renderer& r) {
    if (r.flat.empty()) {
        return;
    }
    glBindVertexArray(r.flatVao);
    glBindBuffer(GL_ARRAY_BUFFER, r.flatVbo);
    glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(r.flat.size() * sizeof(FlatVertex)), r.flat.data(),
                 GL_STREAM_DRAW);
    glDrawArrays(GL_LINES, 0, GLsizei(r.flat.size()));
    r.flat.clear();
}

/// A network without a surface: its masses as small lit balls of one colour (instanced).
void drawBalls(Renderer& r, const SpringNetwork& net, const std::vector<Vec3>& x,
               const std::array<float, 4>& c) {
    const float radius = float(std::max(0.04, net.thickness));
    const Mat4 identity = model({0, 0, 0}, {1, 1, 1});
    glUniformMatrix4fv(r.mesh.model, 1, GL_FALSE, identity.data());
    r.instances.clear();
    for (const Vec3& p : x) {
        r.instances.insert(r.instances.end(), {float(p.x), float(p.y), float(p.z), radius});
    }
    setColour(r, c);
    glBindVertexArray(r.ball.vao);
    glBindBuffer(GL_ARRAY_BUFFER, r.ballInstances);
    glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(r.instances.size() * sizeof(float)), r.instances.data(),
                 GL_STREAM_DRAW);
    glEnable(GL_CULL_FACE); // balls are closed (see drawColliders)
    glDrawArraysInstanced(GL_TRIANGLES, 0, r.ball.vertices, GLsizei(x.size()));
    glDisable(GL_CULL_FACE);
}

/// How far a body's shape reaches from its position, m (a sphere around it).
double reach(const RigidBody& b) {
    switch (b.shape) {
    case ShapeKind::Plane:
        return 0.0;
    case ShapeKind::Sphere:
        return b.radius;
    case ShapeKind::Box:
        return length(b.halfExtents);
    case ShapeKind::Cylinder:
    case ShapeKind::Capsule:
        return std::hypot(b.radius, 0.5 * b.height) + b.radius;
    case ShapeKind::Convex:
    case ShapeKind::Mesh:
        return length(Vec3{std::max(std::abs(b.mesh->lo.x), std::abs(b.mesh->hi.x)),
                           std::max(std::abs(b.mesh->lo.y), std::abs(b.mesh->hi.y)),
                           std::max(std::abs(b.mesh->lo.z), std::abs(b.mesh->hi.z))});
    }
    return 0.0;
}

double reach(const RigidBody2D& b) {
    double r = 0.0;
    switch (b.shape) {
    case Shape2DKind::Box:
        r = std::hypot(b.halfExtents[0], b.halfExtents[1]);
        break;
    case Shape2DKind::Circle:
        r = b.radius;
        break;
    case Shape2DKind::Polygon:
        for (const Vec2& v : b.vertices) {
            r = std::max(r, std::hypot(v[0], v[1]));
        }
        break;
    case Shape2DKind::Edge:
        r = std::max(std::hypot(b.from[0], b.from[1]), std::hypot(b.to[0], b.to[1])) + kEdgeDrawnHalfWidth;
        break;
    }
    return std::hypot(r, kSlabHalfDepth);
}

/// The box holding everything that casts a shadow (bodies but planes, spring networks), where they are and
/// where they were before the last step; false when nothing casts.
bool casterBounds(World& world, Vec3& lo, Vec3& hi) {
    bool any = false;
    auto grow = [&](const Vec3& p, double r) {
        const Vec3 a{p.x - r, p.y - r, p.z - r}, b{p.x + r, p.y + r, p.z + r};
        lo = any ? Vec3{std::min(lo.x, a.x), std::min(lo.y, a.y), std::min(lo.z, a.z)} : a;
        hi = any ? Vec3{std::max(hi.x, b.x), std::max(hi.y, b.y), std::max(hi.z, b.z)} : b;
        any = true;
    };
    // a frame between two steps draws the casters between where they were and are: both count
    auto before = [&](Entity e, double r) {
        if (const PoseHistory* pose = world.tryGet<PoseHistory>(e)) {
            grow(pose->position, r);
        }
    };
    world.view<const RigidBody>().each([&](Entity e, const RigidBody& b) {
        if (b.shape != ShapeKind::Plane) {
            grow(b.position, reach(b));
            before(e, reach(b));
        }
    });
    world.view<const RigidBody2D, const Transform>().each(
        [&](Entity e, const RigidBody2D& b, const Transform& t) {
            grow({b.position[0], b.position[1], t.position.z}, reach(b));
            before(e, reach(b));
        });
    world.view<const SpringNetwork>().each([&](Entity e, const SpringNetwork& net) {
        const double r = std::max(0.04, net.thickness);
        for (const Vec3& p : net.x) {
            grow(p, r);
        }
        if (const RenderHistory* history = world.tryGet<RenderHistory>(e)) {
            for (const Vec3& p : history->previous) {
                grow(p, r);
            }
        }
    });
    return any && isFinite(lo) && isFinite(hi);
}

constexpr int kShadowMapSize = 1024; ///< texels a side

void makeShadowMap(Renderer& r) {
    glGenTextures(1, &r.shadowMap);
    glBindTexture(GL_TEXTURE_2D, r.shadowMap);
    glTexStorage2D(GL_TEXTURE_2D, 1, GL_DEPTH_COMPONENT24, kShadowMapSize, kShadowMapSize);
    // compared in the lookup, and filtered: each lookup is already a 2 x 2 percentage-closer filter
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_FUNC, GL_LEQUAL);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glGenFramebuffers(1, &r.shadowFbo);
    glBindFramebuffer(GL_FRAMEBUFFER, r.shadowFbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, r.shadowMap, 0);
    const GLenum none = GL_NONE;
    glDrawBuffers(1, &none);
    glReadBuffer(GL_NONE);
    checkComplete(kShadowMapSize, kShadowMapSize, 1);
    glBindTexture(GL_TEXTURE_2D, 0);
}

/// The key light's view and orthographic projection fitted to the casters' box [lo, hi]: across the light,
/// the extent of the box's corners (2% more each side, so that the map's edge texels stay clear: beside
/// the map a lookup reads them); along it, their depth range (the same margin).
Mat4 lightProjection(const Vec3& lo, const Vec3& hi, const Vec3& light) {
    const Vec3 centre = (lo + hi) * 0.5;
    const double radius = std::max(0.5 * length(hi - lo), 1e-3);
    const Mat4 view = lookAt(centre - light * (2.0 * radius), centre);
    Vec3 a{1e300, 1e300, 1e300}, b{-1e300, -1e300, -1e300};
    for (int corner = 0; corner < 8; ++corner) {
        const Vec3 p{corner & 1 ? hi.x : lo.x, corner & 2 ? hi.y : lo.y, corner & 4 ? hi.z : lo.z};
        const Vec3 q{view[0] * p.x + view[4] * p.y + view[8] * p.z + view[12],
                     view[1] * p.x + view[5] * p.y + view[9] * p.z + view[13],
                     view[2] * p.x + view[6] * p.y + view[10] * p.z + view[14]};
        a = {std::min(a.x, q.x), std::min(a.y, q.y), std::min(a.z, q.z)};
        b = {std::max(b.x, q.x), std::max(b.y, q.y), std::max(b.z, q.z)};
    }
    const Vec3 margin = (b - a) * 0.02 + Vec3{1e-3, 1e-3, 1e-3};
    a = a - margin;
    b = b + margin;
    // the view looks down -z: the near plane at -b.z, the far at -a.z
    return multiply(orthographic(a.x, b.x, a.y, b.y, -b.z, -a.z), view);
}

/// The key light's shadow map: what casts drawn from the light (travelling along `light`) with an
/// orthographic projection over a box fitted to the casters' bounds. Returns the light's view-projection
/// (when nothing casts, the map is left clear).
Mat4 drawShadowMap(World& world, Renderer& r, const StepContext& ctx, const Vec3& light, bool wireframe,
                   WorkerPool& pool) {
    if (!r.shadowFbo) {
        makeShadowMap(r);
    }
    // not bound for reading while it is drawn into (the last frame left it on unit 3)
    glActiveTexture(GL_TEXTURE3);
    glBindTexture(GL_TEXTURE_2D, 0);
    glActiveTexture(GL_TEXTURE0);
    glBindFramebuffer(GL_FRAMEBUFFER, r.shadowFbo);
    glViewport(0, 0, kShadowMapSize, kShadowMapSize);
    glClear(GL_DEPTH_BUFFER_BIT);
    Vec3 lo, hi;
    if (!casterBounds(world, lo, hi)) {
        // nothing casts: the map left clear (depth 1 everywhere), and a zero matrix puts every point in its
        // middle at depth 0.5: lit
        return Mat4{};
    }
    const Mat4 lightViewProjection = lightProjection(lo, hi, light);
    glEnable(GL_DEPTH_TEST);
    // depth pushed back by the surface's slope, so that a lit surface does not shadow itself
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(2.0f, 4.0f);
    // the depth program stands in for the mesh program: the draws below set its matrices and nothing else
    glUseProgram(r.depthProgram);
    std::swap(r.mesh, r.depth);
    glVertexAttrib4f(2, 0.0f, 0.0f, 0.0f, 1.0f);
    glUniformMatrix4fv(r.mesh.viewProjection, 1, GL_FALSE, lightViewProjection.data());
    drawColliders(world, r, ctx.alpha);
    std::size_t drawn = 0;
    world.view<const SpringNetwork>().each([&](Entity e, const SpringNetwork& net) {
        const std::vector<Vec3>& x = drawnPositions(world, e, net, ctx.alpha, r.positions, pool);
        if (net.triangles.empty()) {
            drawBalls(r, net, x, palette(drawn));
        } else if (!wireframe) {
            drawSurface(net, x, r, palette(drawn),
                        pool); // in wireframe only its springs are drawn: no shadow
        }
        ++drawn;
    });
    std::swap(r.mesh, r.depth);
    glDisable(GL_POLYGON_OFFSET_FILL);
    return lightViewProjection;
}

/// The frame's look, from [render]'s switches and its background colour (the whole sky's colour without
/// the gradient, else the hue the gradient is made from): the sky's colours and the light, in the space the
/// shaders light in (linear with gamma).
struct Look {
    bool gamma = true;
    Vec3 zenith, horizon, nadir;
    float key = 0.75f; ///< the key light's strength
    Vec3 skyLight, groundLight;
};

Look sceneLook(const SceneDef& scene) {
    Look look;
    look.gamma = scene.renderGamma;
    auto lit = [&](const Vec3& c) {
        return look.gamma ? Vec3{srgbToLinear(c.x), srgbToLinear(c.y), srgbToLinear(c.z)} : c;
    };
    const Vec3 b{scene.background[0], scene.background[1], scene.background[2]};
    Vec3 zenith = b, horizon = b, nadir = b;
    if (scene.renderSkyGradient) {
        // overhead the background's hue deeper (its saturation 1.6 times, a little darker), at the horizon
        // paler (a third of the way to white), below the horizon dark
        const double grey = 0.3 * b.x + 0.59 * b.y + 0.11 * b.z;
        const Vec3 deep = (Vec3{grey, grey, grey} + (b - Vec3{grey, grey, grey}) * 1.6) * 0.85;
        zenith = {std::clamp(deep.x, 0.0, 1.0), std::clamp(deep.y, 0.0, 1.0), std::clamp(deep.z, 0.0, 1.0)};
        horizon = b + (Vec3{1, 1, 1} - b) * 0.35;
        nadir = b * 0.45;
    }
    look.zenith = lit(zenith);
    look.horizon = lit(horizon);
    look.nadir = lit(nadir);
    look.key = look.gamma ? 1.0f : 0.75f;
    if (scene.renderHemisphere) {
        // from above the sky's colour, from below the light the ground throws back (a warm grey)
        look.skyLight = lit(b) * 0.75;
        look.groundLight = lit(Vec3{0.45, 0.42, 0.38}) * 0.5;
    } else {
        // grey, from above only
        const double a = look.gamma ? 0.2 : 0.35;
        look.skyLight = {a, a, a};
        look.groundLight = {};
    }
    return look;
}

void setLook(const Renderer::LookUniforms& u, const Look& look) {
    glUniform3f(u.zenith, float(look.zenith.x), float(look.zenith.y), float(look.zenith.z));
    glUniform3f(u.horizon, float(look.horizon.x), float(look.horizon.y), float(look.horizon.z));
    glUniform3f(u.nadir, float(look.nadir.x), float(look.nadir.y), float(look.nadir.z));
}

/// The mesh program's uniforms for this frame: the camera, the light, the look, the shadow map.
void setMeshFrame(Renderer& r, const Look& look, const Mat4& viewProjection, const Vec3& eye,
                  const Vec3& light, const std::optional<Mat4>& lightViewProjection) {
    glUseProgram(r.meshProgram);
    glVertexAttrib4f(2, 0.0f, 0.0f, 0.0f, 1.0f);
    glUniformMatrix4fv(r.mesh.viewProjection, 1, GL_FALSE, viewProjection.data());
    glUniform3f(r.mesh.lightDir, float(light.x), float(light.y), float(light.z));
    glUniform3f(r.mesh.eye, float(eye.x), float(eye.y), float(eye.z));
    glUniform1f(r.mesh.key, look.key);
    glUniform3f(r.mesh.skyLight, float(look.skyLight.x), float(look.skyLight.y), float(look.skyLight.z));
    glUniform3f(r.mesh.groundLight, float(look.groundLight.x), float(look.groundLight.y),
                float(look.groundLight.z));
    setLook(r.meshLook, look);
    // the shadow map on texture unit 3 (the smoke pass has 0 to 2)
    glActiveTexture(GL_TEXTURE3);
    glBindTexture(GL_TEXTURE_2D, lightViewProjection ? r.shadowMap : 0);
    glActiveTexture(GL_TEXTURE0);
    glUniform1i(r.shadow.map, 3);
    glUniformMatrix4fv(r.shadow.lightViewProjection, 1, GL_FALSE,
                       (lightViewProjection ? *lightViewProjection : Mat4{}).data());
}

constexpr double kGroundHalfSize = 200.0; ///< a ground plane is drawn as a square this far each way

/// A ground plane's model matrix: the unit square y = 0, |x| and |z| at most 1, onto the plane (y along its
/// normal).
Mat4 groundModel(const RigidBody& b) {
    const Vec3 n = b.normal;
    Vec3 t = std::abs(n.x) < 0.9 ? cross(n, Vec3{1, 0, 0}) : cross(n, Vec3{0, 0, 1});
    t = t * (1.0 / length(t));
    const Vec3 s = cross(t, n);
    return model(b.position, {kGroundHalfSize, 1, kGroundHalfSize}, s, n, t);
}

/// Where the shadow map reaches on a ground plane's unit square, {x0, x1, z0, z1}: the box round the
/// parallelogram that the map's square, carried along the light, cuts from the plane (a little wider, against
/// rounding), clipped to the square (x0 = x1 or z0 = z1 if it misses it); the whole square when the light
/// runs along the plane, or the matrix is zero (nothing casts) or not finite. `lightModel`: the light's
/// view-projection times the plane's model matrix. Beyond the map a lookup reads lit (drawShadowMap keeps
/// the map's edge clear), so the ground there needs none.
std::array<float, 4> reachedByMap(const Mat4& lightModel) {
    // the map's coordinates at (x, 0, z): X = a x + b z + e, Y = c x + d z + f (orthographic: w = 1)
    const double a = lightModel[0], b = lightModel[8], e = lightModel[12];
    const double c = lightModel[1], d = lightModel[9], f = lightModel[13];
    const double det = a * d - b * c;
    if (!(std::abs(det) > 1e-9 * (std::abs(a * d) + std::abs(b * c))) || !std::isfinite(e) ||
        !std::isfinite(f)) {
        return {-1.0f, 1.0f, -1.0f, 1.0f};
    }
    double x0 = 1e300, x1 = -1e300, z0 = 1e300, z1 = -1e300;
    for (const double X : {-1.0, 1.0}) {
        for (const double Y : {-1.0, 1.0}) {
            const double x = ((X - e) * d - (Y - f) * b) / det, z = (a * (Y - f) - c * (X - e)) / det;
            x0 = std::min(x0, x);
            x1 = std::max(x1, x);
            z0 = std::min(z0, z);
            z1 = std::max(z1, z);
        }
    }
    const double pad = 1e-3 * std::max(x1 - x0, z1 - z0) + 1e-6;
    auto clip = [](double v) { return float(std::clamp(v, -1.0, 1.0)); };
    return {clip(x0 - pad), clip(x1 + pad), clip(z0 - pad), clip(z1 + pad)};
}

/// A ground plane's unit square cut at `reach`'s lines into 3 x 3 cells, as triangles (position and normal
/// per corner) in `out`: the middle cell (where the map reaches) first, then the others; returns the middle
/// cell's corners (0 or 6). Cells of no area are left out; neighbours share their corners exactly, so the
/// plane has no cracks.
GLsizei groundCells(const std::array<float, 4>& reach, std::vector<float>& out) {
    const float xs[4] = {-1.0f, reach[0], reach[1], 1.0f}, zs[4] = {-1.0f, reach[2], reach[3], 1.0f};
    out.clear();
    auto cell = [&](int i, int k) {
        if (!(xs[i + 1] > xs[i]) || !(zs[k + 1] > zs[k])) {
            return;
        }
        for (const auto& [x, z] :
             {std::pair{xs[i], zs[k]}, std::pair{xs[i + 1], zs[k + 1]}, std::pair{xs[i + 1], zs[k]},
              std::pair{xs[i], zs[k]}, std::pair{xs[i], zs[k + 1]}, std::pair{xs[i + 1], zs[k + 1]}}) {
            out.insert(out.end(), {x, 0.0f, z, 0.0f, 1.0f, 0.0f});
        }
    };
    cell(1, 1);
    const GLsizei onMap = GLsizei(out.size() / 6);
    for (int k = 0; k < 3; ++k) {
        for (int i = 0; i < 3; ++i) {
            if (i != 1 || k != 1) {
                cell(i, k);
            }
        }
    }
    return onMap;
}

/// What a ground plane's program takes for its colour (mesh.frag's GROUND): lit by the key light and in
/// shadow (lit in linear light with gamma), and the written colour beyond the shadow map as a quadratic in
/// the grid's cover g, c0 + g (c1 + g c2), through the written colours at g = 0, 1/2 and 1 (the sRGB curve is
/// smooth over the 30% the grid darkens by: the quadratic is within a tenth of a level of it).
struct GroundColours {
    Vec3 lit, shade;
    std::array<Vec3, 3> cover;
};

GroundColours groundColours(const RigidBody& b, const Look& look, const Vec3& eye, const Vec3& light) {
    // the side facing the eye is lit, as mesh.frag's two-sided surfaces
    Vec3 n = b.normal * (1.0 / length(b.normal));
    if (dot(n, eye - b.position) < 0.0) {
        n = n * -1.0;
    }
    const double diffuse = std::max(dot(n, light * -1.0), 0.0);
    const double up = 0.5 + 0.5 * n.y;
    const Vec3 ambient = look.groundLight + (look.skyLight - look.groundLight) * up;
    const Vec3 c{b.color.x, b.color.y, b.color.z};
    const Vec3 base = look.gamma ? Vec3{srgbToLinear(c.x), srgbToLinear(c.y), srgbToLinear(c.z)} : c;
    auto times = [](const Vec3& a, const Vec3& v) { return Vec3{a.x * v.x, a.y * v.y, a.z * v.z}; };
    GroundColours out;
    out.shade = times(base, ambient);
    out.lit = times(base, ambient + Vec3{1, 1, 1} * (double(look.key) * diffuse));
    const Vec3 e0 = encodeColour(out.lit, look.gamma), eHalf = encodeColour(out.lit * 0.85, look.gamma),
               e1 = encodeColour(out.lit * 0.7, look.gamma);
    out.cover = {e0, eHalf * 4.0 - e0 * 3.0 - e1, e0 * 2.0 - eHalf * 4.0 + e1 * 2.0};
    return out;
}

/// Ground planes with their grid, after everything else opaque (at one sample llvmpipe then skips shading
/// what they hide). Only the part the shadow map reaches is drawn with its lookups (reachedByMap); the rest
/// with a program without them, which gives the same pixels: a CPU rasteriser runs a shader's every branch
/// on every pixel, and the far ground is most of a frame.
void drawGround(World& world, Renderer& r, const Look& look, const Mat4& viewProjection, const Vec3& eye,
                const Vec3& light, const std::optional<Mat4>& lightViewProjection) {
    world.view<const RigidBody>().each([&](Entity, const RigidBody& b) {
        if (b.shape != ShapeKind::Plane) {
            return;
        }
        const Mat4 m = groundModel(b);
        const GroundColours colours = groundColours(b, look, eye, light);
        const GLsizei onMap =
            groundCells(lightViewProjection ? reachedByMap(multiply(*lightViewProjection, m))
                                            : std::array{-1.0f, 1.0f, -1.0f, 1.0f},
                        r.groundVertices);
        const GLsizei all = GLsizei(r.groundVertices.size() / 6);
        glBindVertexArray(r.groundVao);
        glBindBuffer(GL_ARRAY_BUFFER, r.groundVbo);
        glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(r.groundVertices.size() * sizeof(float)),
                     r.groundVertices.data(), GL_STREAM_DRAW);
        for (const auto& [program, first, count] :
             {std::tuple{&r.ground, GLsizei(0), onMap}, std::tuple{&r.groundOffMap, onMap, all - onMap}}) {
            if (count == 0) {
                continue;
            }
            swapLit(r, *program);
            setMeshFrame(r, look, viewProjection, eye, light, lightViewProjection);
            glUniformMatrix4fv(r.mesh.model, 1, GL_FALSE, m.data());
            setColour(r, {float(b.color.x), float(b.color.y), float(b.color.z), 1.0f});
            const auto& u = program->ground;
            for (const auto& [at, v] :
                 {std::pair{u.lit, colours.lit}, std::pair{u.shade, colours.shade},
                  std::pair{u.cover0, colours.cover[0]}, std::pair{u.cover1, colours.cover[1]},
                  std::pair{u.cover2, colours.cover[2]}}) {
                glUniform3f(at, float(v.x), float(v.y), float(v.z));
            }
            glDrawArrays(GL_TRIANGLES, first, count);
            swapLit(r, *program);
        }
    });
}

constexpr int kSkyTexelPixels = 4;   ///< a texel of the sky's texture spans 4 x 4 pixels
constexpr GLint kSkyTextureUnit = 4; ///< (the smoke pass has units 0 to 2, the shadow map 3)

/// The sky's texture for this frame's camera and look, drawn again only if they or the target's size
/// changed since it was last drawn; leaves the target unbound. Its texels hold the gradient at the centres
/// of the target's cells of 4 x 4 pixels (the last row and column of cells may stand past its edge).
void updateSky(Renderer& r, const Look& look, const Mat4& viewProjection, const Vec3& eye) {
    const int width = r.target->width(), height = r.target->height();
    const Eigen::Matrix4f inverse = Eigen::Map<const Eigen::Matrix4f>(viewProjection.data()).inverse();
    std::array<float, 30> key{};
    std::copy(inverse.data(), inverse.data() + 16, key.begin());
    std::size_t at = 16;
    for (const Vec3& v : {eye, look.zenith, look.horizon, look.nadir}) {
        for (const double c : {v.x, v.y, v.z}) {
            key[at++] = float(c);
        }
    }
    key[28] = float(width);
    key[29] = float(height);
    if (key == r.skyDrawnFor) {
        return;
    }
    const int texelsX = (width + kSkyTexelPixels - 1) / kSkyTexelPixels;
    const int texelsY = (height + kSkyTexelPixels - 1) / kSkyTexelPixels;
    if (texelsX != r.skyWidth || texelsY != r.skyHeight) {
        glDeleteTextures(1, &r.skyTexture);
        glDeleteFramebuffers(1, &r.skyFbo);
        glGenTextures(1, &r.skyTexture);
        glBindTexture(GL_TEXTURE_2D, r.skyTexture);
        glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA8, texelsX, texelsY);
        for (const GLenum filter : {GL_TEXTURE_MIN_FILTER, GL_TEXTURE_MAG_FILTER}) {
            glTexParameteri(GL_TEXTURE_2D, filter, GL_LINEAR);
        }
        for (const GLenum wrap : {GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T}) {
            glTexParameteri(GL_TEXTURE_2D, wrap, GL_CLAMP_TO_EDGE);
        }
        glGenFramebuffers(1, &r.skyFbo);
        glBindFramebuffer(GL_FRAMEBUFFER, r.skyFbo);
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, r.skyTexture, 0);
        checkComplete(texelsX, texelsY, 1);
        glBindTexture(GL_TEXTURE_2D, 0);
        r.skyWidth = texelsX;
        r.skyHeight = texelsY;
    }
    glBindFramebuffer(GL_FRAMEBUFFER, r.skyFbo);
    glViewport(0, 0, texelsX, texelsY);
    glDisable(GL_DEPTH_TEST);
    glUseProgram(r.skyTexelsProgram);
    setLook(r.skyLook, look);
    glUniformMatrix4fv(r.sky.inverseViewProjection, 1, GL_FALSE, inverse.data());
    glUniform3f(r.sky.eye, float(eye.x), float(eye.y), float(eye.z));
    // texel i's centre (gl_FragCoord i + 0.5) stands for the pixel 4 i + 2
    glUniform2f(r.sky.texelToNdc, 2.0f * kSkyTexelPixels / float(width),
                2.0f * kSkyTexelPixels / float(height));
    glBindVertexArray(r.skyVao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    r.skyDrawnFor = key;
}

/// A convex polygon in clip space (x, y, z, w) of up to eight corners: a ground plane's square cut by
/// two planes has at most six.
struct ClipPolygon {
    std::array<std::array<double, 4>, 8> corners{};
    std::size_t size = 0;

    void push(const std::array<double, 4>& p) {
        if (size < corners.size()) {
            corners[size++] = p;
        }
    }
};

/// A convex polygon cut by the half-space a . p >= 0 (Sutherland and Hodgman).
ClipPolygon clipPolygon(const ClipPolygon& polygon, const std::array<double, 4>& a) {
    ClipPolygon out;
    auto side = [&](const std::array<double, 4>& p) {
        return a[0] * p[0] + a[1] * p[1] + a[2] * p[2] + a[3] * p[3];
    };
    for (std::size_t i = 0; i < polygon.size; ++i) {
        const auto& p = polygon.corners[i];
        const auto& q = polygon.corners[(i + 1) % polygon.size];
        const double sp = side(p), sq = side(q);
        if (sp >= 0.0) {
            out.push(p);
        }
        if ((sp >= 0.0) != (sq >= 0.0)) {
            const double t = sp / (sp - sq);
            out.push({p[0] + (q[0] - p[0]) * t, p[1] + (q[1] - p[1]) * t, p[2] + (q[2] - p[2]) * t,
                      p[3] + (q[3] - p[3]) * t});
        }
    }
    return out;
}

/// The rows of the target (GL's, from the bottom) where the sky may show, [first, end): all of them but
/// a band along the bottom or the top that a ground plane covers from edge to edge (one row spare; a
/// ground plane is opaque and drawn whole). With multisampling llvmpipe shades every pixel a draw
/// covers, hidden or not, so the sky drawn over the whole target cost as much again as it does where it
/// shows.
std::pair<int, int> skyRows(World& world, const Mat4& viewProjection, int width, int height) {
    int first = 0, end = height;
    world.view<const RigidBody>().each([&](Entity, const RigidBody& b) {
        if (b.shape != ShapeKind::Plane) {
            return;
        }
        const Mat4 m = multiply(viewProjection, groundModel(b));
        ClipPolygon polygon;
        for (const auto& [x, z] :
             {std::pair{-1.0, -1.0}, std::pair{1.0, -1.0}, std::pair{1.0, 1.0}, std::pair{-1.0, 1.0}}) {
            polygon.push({m[0] * x + m[8] * z + m[12], m[1] * x + m[9] * z + m[13],
                          m[2] * x + m[10] * z + m[14], m[3] * x + m[11] * z + m[15]});
        }
        // what the rasteriser draws of it: between the near (z >= -w) and far (z <= w) planes
        polygon = clipPolygon(clipPolygon(polygon, {0, 0, 1, 1}), {0, 0, -1, 1});
        // where the target's left and right edges run through it: the rows between are covered
        double lo = -1e300, hi = 1e300;
        for (const double edge : {0.0, double(width)}) {
            double a = 1e300, c = -1e300;
            for (std::size_t i = 0; i < polygon.size; ++i) {
                const auto& p = polygon.corners[i];
                const auto& q = polygon.corners[(i + 1) % polygon.size];
                const double px = (p[0] / p[3] + 1.0) * 0.5 * width, py = (p[1] / p[3] + 1.0) * 0.5 * height;
                const double qx = (q[0] / q[3] + 1.0) * 0.5 * width, qy = (q[1] / q[3] + 1.0) * 0.5 * height;
                if (std::min(px, qx) <= edge && edge <= std::max(px, qx)) {
                    const double y = px == qx ? py : py + (qy - py) * (edge - px) / (qx - px);
                    a = std::min({a, y, px == qx ? qy : y});
                    c = std::max({c, y, px == qx ? qy : y});
                }
            }
            lo = std::max(lo, a);
            hi = std::min(hi, c);
        }
        if (!(lo < hi) || !std::isfinite(lo) || !std::isfinite(hi)) {
            return;
        }
        if (lo <= 0.0) {
            first = std::max(first, int(std::clamp(std::floor(hi) - 1.0, 0.0, double(height))));
        }
        if (hi >= height) {
            end = std::min(end, int(std::clamp(std::ceil(lo) + 1.0, 0.0, double(height))));
        }
    });
    return {first, std::max(first, end)};
}

/// How the sky is drawn: first, under everything, or last, behind everything.
enum class SkyPass {
    /// Before the scene, with no depth test: over every pixel of its rows, the scene then drawn over it.
    /// With several samples a pixel, where llvmpipe shades every pixel of the rows either way (it skips
    /// no hidden fragment when multisampling), and depth-testing each sample costs more than the sky's
    /// samples the scene covers again (`tumble run curtain`, render p50 with shadows and 4 samples,
    /// alternating: 14.9-17.0 -> 13.7-15.7 ms in three pairs; the avalanche 25.4-25.9 -> 24.8-24.9 in two
    /// of three).
    Under,
    /// After the opaque scene, depth-tested at the far plane: shaded only where it shows. With one sample a
    /// pixel, where llvmpipe skips a hidden fragment before shading it (the curtain: 6.5 ms, 6.7 under).
    Behind,
};

/// The sky gradient, in the rows where it may show: its texture (updateSky), filtered.
void drawSky(World& world, Renderer& r, const Mat4& viewProjection, SkyPass pass) {
    const auto [first, end] = skyRows(world, viewProjection, r.target->width(), r.target->height());
    if (first == end) {
        return;
    }
    glEnable(GL_SCISSOR_TEST);
    glScissor(0, first, r.target->width(), end - first);
    glUseProgram(r.skyProgram);
    glActiveTexture(GL_TEXTURE0 + kSkyTextureUnit);
    glBindTexture(GL_TEXTURE_2D, r.skyTexture);
    glActiveTexture(GL_TEXTURE0);
    glUniform1i(r.sky.texture, kSkyTextureUnit);
    glUniform2f(r.sky.pixelToUv, 1.0f / float(kSkyTexelPixels * r.skyWidth),
                1.0f / float(kSkyTexelPixels * r.skyHeight));
    glBindVertexArray(r.skyVao);
    if (pass == SkyPass::Under) {
        glDisable(GL_DEPTH_TEST);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        glEnable(GL_DEPTH_TEST);
    } else {
        glDepthFunc(GL_LEQUAL);
        glDepthMask(GL_FALSE);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        glDepthMask(GL_TRUE);
        glDepthFunc(GL_LESS);
    }
    glDisable(GL_SCISSOR_TEST);
}

/// Water, see-through: after everything opaque and the sky, blended over them (mesh.frag's water()).
void drawWaters(World& world, Renderer& r, WorkerPool& pool, const Look& look, const Mat4& viewProjection,
                const Vec3& eye, const Vec3& light, const std::optional<Mat4>& lightViewProjection) {
    if (world.view<const Water>().count() == 0) {
        return;
    }
    swapLit(r, r.water);
    setMeshFrame(r, look, viewProjection, eye, light, lightViewProjection);
    glEnable(GL_BLEND);
    // the colour blended, the image's alpha kept at 1 (a PNG or a video frame is opaque)
    glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);
    world.view<const Water>().each([&](Entity, const Water& w) { drawWater(w, r, pool); });
    glDisable(GL_BLEND);
    swapLit(r, r.water);
}

} // namespace

void renderWorld(World& world, const StepContext& ctx) {
    RenderOutput* output = world.tryResource<RenderOutput>();
    if (!output || !output->enabled) {
        return;
    }
    const SceneDef& scene = world.resource<SceneDef>();
    Renderer& r = renderer(world, scene, *output);
    if (output->width > 0 && output->height > 0 &&
        (output->width != r.target->width() || output->height != r.target->height())) {
        // a window resized: a new target of its size (made before the old one goes: if it cannot be made, the
        // error leaves the renderer with a target still)
        r.target = std::make_unique<Framebuffer>(output->width, output->height, scene.renderSamples);
    }
    WorkerPool& pool = poolOr(ctx.pool);
    const auto& eyeAt = output->cameraSet ? output->eye : scene.cameraEye;
    const auto& targetAt = output->cameraSet ? output->target : scene.cameraTarget;
    const Vec3 eye{eyeAt[0], eyeAt[1], eyeAt[2]};
    const Vec3 target{targetAt[0], targetAt[1], targetAt[2]};
    Vec3 light = (target - eye) * 0.5 + Vec3{0.0, -1.0, 0.0} * length(target - eye);
    if (scene.lightDirection) {
        light = {(*scene.lightDirection)[0], (*scene.lightDirection)[1], (*scene.lightDirection)[2]};
    }
    light = light * (1.0 / length(light));
    // which faces the culling of closed shapes takes for back ones (a host's context may have set others)
    glFrontFace(GL_CCW);
    glCullFace(GL_BACK);
    const std::optional<Mat4> lightViewProjection =
        scene.renderShadows
            ? std::optional<Mat4>(drawShadowMap(world, r, ctx, light, output->wireframe, pool))
            : std::nullopt;

    const Mat4 viewProjection = tumble::viewProjection(scene, output);
    const Look look = sceneLook(scene);
    if (scene.renderSkyGradient) {
        updateSky(r, look, viewProjection, eye);
    }

    r.target->bind();
    // with the sky gradient, the sky and the ground planes cover every pixel (skyRows), so the colour is not
    // cleared: at 4 samples a pixel a clear of colour is a pass over 15 MB of its own, 1.1-1.5 ms on llvmpipe
    glClearColor(float(scene.background[0]), float(scene.background[1]), float(scene.background[2]), 1.0f);
    glClear(scene.renderSkyGradient ? GL_DEPTH_BUFFER_BIT : GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    const SkyPass skyPass = r.target->samples() > 1 ? SkyPass::Under : SkyPass::Behind;
    if (scene.renderSkyGradient && skyPass == SkyPass::Under) {
        drawSky(world, r, viewProjection, skyPass);
    }

    // lit meshes: colliders and cloth; attribute 2 (the per-instance offset and scale) is (0, 0, 0, 1) for
    // every draw that is not instanced
    setMeshFrame(r, look, viewProjection, eye, light, lightViewProjection);
    drawColliders(world, r, ctx.alpha);
    std::size_t drawn = 0;
    world.view<const SpringNetwork>().each([&](Entity e, const SpringNetwork& net) {
        if (!net.triangles.empty() && !output->wireframe) {
            drawSurface(net, drawnPositions(world, e, net, ctx.alpha, r.positions, pool), r, palette(drawn),
                        pool);
        }
        ++drawn;
    });

    // lines and points: other spring networks, then particles (blended, after everything opaque)
    // other spring networks: their springs as lines, their masses as small lit balls (instanced)
    glUseProgram(r.flatProgram);
    glUniformMatrix4fv(r.flatViewProjection, 1, GL_FALSE, viewProjection.data());
    world.view<const SpringNetwork>().each([&](Entity e, const SpringNetwork& net) {
        if (!net.triangles.empty() && !output->wireframe) {
            return; // drawn as a surface
        }
        const std::vector<Vec3>& x = drawnPositions(world, e, net, ctx.alpha, r.positions, pool);
        auto line = [&](std::uint32_t a, std::uint32_t b) {
            for (std::uint32_t i : {a, b}) {
                r.flat.push_back(
                    {float(x[i].x), float(x[i].y), float(x[i].z), 0.2f, 0.2f, 0.22f, 1.0f, 0.0f});
            }
        };
        for (const SpringLink& s : net.links) {
            line(s.a, s.b);
        }
        if (net.links.empty()) {
            // an fem body has no springs: the edges of its surface (each shared edge drawn twice)
            for (const auto& t : net.triangles) {
                line(t[0], t[1]);
                line(t[1], t[2]);
                line(t[2], t[0]);
            }
        }
        drawLines(r);
    });
    appendVelocityArrows(world, r.flat);
    drawLines(r);
    glUseProgram(r.meshProgram);
    const Mat4 identity = model({0, 0, 0}, {1, 1, 1});
    glUniformMatrix4fv(r.mesh.model, 1, GL_FALSE, identity.data());
    drawn = 0;
    world.view<const SpringNetwork>().each([&](Entity e, const SpringNetwork& net) {
        const auto c = palette(drawn++);
        if (!net.triangles.empty()) {
            return; // a surface, or in wireframe its springs alone (balls would hide them)
        }
        drawBalls(r, net, drawnPositions(world, e, net, ctx.alpha, r.positions, pool), c);
    });
    drawGround(world, r, look, viewProjection, eye, light, lightViewProjection);
    if (scene.renderSkyGradient && skyPass == SkyPass::Behind) {
        drawSky(world, r, viewProjection, skyPass);
    }
    drawWaters(world, r, pool, look, viewProjection, eye, light, lightViewProjection);

    // smoke, marched up to the opaque scene and blended over it
    drawSmoke(world, r.smoke,
              {viewProjection, eye, r.target->id(), r.target->width(), r.target->height(), r.cube.vao,
               r.cube.vertices});

    // particles: camera-facing quads (instanced), blended after everything opaque
    glUseProgram(r.particleProgram);
    glUniformMatrix4fv(r.particle.viewProjection, 1, GL_FALSE, viewProjection.data());
    const Mat4 view = lookAt(eye, target);
    glUniform3f(r.particle.right, view[0], view[4], view[8]);
    glUniform3f(r.particle.up, view[1], view[5], view[9]);
    glEnable(GL_BLEND);
    // the colour blended, the image's alpha kept at 1 (a PNG or a video frame is opaque)
    glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);
    glDepthMask(GL_FALSE);
    world.view<const ParticleEmitter>().each([&](Entity, const ParticleEmitter& e) {
        const ParticlePool& p = e.pool;
        if (p.count == 0) {
            return;
        }
        // particles move by symplectic Euler, x' = x + dt v', so x - (1 - alpha) dt v is exactly where a
        // particle was at alpha between the last two steps (unless it bounced or was born in the last one)
        const float back = float((std::min(ctx.alpha, 1.0) - 1.0) * ctx.dt);
        r.flat.resize(p.count);
        pool.forEach(p.count, kVertexGrain, [&](std::size_t i) {
            // the fraction of its life lived: steps since birth over the steps it lives through
            const float life = std::min(1.0f, float(p.clock - p.birthStep[i]) /
                                                  (float(p.deathStep[i] - p.birthStep[i]) + 1.0f));
            const auto c = particleColor(e.def, life);
            r.flat[i] = {p.px[i] + back * p.vx[i],
                         p.py[i] + back * p.vy[i],
                         p.pz[i] + back * p.vz[i],
                         c[0],
                         c[1],
                         c[2],
                         c[3],
                         particleSize(e.def, life)};
        });
        glBindVertexArray(r.particleVao);
        glBindBuffer(GL_ARRAY_BUFFER, r.particleVbo);
        glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(r.flat.size() * sizeof(FlatVertex)), r.flat.data(),
                     GL_STREAM_DRAW);
        glDrawArraysInstanced(GL_TRIANGLE_STRIP, 0, 4, GLsizei(r.flat.size()));
        r.flat.clear();
    });
    glDepthMask(GL_TRUE);
    glDisable(GL_BLEND);
    r.drawn = true;

    // keep this frame? every pngEvery frames, and the last frame always; every frame for a video
    const std::uint64_t frame = ctx.frame + 1;
    const bool png = output->keepFrames &&
                     ((output->pngEvery > 0 && frame % output->pngEvery == 0) || frame == output->lastFrame);
    if (png || output->video) {
        r.target->read(r.pixels);
    } else {
        // wait for the frame here, so that its cost shows in the profiler's frame phase where it belongs.
        // Left queued, llvmpipe rasterises it on its threads during the next fixed steps (they then time
        // the contention, p99 of the curtain's springs 1.7 -> 5.5 ms) and frames that are never read back
        // pile up: every later frame took about twice as long (BM_RenderCurtainFrame 5.1 ms with glFlush
        // here, 2.6 ms with glFinish, 2.8 ms for the raw EGL draw of the same triangles)
        glFinish();
    }
    if (output->video) {
        output->video(r.pixels);
    }
    if (png) {
        char name[32];
        std::snprintf(name, sizeof name, "frame_%05llu.png", static_cast<unsigned long long>(frame));
        const std::string path = output->directory + "/" + name;
        writePng(path, r.target->width(), r.target->height(), r.pixels);
        output->written.push_back(path);
    }
}

std::array<float, 16> viewProjection(const SceneDef& scene, const RenderOutput* output) {
    const bool own = output && output->cameraSet;
    const Vec3 eye = own ? Vec3{output->eye[0], output->eye[1], output->eye[2]}
                         : Vec3{scene.cameraEye[0], scene.cameraEye[1], scene.cameraEye[2]};
    const Vec3 target = own ? Vec3{output->target[0], output->target[1], output->target[2]}
                            : Vec3{scene.cameraTarget[0], scene.cameraTarget[1], scene.cameraTarget[2]};
    const bool sized = output && output->width > 0 && output->height > 0;
    const double aspect =
        sized ? double(output->width) / output->height : double(scene.renderWidth) / scene.renderHeight;
    return multiply(perspective(scene.cameraFovDeg, aspect, 0.05, 500.0), lookAt(eye, target));
}

bool lastImage(World& world, int& width, int& height, std::vector<std::uint8_t>& rgba) {
    Renderer* r = world.tryResource<Renderer>();
    if (!r || !r->drawn) {
        return false;
    }
    r->makeCurrent();
    r->target->read(rgba);
    width = r->target->width();
    height = r->target->height();
    return true;
}

bool presentImage(World& world, int width, int height) {
    Renderer* r = world.tryResource<Renderer>();
    if (!r || !r->drawn) {
        return false;
    }
    glBindFramebuffer(GL_READ_FRAMEBUFFER, r->target->resolved());
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    const bool same = width == r->target->width() && height == r->target->height();
    glBlitFramebuffer(0, 0, r->target->width(), r->target->height(), 0, 0, width, height, GL_COLOR_BUFFER_BIT,
                      same ? GL_NEAREST : GL_LINEAR);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    return true;
}

void rememberPositions(World& world, const StepContext&) {
    const RenderOutput* output = world.tryResource<RenderOutput>();
    if (!output || !output->enabled) {
        return;
    }
    world.view<const SpringNetwork>().each([&](Entity e, const SpringNetwork& net) {
        if (RenderHistory* h = world.tryGet<RenderHistory>(e)) {
            h->previous.assign(net.x.begin(), net.x.end());
        } else {
            world.commands().emplace(e, RenderHistory{net.x});
        }
    });
    auto remember = [&](Entity e, const PoseHistory& pose) {
        if (PoseHistory* h = world.tryGet<PoseHistory>(e)) {
            *h = pose;
        } else {
            world.commands().emplace(e, pose);
        }
    };
    world.view<const RigidBody>().each([&](Entity e, const RigidBody& b) {
        if (b.dynamic()) {
            remember(e, {b.position, b.orientation});
        }
    });
    world.view<const RigidBody2D, const Transform>().each(
        [&](Entity e, const RigidBody2D& b, const Transform& t) {
            if (b.dynamic()) {
                remember(e, {{b.position[0], b.position[1], t.position.z}, aboutZ(b.angle)});
            }
        });
}

} // namespace tumble
