#include "app/gl_context.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GLES3/gl3.h>

#include <cstdio>
#include <cstring>
#include <memory>

namespace tumble {

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

void GlContext::makeCurrent() {
    if (eglGetCurrentContext() == static_cast<EGLContext>(m_context)) {
        return;
    }
    if (!eglMakeCurrent(static_cast<EGLDisplay>(m_display), EGL_NO_SURFACE, EGL_NO_SURFACE,
                        static_cast<EGLContext>(m_context))) {
        char code[16];
        std::snprintf(code, sizeof code, "0x%04x", unsigned(eglGetError()));
        throw RenderUnavailable(
            std::string("EGL could not make the renderer's context current again (error ") + code + ")");
    }
}

std::shared_ptr<RenderContext> openHeadlessContext(std::string& device) {
    auto context = std::make_shared<GlContext>();
    device = context->description();
    return context;
}

} // namespace tumble
