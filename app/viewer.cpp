#include "app/viewer.h"

#include "app/run_loop.h"
#include "components/particles.h"
#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "components/spring_network.h"
#include "engine/fixed_loop.h"
#include "engine/name.h"
#include "engine/render_output.h"
#include "engine/replay.h"
#include "engine/run_report.h"
#include "engine/simulation.h"
#include "engine/transform.h"
#include "systems/render_system.h"

#define GLFW_INCLUDE_NONE
#include <GLES3/gl3.h>
#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <imgui.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace tumble {

namespace {

std::string g_glfwError; ///< the last error GLFW reported (its callback has no user pointer)

/// Draws Dear ImGui's triangles with GLES 3. Debian's libimgui ships an OpenGL 3 backend built for desktop
/// GL (it loads libGL.so.1 through GLX and writes "#version 130" shaders), which a GLES context through
/// EGL cannot use; this is the small part of a backend that differs: a shader, the font texture, buffers.
class OverlayRenderer {
public:
    OverlayRenderer() {
        m_program =
            compileProgram("#version 300 es\n"
                           "uniform mat4 uProjection;\n"
                           "layout(location = 0) in vec2 aPosition;\n"
                           "layout(location = 1) in vec2 aUv;\n"
                           "layout(location = 2) in vec4 aColor;\n"
                           "out vec2 vUv;\nout vec4 vColor;\n"
                           "void main() { vUv = aUv; vColor = aColor; gl_Position = uProjection * "
                           "vec4(aPosition, 0.0, 1.0); }\n",
                           "#version 300 es\nprecision mediump float;\n"
                           "uniform sampler2D uTexture;\nin vec2 vUv;\nin vec4 vColor;\nout vec4 outColor;\n"
                           "void main() { outColor = vColor * texture(uTexture, vUv); }\n",
                           "overlay");
        unsigned char* pixels = nullptr;
        int width = 0, height = 0;
        ImGui::GetIO().Fonts->GetTexDataAsRGBA32(&pixels, &width, &height);
        glGenTextures(1, &m_font);
        glBindTexture(GL_TEXTURE_2D, m_font);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA, width, height, 0, GL_RGBA, GL_UNSIGNED_BYTE, pixels);
        ImGui::GetIO().Fonts->SetTexID(reinterpret_cast<ImTextureID>(static_cast<std::intptr_t>(m_font)));
        glGenVertexArrays(1, &m_vao);
        glGenBuffers(1, &m_vbo);
        glGenBuffers(1, &m_ebo);
        glBindVertexArray(m_vao);
        glBindBuffer(GL_ARRAY_BUFFER, m_vbo);
        glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, m_ebo);
        glEnableVertexAttribArray(0);
        glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, sizeof(ImDrawVert),
                              reinterpret_cast<void*>(offsetof(ImDrawVert, pos)));
        glEnableVertexAttribArray(1);
        glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, sizeof(ImDrawVert),
                              reinterpret_cast<void*>(offsetof(ImDrawVert, uv)));
        glEnableVertexAttribArray(2);
        glVertexAttribPointer(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, sizeof(ImDrawVert),
                              reinterpret_cast<void*>(offsetof(ImDrawVert, col)));
        glBindVertexArray(0);
    }
    ~OverlayRenderer() {
        glDeleteBuffers(1, &m_ebo);
        glDeleteBuffers(1, &m_vbo);
        glDeleteVertexArrays(1, &m_vao);
        glDeleteTextures(1, &m_font);
        glDeleteProgram(m_program);
    }
    OverlayRenderer(const OverlayRenderer&) = delete;
    OverlayRenderer& operator=(const OverlayRenderer&) = delete;

    void draw(const ImDrawData* data) {
        const ImVec2 scale = data->FramebufferScale;
        const int width = int(data->DisplaySize.x * scale.x), height = int(data->DisplaySize.y * scale.y);
        if (width <= 0 || height <= 0) {
            return;
        }
        glBindFramebuffer(GL_FRAMEBUFFER, 0);
        glViewport(0, 0, width, height);
        glEnable(GL_BLEND);
        glBlendEquation(GL_FUNC_ADD);
        glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
        glDisable(GL_CULL_FACE);
        glDisable(GL_DEPTH_TEST);
        glEnable(GL_SCISSOR_TEST);
        glUseProgram(m_program);
        // pixels (origin top left) to clip space
        const float l = data->DisplayPos.x, r = l + data->DisplaySize.x, t = data->DisplayPos.y,
                    b = t + data->DisplaySize.y;
        const float projection[16] = {
            2.0f / (r - l),    0, 0,   0, 0, 2.0f / (t - b), 0, 0, 0, 0, -1.0f, 0, (r + l) / (l - r),
            (t + b) / (b - t), 0, 1.0f};
        glUniformMatrix4fv(glGetUniformLocation(m_program, "uProjection"), 1, GL_FALSE, projection);
        glUniform1i(glGetUniformLocation(m_program, "uTexture"), 0);
        glActiveTexture(GL_TEXTURE0);
        glBindVertexArray(m_vao);
        for (int n = 0; n < data->CmdListsCount; ++n) {
            const ImDrawList* list = data->CmdLists[n];
            glBindBuffer(GL_ARRAY_BUFFER, m_vbo);
            glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(list->VtxBuffer.Size) * GLsizeiptr(sizeof(ImDrawVert)),
                         list->VtxBuffer.Data, GL_STREAM_DRAW);
            glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, m_ebo);
            glBufferData(GL_ELEMENT_ARRAY_BUFFER,
                         GLsizeiptr(list->IdxBuffer.Size) * GLsizeiptr(sizeof(ImDrawIdx)),
                         list->IdxBuffer.Data, GL_STREAM_DRAW);
            for (const ImDrawCmd& cmd : list->CmdBuffer) {
                const float x0 = (cmd.ClipRect.x - l) * scale.x, y0 = (cmd.ClipRect.y - t) * scale.y,
                            x1 = (cmd.ClipRect.z - l) * scale.x, y1 = (cmd.ClipRect.w - t) * scale.y;
                if (x1 <= x0 || y1 <= y0) {
                    continue;
                }
                glScissor(int(x0), int(float(height) - y1), int(x1 - x0), int(y1 - y0));
                glBindTexture(GL_TEXTURE_2D, GLuint(reinterpret_cast<std::intptr_t>(cmd.TextureId)));
                glDrawElements(GL_TRIANGLES, GLsizei(cmd.ElemCount),
                               sizeof(ImDrawIdx) == 2 ? GL_UNSIGNED_SHORT : GL_UNSIGNED_INT,
                               reinterpret_cast<void*>(std::size_t(cmd.IdxOffset) * sizeof(ImDrawIdx)));
            }
        }
        glBindVertexArray(0);
        glDisable(GL_SCISSOR_TEST);
        glDisable(GL_BLEND);
    }

private:
    GLuint m_program = 0, m_font = 0, m_vao = 0, m_vbo = 0, m_ebo = 0;
};

/// An orbit camera about a target point.
struct OrbitCamera {
    Vec3 target;
    double distance = 5.0;
    double yaw = 0.0;   ///< rad, about y, 0 looking down -z
    double pitch = 0.0; ///< rad, above the horizon

    static OrbitCamera from(const SceneDef& scene) {
        OrbitCamera c;
        c.target = {scene.cameraTarget[0], scene.cameraTarget[1], scene.cameraTarget[2]};
        const Vec3 d = Vec3{scene.cameraEye[0], scene.cameraEye[1], scene.cameraEye[2]} - c.target;
        c.distance = std::max(length(d), 1e-3);
        c.pitch = std::asin(std::clamp(d.y / c.distance, -1.0, 1.0));
        c.yaw = std::atan2(d.x, d.z);
        return c;
    }
    Vec3 eye() const {
        return target +
               Vec3{std::cos(pitch) * std::sin(yaw), std::sin(pitch), std::cos(pitch) * std::cos(yaw)} *
                   distance;
    }
};

/// A ray from the eye through a window pixel, as the renderer's camera sees it.
struct Ray {
    Vec3 origin, direction; ///< direction is unit
};

Ray pixelRay(const SceneDef& scene, const Vec3& eye, const Vec3& target, double x, double y, int width,
             int height) {
    Vec3 f = target - eye;
    f = f * (1.0 / length(f));
    Vec3 up{0.0, 1.0, 0.0};
    if (std::abs(dot(f, up)) > 0.999) {
        up = {0.0, 0.0, -1.0}; // as the renderer's lookAt
    }
    Vec3 s = cross(f, up);
    s = s * (1.0 / length(s));
    const Vec3 u = cross(s, f);
    const double t = std::tan(scene.cameraFovDeg * std::numbers::pi / 360.0);
    const double aspect = double(width) / double(height);
    const double nx = 2.0 * x / width - 1.0, ny = 1.0 - 2.0 * y / height;
    Vec3 d = f + s * (nx * t * aspect) + u * (ny * t);
    return {eye, d * (1.0 / length(d))};
}

/// Where a point is drawn in the window (pixels, origin top left), and how far in front of the eye; nullopt
/// behind it.
std::optional<std::array<double, 3>> project(const std::array<float, 16>& m, const Vec3& p, int width,
                                             int height) {
    const double cx = m[0] * p.x + m[4] * p.y + m[8] * p.z + m[12];
    const double cy = m[1] * p.x + m[5] * p.y + m[9] * p.z + m[13];
    const double cw = m[3] * p.x + m[7] * p.y + m[11] * p.z + m[15];
    if (cw <= 1e-6) {
        return std::nullopt;
    }
    return std::array<double, 3>{(cx / cw + 1.0) * 0.5 * width, (1.0 - cy / cw) * 0.5 * height, cw};
}

/// A body's extent in its own frame: the box that holds its shape (exact for boxes), m.
struct LocalBox {
    Vec3 lo, hi;
};

LocalBox localBox(const RigidBody& b) {
    switch (b.shape) {
    case ShapeKind::Box:
        return {-b.halfExtents, b.halfExtents};
    case ShapeKind::Sphere:
        return {Vec3{-1, -1, -1} * b.radius, Vec3{1, 1, 1} * b.radius};
    case ShapeKind::Capsule:
    case ShapeKind::Cylinder: {
        const double half = 0.5 * b.height + (b.shape == ShapeKind::Capsule ? b.radius : 0.0);
        return {{-b.radius, -half, -b.radius}, {b.radius, half, b.radius}};
    }
    case ShapeKind::Convex:
    case ShapeKind::Mesh:
        if (b.mesh) {
            return {b.mesh->lo, b.mesh->hi};
        }
        break;
    case ShapeKind::Plane:
        break;
    }
    return {};
}

/// A 2D body is drawn as a slab half a metre deep about its entity's z.
LocalBox localBox(const RigidBody2D& b) {
    constexpr double kHalfDepth = 0.25;
    switch (b.shape) {
    case Shape2DKind::Box:
        return {{-b.halfExtents[0], -b.halfExtents[1], -kHalfDepth},
                {b.halfExtents[0], b.halfExtents[1], kHalfDepth}};
    case Shape2DKind::Circle:
        return {{-b.radius, -b.radius, -kHalfDepth}, {b.radius, b.radius, kHalfDepth}};
    case Shape2DKind::Polygon: {
        LocalBox box{{1e300, 1e300, -kHalfDepth}, {-1e300, -1e300, kHalfDepth}};
        for (const Vec2& v : b.vertices) {
            box.lo = {std::min(box.lo.x, v[0]), std::min(box.lo.y, v[1]), -kHalfDepth};
            box.hi = {std::max(box.hi.x, v[0]), std::max(box.hi.y, v[1]), kHalfDepth};
        }
        return box;
    }
    case Shape2DKind::Edge:
        break;
    }
    return {};
}

/// Where a ray first meets a box given in a body's frame (slab test), as the distance along the ray and
/// the point in the body's frame; nullopt if it misses or the eye is inside.
std::optional<std::pair<double, Vec3>> hitBox(const Ray& ray, const Vec3& position, const Quat& orientation,
                                              const LocalBox& box) {
    const Quat inverse = conjugate(orientation);
    const Vec3 o = rotate(inverse, ray.origin - position), d = rotate(inverse, ray.direction);
    double near = 0.0, far = 1e300;
    const double os[3] = {o.x, o.y, o.z}, ds[3] = {d.x, d.y, d.z}, lo[3] = {box.lo.x, box.lo.y, box.lo.z},
                 hi[3] = {box.hi.x, box.hi.y, box.hi.z};
    for (int k = 0; k < 3; ++k) {
        if (!(hi[k] > lo[k])) {
            return std::nullopt; // no extent: nothing to hold
        }
        if (std::abs(ds[k]) < 1e-15) {
            if (os[k] < lo[k] || os[k] > hi[k]) {
                return std::nullopt;
            }
            continue;
        }
        double t0 = (lo[k] - os[k]) / ds[k], t1 = (hi[k] - os[k]) / ds[k];
        if (t0 > t1) {
            std::swap(t0, t1);
        }
        near = std::max(near, t0);
        far = std::min(far, t1);
        if (near > far) {
            return std::nullopt;
        }
    }
    if (near <= 0.0) {
        return std::nullopt;
    }
    return std::pair{near, o + d * near};
}

/// The first hit of a ray on a sphere, or nullopt.
std::optional<double> hitSphere(const Ray& ray, const Vec3& centre, double radius) {
    const Vec3 oc = ray.origin - centre;
    const double b = dot(oc, ray.direction), c = dot(oc, oc) - radius * radius;
    const double disc = b * b - c;
    if (radius <= 0.0 || disc < 0.0) {
        return std::nullopt;
    }
    const double t = -b - std::sqrt(disc);
    return t > 0.0 ? std::optional<double>(t) : std::nullopt;
}

/// Where a ray first meets a triangle (Moller-Trumbore), either side, or nullopt.
std::optional<double> hitTriangle(const Ray& ray, const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 e1 = b - a, e2 = c - a;
    const Vec3 p = cross(ray.direction, e2);
    const double det = dot(e1, p);
    if (std::abs(det) < 1e-12) {
        return std::nullopt;
    }
    const double inv = 1.0 / det;
    const Vec3 s = ray.origin - a;
    const double u = dot(s, p) * inv;
    if (u < 0.0 || u > 1.0) {
        return std::nullopt;
    }
    const Vec3 q = cross(s, e1);
    const double v = dot(ray.direction, q) * inv;
    if (v < 0.0 || u + v > 1.0) {
        return std::nullopt;
    }
    const double t = dot(e2, q) * inv;
    return t > 0.0 ? std::optional<double>(t) : std::nullopt;
}

/// What a click picked: the entity, its grab event's value, and the picked point.
struct Pick {
    Entity entity;
    std::string name;
    std::vector<double> value;
    Vec3 point;
    double depth = 0.0; ///< m from the eye
};

constexpr double kPickPixels = 14.0; ///< how near a mass or an emitter a click must be

/// A mass of a spring network under the cursor, and its distance from the eye along the ray.
struct NetworkPick {
    std::uint32_t mass = 0;
    double depth = 0.0; ///< m
};

/// A surface (cloth): the free corner nearest to where the ray first meets it.
std::optional<NetworkPick> pickSurface(const SpringNetwork& net, const Ray& ray) {
    std::optional<NetworkPick> best;
    for (const auto& t : net.triangles) {
        const std::optional<double> hit = hitTriangle(ray, net.x[t[0]], net.x[t[1]], net.x[t[2]]);
        if (!hit || (best && *hit >= best->depth)) {
            continue;
        }
        const Vec3 p = ray.origin + ray.direction * *hit;
        std::optional<std::uint32_t> free;
        for (std::uint32_t i : t) {
            if (!net.pinned[i] && (!free || length(net.x[i] - p) < length(net.x[*free] - p))) {
                free = i;
            }
        }
        if (free) {
            best = NetworkPick{*free, *hit};
        }
    }
    return best;
}

/// Masses alone (springs, ropes, jelly): the nearest free mass within a few pixels of the click.
std::optional<NetworkPick> pickMass(const SpringNetwork& net, const std::array<float, 16>& vp,
                                    const RenderOutput& out, double x, double y, const Vec3& eye) {
    std::optional<NetworkPick> found;
    double foundPixels = kPickPixels;
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        if (net.pinned[i]) {
            continue;
        }
        if (auto p = project(vp, net.x[i], out.width, out.height)) {
            const double pixels = std::hypot((*p)[0] - x, (*p)[1] - y);
            if (pixels < foundPixels) {
                // the distance along the ray, as the other picks measure it
                found = NetworkPick{std::uint32_t(i), length(net.x[i] - eye)};
                foundPixels = pixels;
            }
        }
    }
    return found;
}

std::optional<Pick> pickAt(World& world, const SceneDef& scene, const RenderOutput& out, double x, double y) {
    const Vec3 eye{out.eye[0], out.eye[1], out.eye[2]};
    const Vec3 target{out.target[0], out.target[1], out.target[2]};
    const Ray ray = pixelRay(scene, eye, target, x, y, out.width, out.height);
    const std::array<float, 16> vp = viewProjection(scene, &out);
    std::optional<Pick> best;
    auto offer = [&](Entity e, std::vector<double> value, const Vec3& point, double depth) {
        if (!best || depth < best->depth) {
            const Name* name = world.tryGet<Name>(e);
            best = Pick{e, name ? name->value : std::string(), std::move(value), point, depth};
        }
    };
    world.view<const SpringNetwork>().each([&](Entity e, const SpringNetwork& net) {
        const std::optional<NetworkPick> p =
            net.triangles.empty() ? pickMass(net, vp, out, x, y, eye) : pickSurface(net, ray);
        if (p) {
            offer(e, {double(p->mass)}, net.x[p->mass], p->depth);
        }
    });
    world.view<const ParticleEmitter>().each([&](Entity e, const ParticleEmitter& emitter) {
        if (auto p = project(vp, emitter.origin, out.width, out.height)) {
            if (std::hypot((*p)[0] - x, (*p)[1] - y) < kPickPixels * 1.5) {
                offer(e, {}, emitter.origin, length(emitter.origin - eye));
            }
        }
    });
    world.view<const RigidBody>().each([&](Entity e, const RigidBody& b) {
        if (!b.dynamic() || b.frozen) {
            return;
        }
        if (b.shape == ShapeKind::Sphere) {
            if (auto t = hitSphere(ray, b.position, b.radius)) {
                const Vec3 hit = ray.origin + ray.direction * *t;
                const Vec3 local = rotate(conjugate(b.orientation), hit - b.position);
                offer(e, {local.x, local.y, local.z}, hit, *t);
            }
        } else if (auto h = hitBox(ray, b.position, b.orientation, localBox(b))) {
            // the box that holds the shape (exact for boxes): the held point is on or near the surface
            offer(e, {h->second.x, h->second.y, h->second.z}, ray.origin + ray.direction * h->first,
                  h->first);
        }
    });
    world.view<const RigidBody2D, const Transform>().each(
        [&](Entity e, const RigidBody2D& b, const Transform& tr) {
            if (!b.dynamic()) {
                return;
            }
            const Vec3 centre{b.position[0], b.position[1], tr.position.z};
            if (auto h = hitBox(ray, centre, aboutZ(b.angle), localBox(b))) {
                const Vec3 hit = ray.origin + ray.direction * h->first;
                offer(e, {h->second.x, h->second.y}, {hit.x, hit.y, centre.z}, h->first);
            }
        });
    return best;
}

/// Where a ray meets the plane through `point` facing the camera, or nullopt (parallel, or behind).
std::optional<Vec3> onDragPlane(const Ray& ray, const Vec3& point, const Vec3& forward) {
    const double denom = dot(ray.direction, forward);
    if (std::abs(denom) < 1e-9) {
        return std::nullopt;
    }
    const double t = dot(point - ray.origin, forward) / denom;
    return t > 0.0 ? std::optional<Vec3>(ray.origin + ray.direction * t) : std::nullopt;
}

/// The clock the fixed-step loop reads: wall time, scaled by the speed, standing still while paused.
class ViewClock final : public Clock {
public:
    std::int64_t nowNs() const override { return m_ns; }
    void advance(std::int64_t wallNs, double speed) { m_ns += std::int64_t(double(wallNs) * speed); }

private:
    std::int64_t m_ns = 0;
};

/// The replay of one session (from the start or the last reset); FILE, then FILE-2, FILE-3 after resets.
std::string sessionPath(const std::string& base, int session) {
    if (session <= 1) {
        return base;
    }
    const std::filesystem::path p(base);
    return (p.parent_path() / (p.stem().string() + "-" + std::to_string(session) + p.extension().string()))
        .string();
}

/// Input gathered by GLFW's callbacks between two frames.
struct InputState {
    std::vector<int> keys; ///< keys pressed
    double scroll = 0.0;
    /// where the cursor was (window coordinates) at the first left press since the last frame: a slow frame
    /// must not pick where the cursor has moved on to since (a press, then a drag, all within one frame).
    /// Taken from the motion events before the press: glfwGetCursorPos asks X where the pointer is now
    std::optional<std::array<double, 2>> leftPress;
    std::optional<std::array<double, 2>> cursor; ///< as of the last motion event handled
};

InputState* g_input = nullptr;

/// The viewer's state between frames.
class Viewer {
public:
    Viewer(const Catalog& catalog, const ViewRequest& request) : m_catalog(catalog), m_request(request) {}

    int run();

private:
    void startSession();
    void openRecorder();
    void finishSession();
    void handleKeys();
    void handleMouse();
    void pressLeft(double x, double y);
    void pan(double dx, double dy);
    void dragHeld(double x, double y);
    bool addEvent(const std::string& entity, const std::string& action, std::vector<double> value,
                  const Vec3& position);
    void step();
    void drawOverlay();
    void updateOutput();
    bool openWindow();
    void closeWindow();
    bool frame(OverlayRenderer& overlay, const Clock& wall, std::int64_t& lastNs);
    int runWindow();

    const Catalog& m_catalog;
    const ViewRequest& m_request;
    GLFWwindow* m_window = nullptr;
    std::unique_ptr<Simulation> m_sim;
    std::unique_ptr<ReplayWriter> m_recorder;
    std::vector<std::string> m_recordings;
    int m_session = 0;
    std::unique_ptr<FixedLoop> m_loop;
    ViewClock m_clock;
    OrbitCamera m_camera;
    bool m_paused = false;
    bool m_slow = false;
    bool m_quit = false;
    bool m_wireframe = false;
    std::uint64_t m_simFrames = 0; ///< whole frames (substeps steps) simulated this session
    std::int64_t m_droppedNs = 0;
    // the mouse
    enum class Drag { None, Orbit, Pan, Hold } m_drag = Drag::None;
    double m_mouseX = 0.0, m_mouseY = 0.0;
    std::optional<Pick> m_held;
    Vec3 m_heldTarget;
    std::string m_selected; ///< the spring network I acts on: the last one held
    std::string m_status;   ///< the last thing said, shown in the overlay
    std::vector<EntityHash> m_entities;
    InputState m_input;  ///< what GLFW's callbacks gathered since the last frame
    ReportDrain m_drain; ///< what this session's run said so far
};

void Viewer::startSession() {
    m_sim.reset(); // the old scene's memory (and GL objects) go before the new one is built
    m_sim = std::make_unique<Simulation>(m_catalog, m_request.scenarioPath, m_request.scenarioText,
                                         m_request.sets, m_request.memoryCap, m_request.threads);
    const SceneDef& scene = m_sim->scene();
    // room for twice a frame's steps: paced at 60 Hz, a frame that wakes a little early takes no step and
    // the next one owes two; with a cap of one frame's steps that step would be dropped every time
    m_loop = std::make_unique<FixedLoop>(secondsToNs(scene.dt), 2 * scene.substeps);
    m_loop->advanceTo(m_clock); // starts the loop's clock
    m_simFrames = 0;
    m_droppedNs = 0;
    m_held.reset();
    m_drag = Drag::None;
    m_drain = ReportDrain{};
    RenderOutput& out = m_sim->world().setResource<RenderOutput>();
    out.enabled = true;
    out.externalContext = true;
    out.keepFrames = false;
}

void Viewer::openRecorder() {
    ++m_session;
    if (!m_request.record.empty()) {
        const std::string path = sessionPath(m_request.record, m_session);
        m_recorder = std::make_unique<ReplayWriter>(
            path, ReplayHeader{kReplayVersion, buildId(), m_request.scenarioPath, m_request.scenarioText,
                               m_request.sets});
    }
}

void Viewer::finishSession() {
    if (m_recorder) {
        m_recorder->finish();
        m_recordings.push_back(m_recorder->path() + " (" + std::to_string(m_recorder->frames()) + " frames)");
        m_recorder.reset();
    }
}

bool Viewer::addEvent(const std::string& entity, const std::string& action, std::vector<double> value,
                      const Vec3& position) {
    EventDef ev;
    ev.step = m_sim->step(); // applies at the start of the next step
    ev.entity = entity;
    ev.action = action;
    ev.value = std::move(value);
    ev.position = {position.x, position.y, position.z};
    if (auto problem = resolveEvent(m_catalog, m_sim->world(), ev, {})) {
        m_status = "cannot " + action + " '" + entity + "': " + *problem;
        return false;
    }
    m_sim->addEvents({ev});
    return true;
}

/// One fixed step, and the replay's frame when it completes one.
void Viewer::step() {
    m_sim->runStep();
    const auto substeps = static_cast<std::uint64_t>(m_sim->scene().substeps);
    if (m_sim->step() % substeps != 0) {
        return;
    }
    ++m_simFrames;
    std::vector<EventDef> applied = m_sim->takeAppliedEvents();
    if (m_recorder) {
        const std::uint64_t hash = frameHashes(m_sim->world(), m_catalog, m_entities, m_sim->pool());
        m_recorder->frame(FrameRecord{std::move(applied), hash, m_entities});
    }
}

void Viewer::handleKeys() {
    for (int key : g_input->keys) {
        switch (key) {
        case GLFW_KEY_SPACE:
        case GLFW_KEY_P:
            m_paused = !m_paused;
            break;
        case GLFW_KEY_N:
            m_paused = true;
            m_sim->beginFrame();
            step();
            m_sim->endFrame(1.0);
            break;
        case GLFW_KEY_R:
            finishSession();
            startSession();
            openRecorder();
            updateOutput();
            m_status = m_recorder ? "reset: recording to " + m_recorder->path() : "reset";
            break;
        case GLFW_KEY_S:
            m_slow = !m_slow;
            break;
        case GLFW_KEY_W:
            m_wireframe = !m_wireframe;
            break;
        case GLFW_KEY_I: {
            // the selected network, else the first one
            World& world = m_sim->world();
            std::string name = m_selected;
            int current = -1;
            bool fem = false;
            world.view<const Name, const SpringNetwork>().each(
                [&](Entity, const Name& n, const SpringNetwork& net) {
                    if ((name.empty() && current < 0) || n.value == name) {
                        name = n.value;
                        current = static_cast<int>(net.integrator);
                        fem = net.kind == NetworkKind::Fem;
                    }
                });
            if (current < 0) {
                m_status = "no spring network to change the integrator of";
                break;
            }
            // an fem body has two: symplectic and implicit Euler
            const auto symplectic = static_cast<int>(Integrator::SymplecticEuler);
            const auto implicit = static_cast<int>(Integrator::ImplicitEuler);
            const int next =
                fem ? (current == implicit ? symplectic : implicit) : (current + 1) % kIntegratorCount;
            if (addEvent(name, "set_integrator", {double(next)}, {})) {
                m_status = "'" + name + "' now integrates with " +
                           std::string(integratorName(static_cast<Integrator>(next)));
            }
            break;
        }
        case GLFW_KEY_Q:
        case GLFW_KEY_ESCAPE:
            m_quit = true;
            break;
        default:
            break;
        }
    }
    g_input->keys.clear();
}

void Viewer::updateOutput() {
    RenderOutput& out = m_sim->world().resource<RenderOutput>();
    int width = 0, height = 0;
    glfwGetFramebufferSize(m_window, &width, &height);
    out.width = std::max(width, 1);
    out.height = std::max(height, 1);
    out.cameraSet = true;
    const Vec3 eye = m_camera.eye();
    out.eye = {eye.x, eye.y, eye.z};
    out.target = {m_camera.target.x, m_camera.target.y, m_camera.target.z};
    out.wireframe = m_wireframe;
}

/// A left press: hold what is under the cursor (a grab event), or orbit when nothing is.
void Viewer::pressLeft(double x, double y) {
    const RenderOutput& out = m_sim->world().resource<RenderOutput>();
    m_held = pickAt(m_sim->world(), m_sim->scene(), out, x, y);
    if (m_held && !addEvent(m_held->name, "grab", m_held->value, m_held->point)) {
        m_held.reset(); // said why in the status line
    }
    if (!m_held) {
        m_drag = Drag::Orbit;
        return;
    }
    m_drag = Drag::Hold;
    m_heldTarget = m_held->point;
    const bool network = m_sim->world().has<SpringNetwork>(m_held->entity);
    if (network) {
        m_selected = m_held->name;
    }
    m_status =
        "holding '" + m_held->name + "'" +
        (network ? " by mass " + std::to_string(static_cast<long long>(m_held->value[0])) : std::string());
}

/// Moves the camera's target across the view by the cursor's motion in pixels.
void Viewer::pan(double dx, double dy) {
    const RenderOutput& out = m_sim->world().resource<RenderOutput>();
    const Vec3 eye = m_camera.eye();
    Vec3 f = m_camera.target - eye;
    f = f * (1.0 / length(f));
    Vec3 s = cross(f, Vec3{0.0, 1.0, 0.0});
    s = s * (1.0 / std::max(length(s), 1e-9));
    const Vec3 u = cross(s, f);
    const double perPixel = 2.0 * m_camera.distance *
                            std::tan(m_sim->scene().cameraFovDeg * std::numbers::pi / 360.0) /
                            std::max(out.height, 1);
    m_camera.target += (s * -dx + u * dy) * perPixel;
}

/// Moves the held point to where the cursor meets the plane through it facing the camera (a drag event).
void Viewer::dragHeld(double x, double y) {
    const RenderOutput& out = m_sim->world().resource<RenderOutput>();
    const Vec3 eye{out.eye[0], out.eye[1], out.eye[2]};
    const Vec3 target{out.target[0], out.target[1], out.target[2]};
    Vec3 forward = target - eye;
    forward = forward * (1.0 / length(forward));
    const Ray ray = pixelRay(m_sim->scene(), eye, target, x, y, out.width, out.height);
    if (auto p = onDragPlane(ray, m_heldTarget, forward); p && length(*p - m_heldTarget) > 1e-6) {
        m_heldTarget = *p;
        addEvent(m_held->name, "drag", {}, *p);
    }
}

void Viewer::handleMouse() {
    const ImGuiIO& io = ImGui::GetIO();
    double x = 0.0, y = 0.0;
    glfwGetCursorPos(m_window, &x, &y);
    int winW = 1, winH = 1, fbW = 1, fbH = 1;
    glfwGetWindowSize(m_window, &winW, &winH);
    glfwGetFramebufferSize(m_window, &fbW, &fbH);
    // cursor in framebuffer pixels (the same on X11, not on a scaled display)
    x *= double(fbW) / std::max(winW, 1);
    y *= double(fbH) / std::max(winH, 1);
    const double dx = x - m_mouseX, dy = y - m_mouseY;
    m_mouseX = x;
    m_mouseY = y;
    const bool left = glfwGetMouseButton(m_window, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
    const bool right = glfwGetMouseButton(m_window, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS ||
                       glfwGetMouseButton(m_window, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS;
    const std::optional<std::array<double, 2>> press = std::exchange(g_input->leftPress, std::nullopt);
    if (m_drag == Drag::None && !io.WantCaptureMouse) {
        if (press) {
            // where the press was, in framebuffer pixels (a press and release within one frame still holds)
            pressLeft((*press)[0] * double(fbW) / std::max(winW, 1),
                      (*press)[1] * double(fbH) / std::max(winH, 1));
        } else if (left) {
            pressLeft(x, y);
        } else if (right) {
            m_drag = Drag::Pan;
        }
    }
    switch (m_drag) {
    case Drag::Orbit:
        if (!left) {
            m_drag = Drag::None;
            break;
        }
        m_camera.yaw -= dx * 0.008;
        m_camera.pitch = std::clamp(m_camera.pitch + dy * 0.008, -1.5, 1.5);
        break;
    case Drag::Pan:
        if (!right) {
            m_drag = Drag::None;
            break;
        }
        pan(dx, dy);
        break;
    case Drag::Hold:
        if (!left) {
            addEvent(m_held->name, "release", {}, {});
            m_status = "let go of '" + m_held->name + "'";
            m_held.reset();
            m_drag = Drag::None;
            break;
        }
        dragHeld(x, y);
        break;
    case Drag::None:
        break;
    }
    if (g_input->scroll != 0.0 && !io.WantCaptureMouse) {
        m_camera.distance = std::clamp(m_camera.distance * std::pow(0.9, g_input->scroll), 0.05, 1e4);
    }
    g_input->scroll = 0.0;
}

void Viewer::drawOverlay() {
    const SceneDef& scene = m_sim->scene();
    const Profiler& profiler = m_sim->profiler();
    const double budget = profiler.budgetMs();
    const std::size_t window = std::size_t(60 * scene.substeps);
    ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_Always);
    ImGui::SetNextWindowBgAlpha(0.85f);
    ImGui::Begin("budget", nullptr,
                 ImGuiWindowFlags_AlwaysAutoResize | ImGuiWindowFlags_NoMove |
                     ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoFocusOnAppearing);
    ImGui::Text("%s  frame %llu  %.2f s  %s%s", scene.name.c_str(),
                static_cast<unsigned long long>(m_simFrames), m_sim->time(), m_paused ? "PAUSED" : "",
                m_slow ? " x1/4" : "");
    // physics a frame against the budget: a bar, then each fixed-phase system's share
    const std::vector<float> history = profiler.recentPhysics(240);
    const float last = history.empty() ? 0.0f : history.back();
    double recent = 0.0;
    for (std::size_t i = history.size() > 30 ? history.size() - 30 : 0; i < history.size(); ++i) {
        recent = std::max(recent, double(history[i]));
    }
    char label[96];
    std::snprintf(label, sizeof label, "physics %.3f ms of %.1f", double(last), budget);
    ImGui::ProgressBar(float(std::min(1.0, double(last) / budget)), ImVec2(200, 0), label);
    // the systems that take the most, largest first; the rest are summed on one line
    std::vector<RecentSlot> systems;
    for (RecentSlot& s : profiler.recentStats(window)) {
        if (!s.isPhase && s.phase == Phase::Fixed) {
            systems.push_back(std::move(s));
        }
    }
    std::stable_sort(systems.begin(), systems.end(),
                     [](const RecentSlot& a, const RecentSlot& b) { return a.meanMs > b.meanMs; });
    constexpr std::size_t kShown = 5;
    double others = 0.0;
    for (std::size_t i = 0; i < systems.size(); ++i) {
        const double perFrame = systems[i].meanMs * scene.substeps;
        if (i >= kShown) {
            others += perFrame;
            continue;
        }
        std::snprintf(label, sizeof label, "%.3f ms", perFrame);
        ImGui::ProgressBar(float(std::min(1.0, perFrame / budget)), ImVec2(130, 0), label);
        ImGui::SameLine();
        ImGui::TextUnformatted(systems[i].name.c_str());
    }
    if (systems.size() > kShown) {
        ImGui::Text("%zu more systems: %.3f ms", systems.size() - kShown, others);
    }
    std::snprintf(label, sizeof label, "max %.2f ms", recent);
    ImGui::PlotLines("##physics", history.data(), int(history.size()), 0, label, 0.0f,
                     float(std::max(budget * 1.25, recent * 1.1)), ImVec2(200, 40));
    ImGui::SameLine();
    ImGui::TextUnformatted("physics ms\na frame");
    if (m_droppedNs > 0) {
        ImGui::Text("behind real time by %.2f s", double(m_droppedNs) * 1e-9);
    }
    if (!m_status.empty()) {
        ImGui::PushTextWrapPos(320.0f);
        ImGui::TextUnformatted(m_status.c_str());
        ImGui::PopTextWrapPos();
    }
    ImGui::TextDisabled("Space pause  N step  R reset  S slow\nW wire  I integrator  Q quit");
    ImGui::End();
}

/// The window, its GLES 3 context (through EGL, as the headless renderer's) and Dear ImGui; false, having
/// said why, when there is no display or no context to be had.
bool Viewer::openWindow() {
    if (!std::getenv("DISPLAY") && !std::getenv("WAYLAND_DISPLAY")) {
        std::fprintf(stderr,
                     "tumble: view needs a display, and there is none here (DISPLAY is not set); "
                     "`tumble run %s` simulates headlessly and writes PNG frames (--png-every, --video)\n",
                     m_request.scenarioPath.c_str());
        return false;
    }
    glfwSetErrorCallback([](int, const char* message) { g_glfwError = message; });
    if (!glfwInit()) {
        std::fprintf(stderr,
                     "tumble: view cannot open a window here (%s); `tumble run %s` simulates headlessly\n",
                     g_glfwError.c_str(), m_request.scenarioPath.c_str());
        return false;
    }
    const SceneDef& scene = m_sim->scene();
    glfwWindowHint(GLFW_CLIENT_API, GLFW_OPENGL_ES_API);
    glfwWindowHint(GLFW_CONTEXT_CREATION_API, GLFW_EGL_CONTEXT_API);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 0);
    const std::string title = "tumble view: " + scene.name;
    m_window = glfwCreateWindow(scene.renderWidth, scene.renderHeight, title.c_str(), nullptr, nullptr);
    if (!m_window) {
        glfwTerminate();
        std::fprintf(stderr,
                     "tumble: view cannot open a window with an OpenGL ES 3 context (%s); `tumble run %s` "
                     "simulates headlessly\n",
                     g_glfwError.c_str(), m_request.scenarioPath.c_str());
        return false;
    }
    glfwMakeContextCurrent(m_window);
    glfwSwapInterval(0); // paced by the frame pacer, so that a display without vsync (Xvfb) runs at 60 fps
    g_input = &m_input;
    glfwSetKeyCallback(m_window, [](GLFWwindow*, int key, int, int action, int) {
        if (action == GLFW_PRESS && !ImGui::GetIO().WantTextInput) {
            g_input->keys.push_back(key);
        }
    });
    glfwSetScrollCallback(m_window, [](GLFWwindow*, double, double y) { g_input->scroll += y; });
    glfwSetCursorPosCallback(m_window, [](GLFWwindow*, double x, double y) {
        g_input->cursor = std::array{x, y};
    });
    glfwSetMouseButtonCallback(m_window, [](GLFWwindow* window, int button, int action, int) {
        if (button == GLFW_MOUSE_BUTTON_LEFT && action == GLFW_PRESS && !g_input->leftPress) {
            std::array<double, 2> at{};
            if (g_input->cursor) {
                at = *g_input->cursor;
            } else {
                glfwGetCursorPos(window, &at[0], &at[1]); // no motion seen yet: where it is
            }
            g_input->leftPress = at;
        }
    });
    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;
    ImGui::StyleColorsDark();
    ImGui_ImplGlfw_InitForOther(m_window, true); // chains to the callbacks above
    return true;
}

void Viewer::closeWindow() {
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
    glfwDestroyWindow(m_window);
    glfwTerminate();
    g_input = nullptr;
}

/// One frame of the window: input, the steps the (scaled) time since the last frame completes (at most a
/// frame's worth), what the run said, the scene and the overlay. False when the user quits.
bool Viewer::frame(OverlayRenderer& overlay, const Clock& wall, std::int64_t& lastNs) {
    glfwPollEvents();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
    handleKeys();
    if (m_quit) {
        ImGui::EndFrame();
        return false;
    }
    updateOutput();
    handleMouse();
    updateOutput();
    const std::int64_t now = wall.nowNs();
    m_clock.advance(now - lastNs, m_paused ? 0.0 : (m_slow ? 0.25 : 1.0));
    lastNs = now;
    const Tick tick = m_loop->advanceTo(m_clock);
    m_droppedNs += tick.droppedNs;
    m_sim->beginFrame();
    for (int i = 0; i < tick.steps; ++i) {
        step();
    }
    m_sim->endFrame(m_paused ? 1.0 : tick.alpha);
    m_drain.drain(m_sim->world().resource<RunReport>(), [&](const std::string& said, bool failure) {
        std::fprintf(stderr, "tumble: %s: %s\n", failure ? "error" : "note", said.c_str());
        m_status = said.substr(0, 120);
    });
    int width = 0, height = 0;
    glfwGetFramebufferSize(m_window, &width, &height);
    presentImage(m_sim->world(), width, height);
    drawOverlay();
    ImGui::Render();
    overlay.draw(ImGui::GetDrawData());
    glfwSwapBuffers(m_window);
    return true;
}

/// Frames at 60 Hz until the window closes, Q, or the first Ctrl-C (which closes as Q does; a second one
/// kills); then the replay and the budget summary. Returns the exit code.
int Viewer::runWindow() {
    OverlayRenderer overlay;
    openRecorder();
    m_camera = OrbitCamera::from(m_sim->scene());
    m_paused = m_request.paused;
    std::printf("tumble: viewing '%s'%s; Q or Esc quits\n", m_sim->scene().name.c_str(),
                m_request.record.empty() ? "" : (", recording to " + m_request.record).c_str());
    std::fflush(stdout);
    const StopSignal stop;
    const SteadyClock wall;
    std::int64_t lastNs = wall.nowNs();
    FramePacer pacer(wall, 1'000'000'000 / 60);
    while (!glfwWindowShouldClose(m_window) && !stop.requested() && frame(overlay, wall, lastNs)) {
        pacer.wait();
    }
    finishSession();
    int status = kExitOk;
    if (!m_request.profile.empty()) {
        std::ofstream profile(m_request.profile);
        profile << budgetSummaryJson(m_sim->profiler(), m_sim->scene(), m_sim->frame(), m_sim->threads());
        if (!profile) {
            std::fprintf(stderr, "tumble: cannot write %s\n", m_request.profile.c_str());
            status = kExitFailure;
        } else {
            m_recordings.push_back(m_request.profile + " (the budget summary)");
        }
    }
    // the renderer frees its GL objects while the window's context is still current
    m_sim.reset();
    return status;
}

int Viewer::run() {
    // the scene first: a scenario error is the user's (exit 2) whether or not there is a display; the
    // outputs once there is a window, so that a run that cannot open one overwrites nothing
    startSession();
    if (!m_request.profile.empty() && !std::ofstream(m_request.profile, std::ios::app)) {
        std::fprintf(stderr, "tumble: cannot write %s\n", m_request.profile.c_str());
        return kExitFailure;
    }
    if (!openWindow()) {
        return kExitFailure;
    }
    int status = kExitOk;
    try {
        status = runWindow();
    } catch (...) {
        // keep what was recorded (the replay ends properly), close the window, then say what happened
        try {
            finishSession();
        } catch (...) {
        }
        m_sim.reset();
        closeWindow();
        throw;
    }
    closeWindow();
    for (const std::string& w : m_recordings) {
        std::printf("wrote %s\n", w.c_str());
    }
    return status;
}

} // namespace

int runViewer(const Catalog& catalog, const ViewRequest& request) {
    Viewer viewer(catalog, request);
    return viewer.run();
}

} // namespace tumble
