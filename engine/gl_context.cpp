#include "engine/gl_context.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GLES3/gl3.h>
#include <stb/stb_image_write.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>

namespace tumble {

namespace fs = std::filesystem;

namespace {

/// A display from the first EGL device that gives one (a GPU), or none.
EGLDisplay deviceDisplay() {
    const char* extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!extensions || !std::strstr(extensions, "EGL_EXT_platform_device")) {
        return EGL_NO_DISPLAY;
    }
    auto queryDevices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    auto getDisplay =
        reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
    if (!queryDevices || !getDisplay) {
        return EGL_NO_DISPLAY;
    }
    EGLDeviceEXT devices[8];
    EGLint count = 0;
    if (!queryDevices(8, devices, &count)) {
        return EGL_NO_DISPLAY;
    }
    for (EGLint i = 0; i < count; ++i) {
        // Mesa lists its software device too; prefer a device that names a DRM node (a GPU)
        auto queryString =
            reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(eglGetProcAddress("eglQueryDeviceStringEXT"));
        const char* devExt = queryString ? queryString(devices[i], EGL_EXTENSIONS) : nullptr;
        if (!devExt || !std::strstr(devExt, "EGL_EXT_device_drm")) {
            continue;
        }
        EGLDisplay d = getDisplay(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
        EGLint major = 0, minor = 0;
        if (d != EGL_NO_DISPLAY && eglInitialize(d, &major, &minor)) {
            return d;
        }
    }
    return EGL_NO_DISPLAY;
}

} // namespace

GlContext::GlContext() {
    std::string platform = "device";
    EGLDisplay display = deviceDisplay();
    if (display == EGL_NO_DISPLAY) {
        platform = "surfaceless";
        auto getDisplay =
            reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
        display = getDisplay ? getDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr)
                             : EGL_NO_DISPLAY;
        EGLint major = 0, minor = 0;
        if (display == EGL_NO_DISPLAY || !eglInitialize(display, &major, &minor)) {
            throw RenderUnavailable("no headless EGL display could be opened here (neither a GPU device nor "
                                    "Mesa's surfaceless platform); run with --no-render to simulate only");
        }
    }
    m_display = display;
    eglBindAPI(EGL_OPENGL_ES_API);
    const EGLint configAttributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_ES3_BIT, EGL_NONE};
    EGLConfig config = nullptr;
    EGLint configs = 0;
    eglChooseConfig(display, configAttributes, &config, 1, &configs);
    const EGLint contextAttributes[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_NONE};
    EGLContext context = eglCreateContext(display, configs > 0 ? config : EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT,
                                          contextAttributes);
    if (context == EGL_NO_CONTEXT || !eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
        eglTerminate(display);
        throw RenderUnavailable(
            "EGL gave no OpenGL ES 3 context here; run with --no-render to simulate only");
    }
    m_context = context;
    m_description = std::string(reinterpret_cast<const char*>(glGetString(GL_VERSION))) + " | " +
                    reinterpret_cast<const char*>(glGetString(GL_RENDERER)) + " | EGL " + platform;
}

GlContext::~GlContext() {
    auto display = static_cast<EGLDisplay>(m_display);
    eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(display, static_cast<EGLContext>(m_context));
    // the display is left initialised: terminating it unloads the driver (Mesa's), whose few leftover
    // allocations then show up under LeakSanitizer as leaks of an unknown module that no suppression can
    // name; the process ends soon after anyway
}

Framebuffer::Framebuffer(int width, int height) : m_width(width), m_height(height) {
    glGenFramebuffers(1, &m_fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, m_fbo);
    glGenRenderbuffers(1, &m_color);
    glBindRenderbuffer(GL_RENDERBUFFER, m_color);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, width, height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, m_color);
    glGenRenderbuffers(1, &m_depth);
    glBindRenderbuffer(GL_RENDERBUFFER, m_depth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, width, height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, m_depth);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
        throw RenderUnavailable("the offscreen framebuffer is incomplete (" + std::to_string(width) + " x " +
                                std::to_string(height) + ")");
    }
}

Framebuffer::~Framebuffer() {
    glDeleteRenderbuffers(1, &m_depth);
    glDeleteRenderbuffers(1, &m_color);
    glDeleteFramebuffers(1, &m_fbo);
}

void Framebuffer::bind() const {
    glBindFramebuffer(GL_FRAMEBUFFER, m_fbo);
    glViewport(0, 0, m_width, m_height);
}

void Framebuffer::read(std::vector<std::uint8_t>& rgba) const {
    bind();
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
    const fs::path p(path);
    if (p.has_parent_path()) {
        std::error_code ec;
        fs::create_directories(p.parent_path(), ec);
    }
    if (!stbi_write_png(path.c_str(), width, height, 4, rgba.data(), width * 4)) {
        throw std::runtime_error("cannot write " + path);
    }
}

std::string assetDirectory() {
    if (const char* env = std::getenv("TUMBLE_ASSETS"); env && *env) {
        return env;
    }
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) {
        for (const fs::path& candidate :
             {exe.parent_path() / "assets", exe.parent_path() / ".." / "assets"}) {
            if (fs::is_directory(candidate / "shaders")) {
                return fs::weakly_canonical(candidate).string();
            }
        }
    }
    return std::string(TUMBLE_SOURCE_DIR) + "/assets";
}

} // namespace tumble
