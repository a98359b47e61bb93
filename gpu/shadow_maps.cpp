#include "gpu/shadow_maps.h"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <algorithm>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

namespace lightlink::gpu {
namespace {

constexpr float kPi = 3.14159265358979f;
// Cube faces are 2 * atan(1.08) wide instead of 90 degrees: the 3x3 filter at a face edge
// then reads texels of the same face.
constexpr float kCubeHalfTan = 1.08f;
// Widest spot cone (full angle) drawn as one view; wider cones use the cube.
constexpr float kMaxSpotFov = 120.0f * kPi / 180.0f;

glm::vec3 upFor(const glm::vec3& dir) {
  return std::abs(dir.y) < 0.99f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
}

}  // namespace

Expected<std::unique_ptr<ShadowMaps>> ShadowMaps::create(const scene::Scene& scene, int resolution) {
  if (resolution < 16 || resolution > 16384)
    return invalidInput("gpu: shadow_resolution {} not in 16..16384", resolution);
  std::unique_ptr<ShadowMaps> m(new ShadowMaps());
  m->resolution_ = resolution;
  std::vector<glm::vec3> pos;
  std::vector<std::uint32_t> idx;
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (const auto& mesh : scene.meshes) {
    if (!mesh.is_static) continue;  // the CPU's BVH holds static meshes only
    const std::uint32_t base = std::uint32_t(pos.size());
    for (const auto& p : mesh.positions) pos.push_back(p), lo = glm::min(lo, p), hi = glm::max(hi, p);
    for (std::uint32_t i : mesh.indices) idx.push_back(base + i);
  }
  if (pos.empty()) lo = hi = glm::vec3(0.0f);
  m->centre_ = 0.5f * (lo + hi);
  m->radius_ = std::max(0.5f * glm::length(hi - lo), 1e-6f) * 1.01f;
  m->index_count_ = idx.size();
  m->vertices_ = GlBuffer::of(pos);
  m->indices_ = GlBuffer::of(idx);
  glCreateVertexArrays(1, &m->vao_);
  glVertexArrayVertexBuffer(m->vao_, 0, m->vertices_.id(), 0, sizeof(glm::vec3));
  glVertexArrayElementBuffer(m->vao_, m->indices_.id());
  glEnableVertexArrayAttrib(m->vao_, 0);
  glVertexArrayAttribFormat(m->vao_, 0, 3, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribBinding(m->vao_, 0, 0);
  auto prog = GlProgram::raster("shadow.vert", "shadow.frag");
  if (!prog) return prog.status();
  m->program_ = std::move(*prog);
  m->depth_ = GlTexture::create(GL_TEXTURE_2D);
  glTextureStorage2D(m->depth_.id(), 1, GL_DEPTH_COMPONENT32F, resolution, resolution);
  m->fbo_ = GlFramebuffer::create();
  glNamedFramebufferTexture(m->fbo_.id(), GL_DEPTH_ATTACHMENT, m->depth_.id(), 0);
  if (Status s = glCheck("shadow map setup"); !s) return s;
  return m;
}

ShadowMaps::~ShadowMaps() {
  if (vao_) glDeleteVertexArrays(1, &vao_);
}

Status ShadowMaps::render(std::span<const scene::Light> lights, std::span<const std::uint8_t> emits,
                          std::span<glsl::GpuLight> gpu_lights, std::vector<glsl::GpuShadowView>& views) {
  views.clear();
  struct Pending {
    glm::mat4 clip_from_world;
    glm::vec3 eye, dir;
    bool ortho;
  };
  std::vector<Pending> pending;
  const float res = float(resolution_);
  for (std::size_t i = 0; i < lights.size(); ++i) {
    const scene::Light& l = lights[i];
    gpu_lights[i].kind_views.y = int(views.size());
    gpu_lights[i].kind_views.z = 0;
    if (!emits[i]) continue;
    if (l.kind == scene::Light::Kind::kDirectional) {
      const glm::vec3 d = l.direction;
      const glm::vec3 eye = centre_ - d * radius_;
      const glm::mat4 view = glm::lookAt(eye, centre_, upFor(d));
      const glm::mat4 proj = glm::ortho(-radius_, radius_, -radius_, radius_, 0.0f, 2.0f * radius_ * 1.01f);
      glsl::GpuShadowView v;
      v.clip_from_world = proj * view;
      v.eye_mode = glm::vec4(eye, 1.0f);
      v.dir_texel = glm::vec4(d, 2.0f * radius_ / res);
      views.push_back(v);
      pending.push_back({v.clip_from_world, eye, d, true});
      gpu_lights[i].kind_views.z = 1;
      continue;
    }
    // Depth range: up to the far side of the scene's bounding sphere (or the light's range).
    const float reach = glm::length(l.position - centre_) + radius_;
    const float far = l.range > 0.0f ? std::min(l.range, reach) : reach;
    const float near = std::max(far * 1e-4f, 1e-6f);
    const bool cube = l.kind == scene::Light::Kind::kPoint || 2.0f * l.outer_cone_angle > kMaxSpotFov;
    if (cube) {
      static const glm::vec3 kDirs[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
      const glm::mat4 proj = glm::perspective(2.0f * std::atan(kCubeHalfTan), 1.0f, near, far);
      for (const auto& d : kDirs) {
        glsl::GpuShadowView v;
        v.clip_from_world = proj * glm::lookAt(l.position, l.position + d, upFor(d));
        v.eye_mode = glm::vec4(l.position, 0.0f);
        v.dir_texel = glm::vec4(d, 2.0f * kCubeHalfTan / res);
        views.push_back(v);
        pending.push_back({v.clip_from_world, l.position, d, false});
      }
      gpu_lights[i].kind_views.z = 6;
    } else {
      // The cone plus a margin of a few texels so the filter at the cone's edge is in range.
      const float half = std::min(l.outer_cone_angle * 1.05f + 0.01f, 0.5f * kMaxSpotFov + 0.05f);
      const glm::mat4 proj = glm::perspective(2.0f * half, 1.0f, near, far);
      glsl::GpuShadowView v;
      v.clip_from_world = proj * glm::lookAt(l.position, l.position + l.direction, upFor(l.direction));
      v.eye_mode = glm::vec4(l.position, 0.0f);
      v.dir_texel = glm::vec4(l.direction, 2.0f * std::tan(half) / res);
      views.push_back(v);
      pending.push_back({v.clip_from_world, l.position, l.direction, false});
      gpu_lights[i].kind_views.z = 1;
    }
  }
  if (pending.empty()) return {};
  if (int(pending.size()) > layers_) {
    color_ = GlTexture::create(GL_TEXTURE_2D_ARRAY);
    layers_ = std::max<int>(int(pending.size()), 6);
    glTextureStorage3D(color_.id(), 1, GL_R32F, resolution_, resolution_, layers_);
    // texelFetch only, but a texture with mipmap filtering and one level is incomplete.
    glTextureParameteri(color_.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTextureParameteri(color_.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  }
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_.id());
  glViewport(0, 0, resolution_, resolution_);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);
  glBindVertexArray(vao_);
  program_.use();
  const float far_metric[4] = {3.0e38f, 0.0f, 0.0f, 0.0f};  // R: "nothing in the way"
  for (std::size_t v = 0; v < pending.size(); ++v) {
    glNamedFramebufferTextureLayer(fbo_.id(), GL_COLOR_ATTACHMENT0, color_.id(), 0, GLint(v));
    if (v == 0) {
      const GLenum status = glCheckNamedFramebufferStatus(fbo_.id(), GL_FRAMEBUFFER);
      if (status != GL_FRAMEBUFFER_COMPLETE)
        return internalError("shadow map framebuffer incomplete (0x{:x})", status);
    }
    glClearNamedFramebufferfv(fbo_.id(), GL_COLOR, 0, far_metric);
    const float one = 1.0f;
    glClearNamedFramebufferfv(fbo_.id(), GL_DEPTH, 0, &one);
    program_.setMat4("u_clip_from_world", glm::value_ptr(pending[v].clip_from_world));
    program_.set3("u_eye", glm::value_ptr(pending[v].eye));
    program_.set3("u_dir", glm::value_ptr(pending[v].dir));
    program_.set("u_ortho", pending[v].ortho ? 1 : 0);
    if (index_count_) glDrawElements(GL_TRIANGLES, GLsizei(index_count_), GL_UNSIGNED_INT, nullptr);
  }
  glBindVertexArray(0);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  return glCheck("shadow map rendering");
}

}  // namespace lightlink::gpu
