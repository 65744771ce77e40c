#include "systems/render_air.h"

#include "components/air.h"
#include "systems/air_solver.h"
#include "systems/render_system.h"

#include <Eigen/Dense>
#include <GLES3/gl3.h>

#include <algorithm>
#include <cmath>

namespace tumble {

void SmokePass::make(const std::string& vertexSource, const std::string& fragmentSource) {
    program = compileProgram(vertexSource, fragmentSource, "smoke");
    const auto at = [&](const char* name) { return glGetUniformLocation(program, name); };
    uniform = {at("uViewProjection"), at("uInverseViewProjection"),
               at("uViewport"),       at("uEye"),
               at("uBoxMin"),         at("uBoxSize"),
               at("uGridMin"),        at("uGridSize"),
               at("uStep"),           at("uOpacity"),
               at("uColor"),          at("uSmoke"),
               at("uDepth")};
    glGetIntegerv(GL_MAX_3D_TEXTURE_SIZE, &largestTexture);
    glGenTextures(1, &texture);
    glBindTexture(GL_TEXTURE_3D, texture);
    glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    for (GLenum wrap : {GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R}) {
        glTexParameteri(GL_TEXTURE_3D, wrap, GL_CLAMP_TO_EDGE);
    }
}

void SmokePass::release() {
    glDeleteProgram(program);
    glDeleteTextures(1, &texture);
    glDeleteTextures(1, &depthTexture);
    glDeleteFramebuffers(1, &depthFbo);
}

namespace {

/// The scene's depth copied into the pass's depth texture (made, or made again, at the frame's size): the
/// march reads it, which it could not from the framebuffer it draws into.
void copyDepth(SmokePass& pass, const SmokeFrame& frame) {
    if (pass.depthWidth != frame.width || pass.depthHeight != frame.height) {
        glDeleteTextures(1, &pass.depthTexture);
        glDeleteFramebuffers(1, &pass.depthFbo);
        glGenTextures(1, &pass.depthTexture);
        glBindTexture(GL_TEXTURE_2D, pass.depthTexture);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT24, frame.width, frame.height, 0, GL_DEPTH_COMPONENT,
                     GL_UNSIGNED_INT, nullptr);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        glGenFramebuffers(1, &pass.depthFbo);
        glBindFramebuffer(GL_FRAMEBUFFER, pass.depthFbo);
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, pass.depthTexture, 0);
        pass.depthWidth = frame.width;
        pass.depthHeight = frame.height;
    }
    glBindFramebuffer(GL_READ_FRAMEBUFFER, frame.targetFbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, pass.depthFbo);
    glBlitFramebuffer(0, 0, frame.width, frame.height, 0, 0, frame.width, frame.height, GL_DEPTH_BUFFER_BIT,
                      GL_NEAREST);
    glBindFramebuffer(GL_FRAMEBUFFER, frame.targetFbo);
}

void setFrameUniforms(const SmokePass& pass, const SmokeFrame& frame) {
    const Eigen::Map<const Eigen::Matrix4f> vp(frame.viewProjection.data());
    const Eigen::Matrix4f inverse = vp.inverse();
    glUniformMatrix4fv(pass.uniform.viewProjection, 1, GL_FALSE, frame.viewProjection.data());
    glUniformMatrix4fv(pass.uniform.inverseViewProjection, 1, GL_FALSE, inverse.data());
    glUniform2f(pass.uniform.viewport, float(frame.width), float(frame.height));
    glUniform3f(pass.uniform.eye, float(frame.eye.x), float(frame.eye.y), float(frame.eye.z));
    glUniform1i(pass.uniform.smoke, 0);
    glUniform1i(pass.uniform.depth, 1);
}

/// The cells of a grid whose smoke could be seen: from lo to hi (inclusive) along each axis; empty (lo >
/// hi) when there is none. A cell is left out when its density could not take 0.2% of the light even
/// across the whole grid, so that the march skips the clear air round the smoke.
struct SmokeBounds {
    std::array<int, 3> lo, hi;
    bool empty() const { return lo[0] > hi[0]; }
};

SmokeBounds smokeBounds(const Air& air) {
    SmokeBounds b{{air.cells[0], air.cells[1], air.cells[2]}, {-1, -1, -1}};
    if (air.smokeOpacity <= 0.0) {
        return b;
    }
    const int longest = std::max({air.cells[0], air.cells[1], air.cells[2]});
    const auto faint = float(0.002 / (air.smokeOpacity * air.cell * longest));
    for (int k = 0; k < air.cells[2]; ++k) {
        for (int j = 0; j < air.cells[1]; ++j) {
            const float* row = air.smoke.data() + air.at(0, j, k);
            for (int i = 0; i < air.cells[0]; ++i) {
                if (row[i] > faint) {
                    const int at[3] = {i, j, k};
                    for (std::size_t a = 0; a < 3; ++a) {
                        b.lo[a] = std::min(b.lo[a], at[a]);
                        b.hi[a] = std::max(b.hi[a], at[a]);
                    }
                }
            }
        }
    }
    return b;
}

/// Draws one grid's smoke: its density uploaded, the box round it marched.
void drawGridSmoke(const Air& air, SmokePass& pass, const SmokeBounds& bounds, const SmokeFrame& frame) {
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    if (pass.textureCells == air.cells) {
        glTexSubImage3D(GL_TEXTURE_3D, 0, 0, 0, 0, air.cells[0], air.cells[1], air.cells[2], GL_RED, GL_FLOAT,
                        air.smoke.data());
    } else {
        glTexImage3D(GL_TEXTURE_3D, 0, GL_R16F, air.cells[0], air.cells[1], air.cells[2], 0, GL_RED, GL_FLOAT,
                     air.smoke.data());
        pass.textureCells = air.cells;
    }
    const Vec3 origin = air.origin();
    // the smoke's cells and half a cell more each way, where trilinear sampling fades them out, but not
    // past the grid's sides (there the texture's edge would hold the last cell's density)
    auto within = [&](double cells, int side) {
        return std::clamp(cells, 0.0, double(air.cells[std::size_t(side)]));
    };
    const Vec3 lo = origin + Vec3{within(bounds.lo[0] - 0.5, 0), within(bounds.lo[1] - 0.5, 1),
                                  within(bounds.lo[2] - 0.5, 2)} *
                                 air.cell;
    const Vec3 hi = origin + Vec3{within(bounds.hi[0] + 1.5, 0), within(bounds.hi[1] + 1.5, 1),
                                  within(bounds.hi[2] + 1.5, 2)} *
                                 air.cell;
    glUniform3f(pass.uniform.boxMin, float(lo.x), float(lo.y), float(lo.z));
    glUniform3f(pass.uniform.boxSize, float(hi.x - lo.x), float(hi.y - lo.y), float(hi.z - lo.z));
    glUniform3f(pass.uniform.gridMin, float(origin.x), float(origin.y), float(origin.z));
    glUniform3f(pass.uniform.gridSize, float(air.cells[0] * air.cell), float(air.cells[1] * air.cell),
                float(air.cells[2] * air.cell));
    glUniform1f(pass.uniform.step, float(air.cell));
    glUniform1f(pass.uniform.opacity, float(air.smokeOpacity));
    glUniform3f(pass.uniform.colour, air.smokeColour[0], air.smokeColour[1], air.smokeColour[2]);
    glDrawArrays(GL_TRIANGLES, 0, frame.cubeVertices);
}

} // namespace

void drawSmoke(World& world, SmokePass& pass, const SmokeFrame& frame) {
    std::vector<std::pair<const Air*, SmokeBounds>> drawn;
    world.view<const Air>().each([&](Entity, const Air& air) {
        const SmokeBounds b = smokeBounds(air);
        const bool fits = std::max({air.cells[0], air.cells[1], air.cells[2]}) <= pass.largestTexture;
        if (!b.empty() && fits) { // a grid past the GL's 3D texture size is not drawn (README, "Air")
            drawn.emplace_back(&air, b);
        }
    });
    if (drawn.empty()) {
        return;
    }
    copyDepth(pass, frame);
    glUseProgram(pass.program);
    setFrameUniforms(pass, frame);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, pass.depthTexture);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_3D, pass.texture);
    glEnable(GL_CULL_FACE);
    glCullFace(GL_FRONT); // the box's back faces: a camera inside it still marches every pixel
    glDisable(GL_DEPTH_TEST);
    glDepthMask(GL_FALSE);
    glEnable(GL_BLEND);
    glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA); // premultiplied
    glBindVertexArray(frame.cubeVao);
    for (const auto& [air, bounds] : drawn) {
        drawGridSmoke(*air, pass, bounds, frame);
    }
    glDisable(GL_BLEND);
    glDepthMask(GL_TRUE);
    glEnable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    glCullFace(GL_BACK);
}

namespace {

/// Blue for still air to red for the slice's top speed.
std::array<float, 3> speedColour(double t) {
    const auto f = float(std::clamp(t, 0.0, 1.0));
    return {0.15f + 0.85f * f, 0.35f - 0.1f * f, 1.0f - 0.9f * f};
}

void appendSlice(const Air& air, std::vector<FlatVertex>& lines) {
    const int normal = air.velocitySlice, a = (normal + 1) % 3, b = (normal + 2) % 3;
    const int stride =
        std::max(1, (std::max(air.cells[std::size_t(a)], air.cells[std::size_t(b)]) + 31) / 32);
    // the arrows' feet: cell centres every `stride` cells across the slice, at the box's centre along it
    std::vector<std::pair<Vec3, Vec3>> arrows;
    double top = 0.0;
    for (int j = stride / 2; j < air.cells[std::size_t(b)]; j += stride) {
        for (int i = stride / 2; i < air.cells[std::size_t(a)]; i += stride) {
            std::array<double, 3> local{};
            local[std::size_t(normal)] = 0.5 * air.cells[std::size_t(normal)] * air.cell;
            local[std::size_t(a)] = (i + 0.5) * air.cell;
            local[std::size_t(b)] = (j + 0.5) * air.cell;
            const Vec3 foot = air.origin() + Vec3{local[0], local[1], local[2]};
            const Vec3 v = airVelocityAt(air, foot);
            top = std::max(top, length(v));
            arrows.emplace_back(foot, v);
        }
    }
    if (top < 1e-9) {
        return; // still air: nothing to point
    }
    const double longest = 0.9 * stride * air.cell;
    std::array<double, 3> n{};
    n[std::size_t(normal)] = 1.0;
    const Vec3 across{n[0], n[1], n[2]};
    auto push = [&](const Vec3& p, const std::array<float, 3>& c) {
        lines.push_back({float(p.x), float(p.y), float(p.z), c[0], c[1], c[2], 1.0f, 0.0f});
    };
    for (const auto& [foot, v] : arrows) {
        const double speed = length(v);
        if (speed < 1e-3 * top) {
            continue;
        }
        const Vec3 along = v * (1.0 / speed), tip = foot + along * (longest * speed / top);
        Vec3 side = cross(along, across);
        side = length(side) > 1e-6 ? side * (1.0 / length(side)) : Vec3{across.y, across.z, across.x};
        const double head = 0.3 * longest * speed / top;
        const auto c = speedColour(speed / top);
        for (const Vec3& end : {foot, tip, tip, tip - along * head + side * (0.5 * head), tip,
                                tip - along * head - side * (0.5 * head)}) {
            push(end, c);
        }
    }
}

} // namespace

void appendVelocityArrows(World& world, std::vector<FlatVertex>& lines) {
    world.view<const Air>().each([&](Entity, const Air& air) {
        if (air.velocitySlice >= 0) {
            appendSlice(air, lines);
        }
    });
}

} // namespace tumble
