// Rendering the curtain demo at 1280 x 720 on this machine's GL (llvmpipe here): one frame drawn and read
// back by the renderer, and, for the ratio, a raw EGL program drawing the same triangles (the cloth and
// the ground) with the renderer's own shader and reading them back: the difference is the renderer's
// work around the draw (normals, uploads, state), not its shading. Then the curtain and avalanche frames
// as the demos have them (shadows, 4x multisampling) against the same frames with both off. The
// renderer's frames report their two parts: draw_ms (drawn and waited for) and read_ms (the multisampled
// image resolved, read back and turned top row first). Last, the raw program at 4 samples a pixel, with the
// renderer's shading and with one colour: the floor under any multisampled frame of the curtain here.
//   build/tests/bench/tumble_bench --benchmark_filter=Render --benchmark_repetitions=5

#include "app/gl_context.h"
#include "components/rigid_body.h"
#include "components/spring_network.h"
#include "engine/assets.h"
#include "engine/render_output.h"
#include "engine/simulation.h"
#include "systems/builtin.h"
#include "systems/render_system.h"
#include "tests/bench/bench_support.h"

#include <GLES3/gl3.h>
#include <benchmark/benchmark.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <string>

namespace tumble {
namespace {

std::unique_ptr<Simulation> settledDemo(bool render, const std::string& demo = "curtain",
                                        const std::vector<std::string>& sets = {}) {
    const Catalog& catalog = bench::builtinCatalog();
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/" + demo + ".toml";
    auto sim = std::make_unique<Simulation>(catalog, path, readScenarioFile(path), sets);
    RenderOutput& out = sim->world().setResource<RenderOutput>();
    out.enabled = render;
    out.openContext = openHeadlessContext;
    out.lastFrame = 0; // no PNG files
    for (int i = 0; i < 60; ++i) {
        sim->runFrame();
    }
    return sim;
}

/// One frame of a demo after 60, drawn and read back, again and again.
void renderFrames(benchmark::State& state, const std::string& demo, const std::vector<std::string>& sets) {
    auto sim = settledDemo(true, demo, sets);
    StepContext ctx;
    std::vector<std::uint8_t> pixels;
    int w = 0, h = 0;
    // the frame in two parts: drawn (renderWorld waits for it, glFinish), then resolved and read back
    using Clock = std::chrono::steady_clock;
    double drawMs = 0.0, readMs = 0.0;
    for (auto _ : state) {
        const auto start = Clock::now();
        renderWorld(sim->world(), ctx);
        const auto drawn = Clock::now();
        lastImage(sim->world(), w, h, pixels);
        benchmark::DoNotOptimize(pixels.data());
        drawMs += std::chrono::duration<double, std::milli>(drawn - start).count();
        readMs += std::chrono::duration<double, std::milli>(Clock::now() - drawn).count();
    }
    state.counters["pixels"] = double(w) * double(h);
    state.counters["draw_ms"] = drawMs / double(state.iterations());
    state.counters["read_ms"] = readMs / double(state.iterations());
}

const std::vector<std::string> kPlain{"render.shadows=false", "render.msaa=1"};

void BM_RenderCurtainShadowsMsaa(benchmark::State& state) {
    renderFrames(state, "curtain", {});
}
BENCHMARK(BM_RenderCurtainShadowsMsaa)->Unit(benchmark::kMillisecond)->Iterations(40);

void BM_RenderAvalancheShadowsMsaa(benchmark::State& state) {
    renderFrames(state, "avalanche", {});
}
BENCHMARK(BM_RenderAvalancheShadowsMsaa)->Unit(benchmark::kMillisecond)->Iterations(40);

void BM_RenderAvalanchePlain(benchmark::State& state) {
    renderFrames(state, "avalanche", kPlain);
}
BENCHMARK(BM_RenderAvalanchePlain)->Unit(benchmark::kMillisecond)->Iterations(40);

// shadows and multisampling off, as the raw EGL program below draws it
void BM_RenderCurtainFrame(benchmark::State& state) {
    renderFrames(state, "curtain", kPlain);
}
BENCHMARK(BM_RenderCurtainFrame)->Unit(benchmark::kMillisecond)->Iterations(40);

/// How a raw EGL frame of the curtain shades its triangles.
enum class RawShading {
    Renderer, ///< with the renderer's own programs (no shadows): the difference is the renderer's work
    OneColour ///< one constant colour: the least any frame of these triangles can cost
};

/// The curtain's triangles drawn by a raw EGL program into a target of `samples` a pixel and read back.
void rawEglCurtain(benchmark::State& state, int samples, RawShading shading) {
    // the triangles the renderer draws: the cloth (with flat per-triangle normals) and a ground quad
    auto sim = settledDemo(false);
    std::vector<float> vertices;
    sim->world().view<const SpringNetwork>().each([&](Entity, const SpringNetwork& net) {
        for (const auto& t : net.triangles) {
            const Vec3 n = cross(net.x[t[1]] - net.x[t[0]], net.x[t[2]] - net.x[t[0]]);
            for (std::uint32_t i : t) {
                vertices.insert(vertices.end(), {float(net.x[i].x), float(net.x[i].y), float(net.x[i].z),
                                                 float(n.x), float(n.y), float(n.z)});
            }
        }
    });
    for (const auto& p :
         {std::array{-200.f, 0.f, -200.f}, std::array{200.f, 0.f, 200.f}, std::array{200.f, 0.f, -200.f},
          std::array{-200.f, 0.f, -200.f}, std::array{-200.f, 0.f, 200.f}, std::array{200.f, 0.f, 200.f}}) {
        vertices.insert(vertices.end(), {p[0], p[1], p[2], 0.f, 1.f, 0.f});
    }
    GlContext context;
    Framebuffer target(1280, 720, samples);
    // the renderer's own shaders (the difference is then the renderer's work, not its shading) or one colour
    // colour
    auto readText = [](const std::string& path) {
        std::ifstream in(path);
        std::ostringstream ss;
        ss << in.rdbuf();
        return ss.str();
    };
    const std::string shaders = assetDirectory() + "/shaders/";
    // the cloth with the mesh program, the ground with its own (mesh.frag with GROUND: the grid)
    const std::string oneColour =
        "#version 300 es\nprecision highp float;\nuniform vec4 uColor;\nout vec4 fragColor;\n"
        "void main() { fragColor = uColor; }\n";
    const bool own = shading == RawShading::Renderer;
    const unsigned program = compileProgram(
        readText(shaders + "mesh.vert"), own ? withLook("mesh.frag", "#define GAMMA\n") : oneColour, "mesh");
    const unsigned groundProgram =
        compileProgram(readText(shaders + "mesh.vert"),
                       own ? withLook("mesh.frag", "#define GAMMA\n#define GROUND\n") : oneColour, "ground");
    GLuint vao = 0, vbo = 0;
    glGenVertexArrays(1, &vao);
    glGenBuffers(1, &vbo);
    glBindVertexArray(vao);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), nullptr);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float),
                          reinterpret_cast<void*>(3 * sizeof(float)));
    const auto vp = viewProjection(sim->scene());
    const float identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    for (const unsigned p : {program, groundProgram}) {
        glUseProgram(p);
        glUniformMatrix4fv(glGetUniformLocation(p, "uViewProjection"), 1, GL_FALSE, vp.data());
        glUniformMatrix4fv(glGetUniformLocation(p, "uModel"), 1, GL_FALSE, identity);
        glUniform3f(glGetUniformLocation(p, "uLightDir"), 0.0f, -0.8f, -0.6f);
        glUniform3f(glGetUniformLocation(p, "uEye"), 1.8f, 1.2f, 4.5f);
        glUniform4f(glGetUniformLocation(p, "uColor"), 0.8f, 0.3f, 0.25f, 1.0f);
        glUniform1f(glGetUniformLocation(p, "uKey"), 1.0f);
        glUniform3f(glGetUniformLocation(p, "uSkyLight"), 0.3f, 0.4f, 0.55f);
    }
    const GLsizei clothVertices = GLsizei(vertices.size() / 6) - 6;
    std::vector<std::uint8_t> pixels;
    for (auto _ : state) {
        target.bind();
        glClearColor(0.6f, 0.7f, 0.9f, 1.0f);
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        glEnable(GL_DEPTH_TEST);
        glBindBuffer(GL_ARRAY_BUFFER, vbo);
        glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(vertices.size() * sizeof(float)), vertices.data(),
                     GL_STREAM_DRAW);
        glUseProgram(program);
        glDrawArrays(GL_TRIANGLES, 0, clothVertices);
        glUseProgram(groundProgram);
        glDrawArrays(GL_TRIANGLES, clothVertices, 6);
        target.read(pixels);
        benchmark::DoNotOptimize(pixels.data());
    }
    glDeleteBuffers(1, &vbo);
    glDeleteVertexArrays(1, &vao);
    glDeleteProgram(program);
    glDeleteProgram(groundProgram);
}

void BM_RawEglCurtainFrame(benchmark::State& state) {
    rawEglCurtain(state, 1, RawShading::Renderer);
}
BENCHMARK(BM_RawEglCurtainFrame)->Unit(benchmark::kMillisecond)->Iterations(40);

// the same at 4 samples a pixel, resolved before it is read: what multisampling costs by itself, with the
// renderer's shading and with none to speak of (the floor under any 4x frame of the curtain here)
void BM_RawEglCurtainFrameMsaa(benchmark::State& state) {
    rawEglCurtain(state, 4, RawShading::Renderer);
}
BENCHMARK(BM_RawEglCurtainFrameMsaa)->Unit(benchmark::kMillisecond)->Iterations(40);

void BM_RawEglCurtainFrameMsaaOneColour(benchmark::State& state) {
    rawEglCurtain(state, 4, RawShading::OneColour);
}
BENCHMARK(BM_RawEglCurtainFrameMsaaOneColour)->Unit(benchmark::kMillisecond)->Iterations(40);

} // namespace
} // namespace tumble
