#include "gpu/egl_context.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <cstring>
#include <mutex>
#include <vector>

#include <fmt/format.h>

namespace lightlink::gpu {
namespace {

bool hasExtension(const char* list, const char* name) {
  if (!list) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

std::string eglErrorName(EGLint e) {
  switch (e) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    default: return fmt::format("EGL error 0x{:x}", e);
  }
}

// A 4.5 core context on `dpy` (initialised), or why not.
Expected<EGLContext> makeContext(EGLDisplay dpy) {
  if (!eglBindAPI(EGL_OPENGL_API)) return unsupported("eglBindAPI(EGL_OPENGL_API) failed: no desktop OpenGL");
  const char* ext = eglQueryString(dpy, EGL_EXTENSIONS);
  if (!hasExtension(ext, "EGL_KHR_surfaceless_context"))
    return unsupported("the EGL display lacks EGL_KHR_surfaceless_context");
  EGLConfig config = nullptr;
  const EGLint config_attribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
  EGLint n = 0;
  if (!eglChooseConfig(dpy, config_attribs, &config, 1, &n) || n < 1) {
    if (!hasExtension(ext, "EGL_KHR_no_config_context"))
      return unsupported("no EGL config renders OpenGL ({})", eglErrorName(eglGetError()));
    config = nullptr;  // EGL_NO_CONFIG_KHR
  }
  const EGLint ctx_attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                                EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  EGLContext ctx = eglCreateContext(dpy, config, EGL_NO_CONTEXT, ctx_attribs);
  if (ctx == EGL_NO_CONTEXT)
    return unsupported("no OpenGL 4.5 core context ({})", eglErrorName(eglGetError()));
  return ctx;
}

struct DisplayState {
  std::once_flag once;
  EGLDisplay display = EGL_NO_DISPLAY;
  std::string platform;
  Status status;
};

DisplayState& displayState() {
  static DisplayState s;
  return s;
}

// Tries one display: initialise, make a context current, check GL 4.5 + compute.
Status tryDisplay(EGLDisplay dpy) {
  if (dpy == EGL_NO_DISPLAY) return unsupported("no EGL display");
  EGLint major = 0, minor = 0;
  if (!eglInitialize(dpy, &major, &minor)) return unsupported("eglInitialize failed ({})", eglErrorName(eglGetError()));
  auto ctx = makeContext(dpy);
  if (!ctx) return ctx.status();
  if (!eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, *ctx)) {
    Status s = unsupported("eglMakeCurrent without a surface failed ({})", eglErrorName(eglGetError()));
    eglDestroyContext(dpy, *ctx);
    return s;
  }
  GLint gl_major = 0, gl_minor = 0;
  glGetIntegerv(GL_MAJOR_VERSION, &gl_major);
  glGetIntegerv(GL_MINOR_VERSION, &gl_minor);
  eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(dpy, *ctx);
  if (gl_major * 10 + gl_minor < 45) return unsupported("OpenGL {}.{} < 4.5", gl_major, gl_minor);
  return {};
}

void openDisplay(DisplayState& st) {
  auto get_platform_display =
      reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  std::vector<std::string> tried;
  if (get_platform_display && hasExtension(client, "EGL_MESA_platform_surfaceless")) {
    EGLDisplay d = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    Status s = tryDisplay(d);
    if (s) {
      st.display = d, st.platform = "surfaceless";
      return;
    }
    tried.push_back("surfaceless: " + s.message());
  }
  auto query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
  if (get_platform_display && query_devices && hasExtension(client, "EGL_EXT_platform_device")) {
    EGLDeviceEXT devices[16];
    EGLint count = 0;
    if (query_devices(16, devices, &count)) {
      for (EGLint i = 0; i < count; ++i) {
        EGLDisplay d = get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
        Status s = tryDisplay(d);
        if (s) {
          st.display = d, st.platform = fmt::format("device {} (EGL_EXT_device_enumeration)", i);
          return;
        }
        tried.push_back(fmt::format("device {}: {}", i, s.message()));
      }
    }
  }
  EGLDisplay d = eglGetDisplay(EGL_DEFAULT_DISPLAY);
  Status s = tryDisplay(d);
  if (s) {
    st.display = d, st.platform = "default";
    return;
  }
  tried.push_back("default display: " + s.message());
  std::string all;
  for (const auto& t : tried) all += (all.empty() ? "" : "; ") + t;
  st.status = unsupported("no usable EGL display with OpenGL 4.5 core: {}", all);
}

}  // namespace

Expected<std::unique_ptr<GlContext>> GlContext::create() {
  DisplayState& st = displayState();
  std::call_once(st.once, [&] { openDisplay(st); });
  if (!st.status) return st.status;
  auto ctx = makeContext(st.display);
  if (!ctx) return ctx.status();
  std::unique_ptr<GlContext> c(new GlContext());
  c->display_ = st.display;
  c->context_ = *ctx;
  c->info_.platform = st.platform;
  Current cur(*c);
  if (!cur.status()) return cur.status();
  auto str = [](GLenum e) {
    const GLubyte* s = glGetString(e);
    return s ? std::string(reinterpret_cast<const char*>(s)) : std::string();
  };
  c->info_.renderer = str(GL_RENDERER);
  c->info_.version = str(GL_VERSION);
  c->info_.vendor = str(GL_VENDOR);
  return c;
}

GlContext::~GlContext() {
  if (context_) eglDestroyContext(static_cast<EGLDisplay>(display_), static_cast<EGLContext>(context_));
}

GlContext::Current::Current(GlContext& c) : ctx_(c) {
  if (eglGetCurrentContext() == static_cast<EGLContext>(c.context_)) return;  // nested scope
  if (!eglMakeCurrent(static_cast<EGLDisplay>(c.display_), EGL_NO_SURFACE, EGL_NO_SURFACE,
                      static_cast<EGLContext>(c.context_))) {
    status_ = internalError("eglMakeCurrent failed ({}): is the context current on another thread?",
                            eglErrorName(eglGetError()));
    return;
  }
  made_ = true;
}

GlContext::Current::~Current() {
  if (made_) eglMakeCurrent(static_cast<EGLDisplay>(ctx_.display_), EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
}

}  // namespace lightlink::gpu
