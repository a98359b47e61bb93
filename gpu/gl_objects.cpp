#include "gpu/gl_objects.h"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <fmt/format.h>

#include "shaders/embedded.h"

namespace lightlink::gpu {

// ---- buffers ---------------------------------------------------------------------------

GlBuffer::GlBuffer(std::size_t bytes, const void* data, unsigned flags) {
  bytes_ = bytes;
  glCreateBuffers(1, &id_);
  const std::size_t alloc = bytes ? bytes : 16;
  // Zero storage comes from host zeros, not glClearNamedBufferData: on NVIDIA (580) a large
  // glNamedBufferSubData issued right after a clear of the same buffer was overtaken by the
  // clear (the uploaded links read back as zeros; tests/gpu caught it on an H100).
  std::vector<std::uint8_t> zeros;
  if (!data) zeros.assign(alloc, 0);
  glNamedBufferStorage(id_, GLsizeiptr(alloc), data ? data : zeros.data(), flags | GL_DYNAMIC_STORAGE_BIT);
}

GlBuffer::~GlBuffer() {
  if (id_) glDeleteBuffers(1, &id_);
}

GlBuffer& GlBuffer::operator=(GlBuffer&& o) noexcept {
  if (this != &o) {
    if (id_) glDeleteBuffers(1, &id_);
    id_ = std::exchange(o.id_, 0u);
    bytes_ = std::exchange(o.bytes_, 0u);
  }
  return *this;
}

void GlBuffer::bindStorage(int binding) const { glBindBufferBase(GL_SHADER_STORAGE_BUFFER, GLuint(binding), id_); }

void GlBuffer::upload(const void* data, std::size_t bytes, std::size_t offset) const {
  if (bytes) glNamedBufferSubData(id_, GLintptr(offset), GLsizeiptr(bytes), data);
}

void GlBuffer::zero() const {
  const std::uint32_t z = 0;
  glClearNamedBufferData(id_, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &z);
}

// ---- programs --------------------------------------------------------------------------

namespace {

std::string infoLog(GLuint obj, bool program) {
  GLint len = 0;
  if (program) glGetProgramiv(obj, GL_INFO_LOG_LENGTH, &len);
  else glGetShaderiv(obj, GL_INFO_LOG_LENGTH, &len);
  std::string log(std::size_t(std::max(len, 1)), '\0');
  if (program) glGetProgramInfoLog(obj, len, nullptr, log.data());
  else glGetShaderInfoLog(obj, len, nullptr, log.data());
  while (!log.empty() && (log.back() == '\0' || log.back() == '\n')) log.pop_back();
  return log;
}

Status expandIncludes(std::string_view name, std::string_view src, std::string& out, int depth) {
  if (depth > 8) return internalError("shader {}: includes nested deeper than 8", name);
  std::size_t pos = 0;
  while (pos < src.size()) {
    std::size_t eol = src.find('\n', pos);
    if (eol == std::string_view::npos) eol = src.size();
    std::string_view line = src.substr(pos, eol - pos);
    if (line.starts_with("#include \"")) {
      const std::size_t q = line.find('"', 10);
      const std::string_view inc = line.substr(10, q == std::string_view::npos ? 0 : q - 10);
      auto text = shaders::find(inc);
      if (!text) return notFound("shader {}: included file '{}' is not an embedded shader", name, inc);
      if (Status s = expandIncludes(inc, *text, out, depth + 1); !s) return s;
      out += "\n";
    } else {
      out.append(line);
      out += "\n";
    }
    pos = eol + 1;
  }
  return {};
}

Expected<GLuint> compileStage(GLenum stage, std::string_view name, const std::string& text) {
  GLuint sh = glCreateShader(stage);
  const char* p = text.c_str();
  glShaderSource(sh, 1, &p, nullptr);
  glCompileShader(sh);
  GLint ok = 0;
  glGetShaderiv(sh, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    std::string log = infoLog(sh, false);
    glDeleteShader(sh);
    return internalError("shader {} failed to compile:\n{}", name, log);
  }
  return sh;
}

Expected<GLuint> link(std::string_view name, std::initializer_list<GLuint> stages) {
  GLuint prog = glCreateProgram();
  for (GLuint s : stages) glAttachShader(prog, s);
  glLinkProgram(prog);
  for (GLuint s : stages) glDeleteShader(s);
  GLint ok = 0;
  glGetProgramiv(prog, GL_LINK_STATUS, &ok);
  if (!ok) {
    std::string log = infoLog(prog, true);
    glDeleteProgram(prog);
    return internalError("shader {} failed to link:\n{}", name, log);
  }
  return prog;
}

}  // namespace

Expected<std::string> preprocessShader(std::string_view name, std::string_view source,
                                       const std::vector<ShaderDefine>& defines) {
  std::string body;
  if (Status s = expandIncludes(name, source, body, 0); !s) return s;
  // The #version line goes first (the files open with a comment), then the defines.
  std::string version;
  const std::size_t v = body.find("#version");
  if (v != std::string::npos && (v == 0 || body[v - 1] == '\n')) {
    const std::size_t eol = body.find('\n', v);
    version = body.substr(v, eol - v + 1);
    body.erase(v, eol - v + 1);
  }
  std::string defs;
  for (const auto& d : defines) defs += fmt::format("#define {} {}\n", d.name, d.value);
  return version + defs + body;
}

GlProgram::~GlProgram() {
  if (id_) glDeleteProgram(id_);
}

GlProgram& GlProgram::operator=(GlProgram&& o) noexcept {
  if (this != &o) {
    if (id_) glDeleteProgram(id_);
    id_ = std::exchange(o.id_, 0u);
  }
  return *this;
}

Expected<GlProgram> GlProgram::computeFromSource(std::string_view name, std::string_view source,
                                                 const std::vector<ShaderDefine>& defines) {
  auto text = preprocessShader(name, source, defines);
  if (!text) return text.status();
  auto cs = compileStage(GL_COMPUTE_SHADER, name, *text);
  if (!cs) return cs.status();
  auto prog = link(name, {*cs});
  if (!prog) return prog.status();
  GlProgram p;
  p.id_ = *prog;
  return p;
}

Expected<GlProgram> GlProgram::compute(std::string_view name, const std::vector<ShaderDefine>& defines) {
  auto src = shaders::find(name);
  if (!src) return notFound("shader {} is not embedded in this build", name);
  return computeFromSource(name, *src, defines);
}

Expected<GlProgram> GlProgram::raster(std::string_view vertex, std::string_view fragment) {
  auto vs_src = shaders::find(vertex);
  auto fs_src = shaders::find(fragment);
  if (!vs_src || !fs_src) return notFound("shader {} or {} is not embedded in this build", vertex, fragment);
  auto vt = preprocessShader(vertex, *vs_src, {});
  if (!vt) return vt.status();
  auto ft = preprocessShader(fragment, *fs_src, {});
  if (!ft) return ft.status();
  auto vs = compileStage(GL_VERTEX_SHADER, vertex, *vt);
  if (!vs) return vs.status();
  auto fs = compileStage(GL_FRAGMENT_SHADER, fragment, *ft);
  if (!fs) {
    glDeleteShader(*vs);
    return fs.status();
  }
  auto prog = link(fmt::format("{} + {}", vertex, fragment), {*vs, *fs});
  if (!prog) return prog.status();
  GlProgram p;
  p.id_ = *prog;
  return p;
}

void GlProgram::use() const { glUseProgram(id_); }
int GlProgram::uniform(const char* name) const { return glGetUniformLocation(id_, name); }
void GlProgram::set(const char* name, std::uint32_t v) const { glProgramUniform1ui(id_, uniform(name), v); }
void GlProgram::set(const char* name, int v) const { glProgramUniform1i(id_, uniform(name), v); }
void GlProgram::set(const char* name, float v) const { glProgramUniform1f(id_, uniform(name), v); }
void GlProgram::set3(const char* name, const float* v) const { glProgramUniform3fv(id_, uniform(name), 1, v); }
void GlProgram::setMat4(const char* name, const float* m) const {
  glProgramUniformMatrix4fv(id_, uniform(name), 1, GL_FALSE, m);
}

// ---- textures, framebuffers ------------------------------------------------------------

GlTexture GlTexture::create(unsigned target) {
  GlTexture t;
  glCreateTextures(target, 1, &t.id_);
  return t;
}
GlTexture::~GlTexture() {
  if (id_) glDeleteTextures(1, &id_);
}
GlTexture& GlTexture::operator=(GlTexture&& o) noexcept {
  if (this != &o) {
    if (id_) glDeleteTextures(1, &id_);
    id_ = std::exchange(o.id_, 0u);
  }
  return *this;
}

GlFramebuffer GlFramebuffer::create() {
  GlFramebuffer f;
  glCreateFramebuffers(1, &f.id_);
  return f;
}
GlFramebuffer::~GlFramebuffer() {
  if (id_) glDeleteFramebuffers(1, &id_);
}
GlFramebuffer& GlFramebuffer::operator=(GlFramebuffer&& o) noexcept {
  if (this != &o) {
    if (id_) glDeleteFramebuffers(1, &id_);
    id_ = std::exchange(o.id_, 0u);
  }
  return *this;
}

// ---- timers ----------------------------------------------------------------------------

GpuTimers::~GpuTimers() {
  if (!pool_.empty()) glDeleteQueries(GLsizei(pool_.size()), pool_.data());
}

void GpuTimers::reset() {
  used_ = 0;
  names_.clear();
}

void GpuTimers::begin(std::string name) {
  if (used_ + 2 > pool_.size()) {
    const std::size_t old = pool_.size();
    pool_.resize(std::max<std::size_t>(64, 2 * old));
    glCreateQueries(GL_TIMESTAMP, GLsizei(pool_.size() - old), pool_.data() + old);
  }
  glQueryCounter(pool_[used_++], GL_TIMESTAMP);
  names_.push_back(std::move(name));
}

void GpuTimers::end() { glQueryCounter(pool_[used_++], GL_TIMESTAMP); }

std::vector<std::pair<std::string, double>> GpuTimers::resolve() {
  std::vector<std::pair<std::string, double>> out;
  for (std::size_t i = 0; i < names_.size(); ++i) {
    GLuint64 t0 = 0, t1 = 0;
    glGetQueryObjectui64v(pool_[2 * i], GL_QUERY_RESULT, &t0);
    glGetQueryObjectui64v(pool_[2 * i + 1], GL_QUERY_RESULT, &t1);
    out.emplace_back(names_[i], t1 > t0 ? double(t1 - t0) * 1e-9 : 0.0);
  }
  return out;
}

Status glCheck(std::string_view where) {
  GLenum e = glGetError(), first = e;
  while (e != GL_NO_ERROR) e = glGetError();
  if (first == GL_NO_ERROR) return {};
  return internalError("GL error 0x{:x} in {}", first, where);
}

}  // namespace lightlink::gpu
