// RAII wrappers for the GL objects the GPU relight uses (buffers, programs, textures,
// framebuffers, timer queries), and shader compilation from the embedded sources.
//
// Only gpu includes GL; this header exposes GLuint-sized handles as unsigned so the
// rest of the backend's headers stay GL-free. Objects must be created and destroyed with
// their context current (GpuRelighter guarantees it). A program is compiled from named
// embedded sources (shaders/embedded.h) with `#include "x"` expanded and defines inserted
// after `#version`; compile and link errors name the shader and carry GL's info log.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/common/status.h"

namespace lightlink::gpu {

// A GL buffer object (immutable storage, glNamedBufferStorage). Size 0 allocates 16 bytes
// so that an empty array still binds.
class GlBuffer {
 public:
  GlBuffer() = default;
  GlBuffer(std::size_t bytes, const void* data, unsigned flags = 0);
  ~GlBuffer();
  GlBuffer(GlBuffer&& o) noexcept { *this = std::move(o); }
  GlBuffer& operator=(GlBuffer&& o) noexcept;
  template <typename T>
  static GlBuffer of(const std::vector<T>& v) {
    return GlBuffer(v.size() * sizeof(T), v.empty() ? nullptr : v.data());
  }
  unsigned id() const { return id_; }
  std::size_t bytes() const { return bytes_; }
  // Binds as shader storage buffer `binding`.
  void bindStorage(int binding) const;
  void upload(const void* data, std::size_t bytes, std::size_t offset = 0) const;
  void zero() const;

 private:
  unsigned id_ = 0;
  std::size_t bytes_ = 0;
};

struct ShaderDefine {
  std::string name, value;
};

class GlProgram {
 public:
  GlProgram() = default;
  ~GlProgram();
  GlProgram(GlProgram&& o) noexcept { *this = std::move(o); }
  GlProgram& operator=(GlProgram&& o) noexcept;

  // A compute program from one embedded shader.
  static Expected<GlProgram> compute(std::string_view name, const std::vector<ShaderDefine>& defines = {});
  // A compute program from source text (tests: a broken shader must report its name + log).
  static Expected<GlProgram> computeFromSource(std::string_view name, std::string_view source,
                                               const std::vector<ShaderDefine>& defines = {});
  // A raster program from two embedded shaders.
  static Expected<GlProgram> raster(std::string_view vertex, std::string_view fragment);

  unsigned id() const { return id_; }
  void use() const;
  int uniform(const char* name) const;
  void set(const char* name, std::uint32_t v) const;
  void set(const char* name, int v) const;
  void set(const char* name, float v) const;
  void set3(const char* name, const float* v) const;
  void setMat4(const char* name, const float* m) const;

 private:
  unsigned id_ = 0;
};

// Expands `#include "name"` from the embedded table and inserts defines after #version.
Expected<std::string> preprocessShader(std::string_view name, std::string_view source,
                                       const std::vector<ShaderDefine>& defines);

class GlTexture {
 public:
  GlTexture() = default;
  ~GlTexture();
  GlTexture(GlTexture&& o) noexcept { *this = std::move(o); }
  GlTexture& operator=(GlTexture&& o) noexcept;
  // target: GL_TEXTURE_2D_ARRAY etc.
  static GlTexture create(unsigned target);
  unsigned id() const { return id_; }

 private:
  unsigned id_ = 0;
};

class GlFramebuffer {
 public:
  GlFramebuffer() = default;
  ~GlFramebuffer();
  GlFramebuffer(GlFramebuffer&& o) noexcept { *this = std::move(o); }
  GlFramebuffer& operator=(GlFramebuffer&& o) noexcept;
  static GlFramebuffer create();
  unsigned id() const { return id_; }

 private:
  unsigned id_ = 0;
};

// Named GPU time intervals from GL_TIMESTAMP queries: begin(name) ... end(), in issue
// order; results are read once after the work (resolve()), so nothing stalls in between.
class GpuTimers {
 public:
  GpuTimers() = default;
  ~GpuTimers();
  GpuTimers(const GpuTimers&) = delete;
  GpuTimers& operator=(const GpuTimers&) = delete;
  void reset();
  void begin(std::string name);
  void end();
  // Waits for the queries and returns (name, seconds) per interval, in issue order.
  std::vector<std::pair<std::string, double>> resolve();

 private:
  std::vector<unsigned> pool_;  // query objects, reused
  std::size_t used_ = 0;
  std::vector<std::string> names_;
};

// The GL error flag drained into a status naming `where` (a stage), or OK.
Status glCheck(std::string_view where);

}  // namespace lightlink::gpu
