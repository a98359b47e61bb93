#include "gpu/emitter_sampling.h"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <algorithm>

#include <fmt/format.h>

#include "core/rt/flat_bvh.h"
#include "shaders/gpu_layout.h"

namespace lightlink::gpu {

using namespace glsl;

namespace {

static_assert(kEmLocalPickMax == int(relight::detail::EmitterSampler::kLocalPickMax));

// Points (one workgroup each) per dispatch: within the 65535 workgroups GL guarantees, and
// short enough that one dispatch never holds a GPU for long.
constexpr std::size_t kPointsPerDispatch = 32768;

}  // namespace

GpuEmitterSampling::GpuEmitterSampling(const scene::Scene& scene, const rt::Accel& accel, int lanes)
    : scene_(scene), accel_(accel), lanes_(lanes) {}

GpuEmitterSampling::~GpuEmitterSampling() = default;

Status GpuEmitterSampling::ensureBvh() {
  if (bvh_ready_) return {};
  // Without a shadow-casting static triangle nothing occludes: no BVH to walk.
  has_bvh_ = std::any_of(scene_.meshes.begin(), scene_.meshes.end(), [](const scene::MeshInstance& mesh) {
    return mesh.is_static && mesh.cast_shadows && mesh.triangleCount() > 0;
  });
  if (has_bvh_) {
    auto bvh = rt::FlatBvh::build(scene_);
    if (!bvh) return bvh.status();
    nodes_ = GlBuffer::of(bvh->nodes);
    triangles_ = GlBuffer::of(bvh->triangles);
    cutout_meshes_ = bvh->cutout_meshes;
  } else {
    nodes_ = GlBuffer(16, nullptr);
    triangles_ = GlBuffer(16, nullptr);
  }
  bvh_ready_ = true;
  return {};
}

Expected<bool> GpuEmitterSampling::trace(const relight::detail::EmitterSampler& sampler,
                                         const relight::detail::EmitterReceivers& points, int samples, int bands,
                                         const std::string& stage, std::vector<float>& layers, std::size_t& rays) {
  declined_.clear();
  if (!sampler.uniformRadiance()) {
    declined_ = "an emitter's emission is read from a texture, which the GPU sampler does not read";
    return false;
  }
  if (bands < 0 || bands > 4) {
    declined_ = fmt::format("{} SH bands (the GPU sampler projects up to 4)", bands);
    return false;
  }
  if (Status s = ensureBvh(); !s) return s;
  if (cutout_meshes_ > 0) {
    declined_ = fmt::format("{} shadow-casting mesh(es) with alpha cut-outs, which the GPU BVH does not model",
                            cutout_meshes_);
    return false;
  }
  const bool sh = bands > 0;
  if (sh != points.normal.empty()) return internalError("gpu emitter sampling: normals given for SH or missing for irradiance");
  const std::size_t n = points.position.size(), L = std::size_t(sampler.layerCount());
  if (points.rotation.size() != n || (!sh && points.normal.size() != n) || (!points.valid.empty() && points.valid.size() != n))
    return internalError("gpu emitter sampling: {} points but {} rotations, {} normals, {} validity flags", n,
                         points.rotation.size(), points.normal.size(), points.valid.size());
  const std::size_t stride = sh ? std::size_t(3) * bands * bands : 3;
  const std::size_t m = sampler.triangleCount();
  layers.assign(n * L * stride, 0.0f);
  if (n == 0 || m == 0 || samples <= 0) return true;

  const std::string key = sh ? fmt::format("sh{}", bands) : "irradiance";
  auto it = std::find_if(programs_.begin(), programs_.end(), [&](const auto& p) { return p.first == key; });
  if (it == programs_.end()) {
    std::vector<ShaderDefine> defines{{"LANES", std::to_string(lanes_)}};
    if (sh) defines.push_back({"MODE_SH", "1"}), defines.push_back({"BANDS", std::to_string(bands)});
    auto prog = GlProgram::compute("emitter_points.comp", defines);
    if (!prog) return prog.status();
    programs_.emplace_back(key, std::move(*prog));
    it = programs_.end() - 1;
  }
  const GlProgram& prog = it->second;

  const auto t = sampler.tables();
  std::vector<GpuEmitter> em(m);
  std::vector<double> pick(4 * m, 0.0);
  for (std::size_t e = 0; e < m; ++e) {
    em[e].p0_inv_pick = glm::vec4(t.p0[e], t.inv_pick[e]);
    em[e].e1_inv_pdf_area = glm::vec4(t.e1[e], t.inv_pdf_area[e]);
    em[e].e2_layer = glm::vec4(t.e2[e], float(t.layer[e]));
    em[e].normal_two_sided = glm::vec4(t.normal[e], t.double_sided[e] ? 1.0f : 0.0f);
    em[e].radiance = glm::vec4(sampler.constantRadiance(e), 0.0f);
    pick[4 * e] = t.cdf[e], pick[4 * e + 1] = t.weight[e], pick[4 * e + 2] = t.area[e];
  }
  std::vector<glm::vec4> pos(n), nrm(sh ? 1 : n);
  std::vector<std::uint32_t> valid(n, 1u);
  for (std::size_t i = 0; i < n; ++i) {
    pos[i] = glm::vec4(points.position[i], 0.0f);
    if (!sh) nrm[i] = glm::vec4(points.normal[i], 0.0f);
    if (!points.valid.empty()) valid[i] = points.valid[i];
  }
  const GlBuffer emitters = GlBuffer::of(em), pick_buf = GlBuffer::of(pick), pos_buf = GlBuffer::of(pos),
                 nrm_buf = GlBuffer::of(nrm), valid_buf = GlBuffer::of(valid),
                 rot_buf(points.rotation.size() * sizeof(glm::vec2), points.rotation.data()),
                 out(layers.size() * sizeof(float), nullptr), ray_buf(n * sizeof(std::uint32_t), nullptr);
  emitters.bindStorage(kEmEmitters);
  pick_buf.bindStorage(kEmPick);
  pos_buf.bindStorage(kEmPositions);
  nrm_buf.bindStorage(kEmNormals);
  rot_buf.bindStorage(kEmRotation);
  valid_buf.bindStorage(kEmValid);
  out.bindStorage(kEmOut);
  ray_buf.bindStorage(kEmRays);
  nodes_.bindStorage(kEmBvhNodes);
  triangles_.bindStorage(kEmBvhTriangles);
  prog.use();
  prog.set("u_count", std::uint32_t(n));
  prog.set("u_samples", samples);
  prog.set("u_emitters", int(m));
  prog.set("u_layers", int(L));
  prog.set("u_local", m <= relight::detail::EmitterSampler::kLocalPickMax ? 1 : 0);
  prog.set("u_has_bvh", has_bvh_ ? 1 : 0);
  prog.set("u_eps", accel_.rayEpsilon());
  timers_.reset();
  timers_.begin(stage);
  for (std::size_t first = 0; first < n; first += kPointsPerDispatch) {
    prog.set("u_first", std::uint32_t(first));
    const std::size_t batch = std::min(kPointsPerDispatch, n - first);
    glDispatchCompute(GLuint(batch), 1, 1);
  }
  timers_.end();
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  glGetNamedBufferSubData(out.id(), 0, GLsizeiptr(layers.size() * sizeof(float)), layers.data());
  std::vector<std::uint32_t> traced(n);
  glGetNamedBufferSubData(ray_buf.id(), 0, GLsizeiptr(n * sizeof(std::uint32_t)), traced.data());
  if (Status s = glCheck("emitter sampling"); !s) return s;
  seconds_ = 0.0;
  for (const auto& [name, sec] : timers_.resolve()) seconds_ += sec;
  for (std::uint32_t r : traced) rays += r;
  return true;
}

}  // namespace lightlink::gpu
