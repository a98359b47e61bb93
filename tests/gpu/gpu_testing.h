// What every GPU test file shares: Mesa's shader cache in the build tree (not the home
// directory), and REQUIRE_GPU(), which skips visibly where no usable EGL display exists.
#pragma once

#include <cstdlib>

#include <gtest/gtest.h>

#include "gpu/backend_factory.h"

namespace lightlink::gpu {

inline const bool kMesaCacheInBuildTree = [] {
  setenv("MESA_SHADER_CACHE_DIR", LIGHTLINK_BINARY_DIR "/mesa_shader_cache", 0);
  return true;
}();

}  // namespace lightlink::gpu

#define REQUIRE_GPU()                                                                        \
  do {                                                                                       \
    const ::lightlink::gpu::GpuProbe& probe = ::lightlink::gpu::probeGpu();                  \
    if (!probe.available) GTEST_SKIP() << "no usable EGL display / GL 4.5: " << probe.error; \
  } while (0)
