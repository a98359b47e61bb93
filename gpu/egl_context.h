// Headless OpenGL 4.5 core contexts through EGL, with no window system (DESIGN.md sec 10).
//
// Display: first EGL_PLATFORM_SURFACELESS_MESA (Mesa: llvmpipe on every CI machine, or a
// Mesa GPU driver), then every device of EGL_EXT_device_enumeration through
// EGL_PLATFORM_DEVICE_EXT (NVIDIA's EGL, which has no surfaceless platform), then the
// default display. The first display on which a 4.5 core context with compute shaders can be
// made current without a surface wins; it lives for the rest of the process (eglTerminate
// would pull it from under other contexts). eglGetPlatformDisplayEXT is fetched with
// eglGetProcAddress, not through a GL loader (libepoxy's wrapper aborts on Mesa).
//
// A GlContext is one EGL context on that display. GL state is per thread: `Current` makes it
// current for a scope and releases it afterwards, so a backend created on one thread can
// relight on another (never on two at once). Errors say which step failed: no EGL display,
// no OpenGL API, no 4.5 core context, not current.
#pragma once

#include <memory>
#include <string>

#include "core/common/status.h"

namespace lightlink::gpu {

struct GlContextInfo {
  std::string platform;  // "surfaceless", "device 0 (EGL_EXT_device_enumeration)" or "default"
  std::string renderer;  // GL_RENDERER
  std::string version;   // GL_VERSION
  std::string vendor;    // GL_VENDOR
};

class GlContext {
 public:
  // A new context on the process's display (opened on first use).
  static Expected<std::unique_ptr<GlContext>> create();
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  const GlContextInfo& info() const { return info_; }

  // Makes the context current on this thread for the scope; restores "none current" after.
  class Current {
   public:
    explicit Current(GlContext& c);
    ~Current();
    Current(const Current&) = delete;
    Current& operator=(const Current&) = delete;
    const Status& status() const { return status_; }

   private:
    GlContext& ctx_;
    bool made_ = false;
    Status status_;
  };

 private:
  GlContext() = default;
  void* display_ = nullptr;  // EGLDisplay
  void* context_ = nullptr;  // EGLContext
  GlContextInfo info_;
};

}  // namespace lightlink::gpu
