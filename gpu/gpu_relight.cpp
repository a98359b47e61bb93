#include "gpu/gpu_relight.h"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>

#include <fmt/format.h>

#include "core/relight/direct_points.h"
#include "core/relight/passes.h"
#include "core/relight/pipeline.h"
#include "core/relight/scene_tables.h"
#include "gpu/emitter_sampling.h"
#include "gpu/gl_objects.h"
#include "gpu/shadow_maps.h"
#include "shaders/gpu_layout.h"

namespace lightlink::gpu {

using namespace glsl;
using relight::EffectsPlan;
using relight::LightSet;
using relight::LinkForm;
using relight::RelightFrame;
using relight::RelightOptions;
using relight::RelightResult;

namespace {

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

template <typename T>
std::vector<std::uint32_t> widen(std::span<const T> v) {
  return std::vector<std::uint32_t>(v.begin(), v.end());
}

// A FillPlan reordered into levels: no target of a level reads a target of the same or a
// later level, so each level is one dispatch and the result equals the CPU's front-to-back
// pass (sources that are targets are always targets listed earlier: caches::FillPlan).
struct GpuFill {
  GlBuffer target, begin, source;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> levels;  // [begin, end) in the reordered plan
  std::size_t count = 0;
};

Expected<GpuFill> levelFill(const caches::FillPlan& plan, const char* name) {
  GpuFill f;
  const std::size_t n = plan.target.size();
  f.count = n;
  std::uint32_t max_item = 0;
  for (std::uint32_t t : plan.target) max_item = std::max(max_item, t);
  std::vector<int> level_of(n ? std::size_t(max_item) + 1 : 0, -1);  // -1: not (yet) a target
  std::vector<std::int64_t> position(level_of.size(), -1);             // index of each target
  for (std::size_t t = 0; t < n; ++t) position[plan.target[t]] = std::int64_t(t);
  std::vector<int> level(n, 0);
  int max_level = -1;
  for (std::size_t t = 0; t < n; ++t) {
    int lv = 0;
    for (std::uint32_t k = plan.source_begin[t]; k < plan.source_begin[t + 1]; ++k) {
      const std::uint32_t s = plan.source[k];
      // A source filled later in the CPU's order would be read before its fill there; the
      // levels cannot express that (caches::FillPlan never does it).
      if (s < position.size() && position[s] > std::int64_t(t))
        return internalError("gpu: {} fill plan: target {} reads target {} filled after it", name, t, s);
      if (s < level_of.size() && level_of[s] >= 0) lv = std::max(lv, level_of[s] + 1);
    }
    level[t] = lv;
    level_of[plan.target[t]] = lv;
    max_level = std::max(max_level, lv);
  }
  std::vector<std::uint32_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = std::uint32_t(i);
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return level[a] < level[b]; });
  std::vector<std::uint32_t> target(n), begin(n + 1, 0), source;
  source.reserve(plan.source.size());
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t t = order[i];
    target[i] = plan.target[t];
    for (std::uint32_t k = plan.source_begin[t]; k < plan.source_begin[t + 1]; ++k) source.push_back(plan.source[k]);
    begin[i + 1] = std::uint32_t(source.size());
  }
  for (int lv = 0, i = 0; lv <= max_level; ++lv) {
    const int start = i;
    while (i < int(n) && level[order[i]] == lv) ++i;
    f.levels.emplace_back(std::uint32_t(start), std::uint32_t(i));
  }
  f.target = GlBuffer::of(target);
  f.begin = GlBuffer::of(begin);
  f.source = GlBuffer::of(source);
  return f;
}

// fp16 arrays as uploaded from the artifact, padded to whole uint32 words.
GlBuffer halves(std::span<const half_bits> h) {
  std::vector<half_bits> padded(h.begin(), h.end());
  if (padded.size() % 2) padded.push_back(0);
  return GlBuffer::of(padded);
}

struct GpuLinks {
  std::size_t caches = 0, links = 0;
  int ncl = 0;
  GlBuffer offsets, node, coeffs, direction, omega, sky, valid;
  std::size_t projectedBytes() const { return links * (4 + 2 * std::size_t(ncl)); }
  std::size_t runtimeBytes() const { return links * (4 + 4 + 2); }
};

GpuLinks uploadLinks(const links::LinksView& v, std::span<const std::uint8_t> valid) {
  GpuLinks g;
  g.caches = v.cacheCount();
  g.links = v.linkCount();
  g.ncl = v.bands * v.bands;
  g.offsets = GlBuffer(v.offsets.size() * 4, v.offsets.data());
  g.node = GlBuffer(v.node.size() * 4, v.node.data());
  g.coeffs = halves(v.coeffs);
  g.direction = GlBuffer(v.direction.size() * 4, v.direction.data());
  g.omega = halves(v.solid_angle);
  g.sky = GlBuffer(v.sky.size() * 4, v.sky.data());
  g.valid = GlBuffer::of(widen(valid));
  return g;
}

}  // namespace

// The GPU backend's relight passes (relight::RelightPasses): everything per relight stays on
// the GPU; only what RelightResult carries is read back, in texels().
class GpuPasses final : public relight::RelightPasses {
 public:
  GpuPasses(const relight::SceneTables& t, const GpuOptions& o)
      : t_(t), scene(t.scene), p(t.p), options(o) {}
  ~GpuPasses() override {
    if (staging_ptr) glUnmapNamedBuffer(staging.id());
  }
  Status setup();

  std::string_view backend() const override { return "gpu"; }
  relight::detail::EmitterTracer* emitterTracer() override {
    return options.emitter_sampling ? emitter_sampling_.get() : nullptr;
  }
  std::string kernelName(const RelightOptions&) const override { return fmt::format("glsl-lanes{}", options.lanes); }
  Status begin(const RelightFrame& f) override;
  Status setEmission(std::span<const glm::vec3> emission_b, std::uint64_t generation) override;
  Status surfelDirect(const RelightFrame& f, std::span<const glm::vec3> surfel_emit, RelightResult& res) override;
  Status pullAndLight(const RelightFrame& f, const std::string& prefix, bool grid, RelightResult& res) override;
  Status gather(const RelightFrame& f, int bounce, bool fill_grid, RelightResult& res) override;
  Expected<relight::BounceSums> bounceSums() override;
  bool sumsLag() const override { return true; }
  Status cacheDirect(const RelightFrame& f, const relight::EmitterTexels& emitter, RelightResult& res) override;
  Status texels(const RelightFrame& f, RelightResult& res) override;

  Expected<double> measureStream(std::size_t bytes, bool copy, int repeats);

 private:
  Expected<const GlProgram*> variant(const std::string& shader, const std::vector<ShaderDefine>& defines) {
    std::string key = shader;
    for (const auto& d : defines) key += fmt::format(" {}={}", d.name, d.value);
    auto it = variants.find(key);
    if (it != variants.end()) return &it->second;
    auto prog = GlProgram::compute(shader, defines);
    if (!prog) return prog.status();
    return &variants.emplace(key, std::move(*prog)).first->second;
  }

  // LIGHTLINK_GPU_DEBUG=1: sums of a buffer's floats after a stage, on stderr (driver triage).
  static void debugSum(const char* label, const GlBuffer& buf) {
    static const bool on = std::getenv("LIGHTLINK_GPU_DEBUG") != nullptr;
    if (!on) return;
    glMemoryBarrier(GL_ALL_BARRIER_BITS);
    glFinish();
    std::vector<float> v(buf.bytes() / 4);
    glGetNamedBufferSubData(buf.id(), 0, GLsizeiptr(v.size() * 4), v.data());
    double sum = 0.0, abs_sum = 0.0;
    for (float x : v) sum += x, abs_sum += std::abs(x);
    std::fprintf(stderr, "gpu debug %-16s floats %zu sum %.6g abs %.6g\n", label, v.size(), sum, abs_sum);
  }

  static void dispatch(const GlProgram& prog, std::size_t items, std::size_t group) {
    if (items == 0) return;
    prog.use();
    glDispatchCompute(GLuint((items + group - 1) / group), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }

  template <class F>
  Status stage(std::string name, F&& body) {
    timers.begin(std::move(name));
    Status st = body();
    timers.end();
    return st;
  }

  void ensureBuffers(int stride);
  Status prepareLights(const RelightFrame& f);
  void pullFlux(const GlBuffer& radiosity_in);
  Status lightCaches(const GpuLinks& links, const GlBuffer& node_rad, const GlBuffer& out, int bands, LinkForm form,
                     bool sky);
  void applyFill(const GpuFill& f, const GlBuffer& data, int stride);
  void dispatchLevels(const GlProgram& prog, const GpuFill& f, int stride);
  void readBack(const RelightFrame& f, RelightResult& res);

  const relight::SceneTables& t_;
  const scene::Scene& scene;
  const precompute::Precomputation& p;
  GpuOptions options;
  std::unique_ptr<ShadowMaps> shadows;
  GpuTimers timers;
  // The emitters' sampling on the GPU (declines what it cannot run; then the host samples).
  std::unique_ptr<GpuEmitterSampling> emitter_sampling_;

  std::size_t ns = 0, nodes = 0, ncache = 0, ngrid = 0, texels_ = 0;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> tree_levels;  // deepest first

  // Programs: fixed ones at creation, band/form variants on first use.
  GlProgram light_surfels, light_caches, leaf_flux, pull, radiosity, fill, dilate, texel_pass;
  std::map<std::string, GlProgram> variants;

  // Static buffers.
  GlBuffer surfel_pos, surfel_normal, surfel_albedo, surfel_area, surfel_leaf, surfel_normal_area, tree_nodes;
  GlBuffer cache_pos, cache_normal, cache_valid, cache_of_texel, lm_has_value;
  GlBuffer gather_begin, gather_cache, gather_weight, gather_from_grid;
  GpuLinks lm, grid;
  GpuFill lm_fill, grid_fill, dilation;
  GlBuffer dummy;

  // Per-relight buffers.
  GlBuffer lights_buf, views_buf, given, b0, b, albedo_emit, flux, rad, sky_matrix;
  GlBuffer lm_sh, grid_sh, cache_direct, emitter_buf, partials;
  GlBuffer texel_sh, texel_direct, texel_valid;
  GlBuffer staging;
  void* staging_ptr = nullptr;
  std::size_t staging_bytes = 0;
  int sized_stride = 0;

  // Per relight: lights uploaded and shadow maps rendered (once, on first need).
  bool lights_ready = false;
  std::vector<std::uint8_t> emits;  // per light: non-zero power
  std::vector<std::pair<std::string, double>> host_stages;  // CPU-side stages, host seconds
  GLsync bounce_fence = nullptr;    // the last gather's sums, copied to staging
  // What the GPU holds (generations of the pipeline's EmissionState products).
  std::uint64_t emission_generation = ~std::uint64_t(0), emitter_generation = ~std::uint64_t(0);
};

Status GpuPasses::setup() {
  emitter_sampling_ = std::make_unique<GpuEmitterSampling>(scene, t_.accel, options.emitter_lanes);
  auto need = [](Expected<GlProgram> e, GlProgram& out) -> Status {
    if (!e) return e.status();
    out = std::move(*e);
    return {};
  };
  if (Status s = need(GlProgram::compute("light_points.comp", {{"MODE_SURFELS", "1"}}), light_surfels); !s) return s;
  if (Status s = need(GlProgram::compute("light_points.comp", {{"MODE_CACHES", "1"}}), light_caches); !s) return s;
  if (Status s = need(GlProgram::compute("leaf_flux.comp"), leaf_flux); !s) return s;
  if (Status s = need(GlProgram::compute("pull.comp"), pull); !s) return s;
  if (Status s = need(GlProgram::compute("radiosity.comp"), radiosity); !s) return s;
  if (Status s = need(GlProgram::compute("fill.comp"), fill); !s) return s;
  if (Status s = need(GlProgram::compute("fill.comp", {{"DILATE", "1"}}), dilate); !s) return s;
  if (Status s = need(GlProgram::compute("texels.comp"), texel_pass); !s) return s;
  auto sm = ShadowMaps::create(scene, options.shadow_resolution);
  if (!sm) return sm.status();
  shadows = std::move(*sm);

  const auto& sf = p.surfels;
  const auto& t = p.tree;
  ns = sf.size();
  nodes = t.nodeCount();
  ncache = p.lightmap.size();
  ngrid = p.has_grid ? t_.grid_links.cacheCount() : 0;
  texels_ = std::size_t(p.lightmap.width) * p.lightmap.height;
  std::vector<glm::vec4> v4(ns);
  for (std::size_t s = 0; s < ns; ++s) v4[s] = glm::vec4(sf.position[s], 0.0f);
  surfel_pos = GlBuffer::of(v4);
  for (std::size_t s = 0; s < ns; ++s) v4[s] = glm::vec4(sf.normal[s], 0.0f);
  surfel_normal = GlBuffer::of(v4);
  for (std::size_t s = 0; s < ns; ++s) v4[s] = glm::vec4(sf.normal[s], sf.area[s]);
  surfel_normal_area = GlBuffer::of(v4);
  for (std::size_t s = 0; s < ns; ++s) v4[s] = glm::vec4(sf.albedo[s], 0.0f);
  surfel_albedo = GlBuffer::of(v4);
  // The pull's leaf areas and node inverse areas, as the CPU pull (relight::pullAreas:
  // surfels no cache sees add nothing to their nodes).
  const relight::PullAreas* pull_areas = &t_.pull;
  surfel_area = GlBuffer::of(pull_areas->surfel);
  surfel_leaf = GlBuffer::of(t.leaf_of_surfel);
  std::vector<glm::ivec4> tn(nodes);
  for (std::size_t n = 0; n < nodes; ++n) {
    const float inv_area = pull_areas->inv_node[n];
    int bits;
    std::memcpy(&bits, &inv_area, 4);
    tn[n] = glm::ivec4(t.left[n], t.right[n], bits, 0);
  }
  tree_nodes = GlBuffer::of(tn);
  for (std::size_t d = t.levelCount(); d-- > 0;) tree_levels.emplace_back(t.level_begin[d], t.level_begin[d + 1]);

  std::vector<glm::vec4> c4(ncache);
  for (std::size_t c = 0; c < ncache; ++c) c4[c] = glm::vec4(p.lightmap.position[c], 0.0f);
  cache_pos = GlBuffer::of(c4);
  for (std::size_t c = 0; c < ncache; ++c) c4[c] = glm::vec4(p.lightmap.normal[c], 0.0f);
  cache_normal = GlBuffer::of(c4);
  cache_valid = GlBuffer::of(widen(std::span<const std::uint8_t>(p.lightmap.valid)));
  cache_of_texel = GlBuffer::of(p.lightmap.cache_of_texel);
  lm_has_value = GlBuffer::of(widen(std::span<const std::uint8_t>(t_.lm_has_value)));
  gather_begin = GlBuffer::of(t_.gather_begin);
  gather_cache = GlBuffer::of(t_.gather_cache);
  gather_weight = GlBuffer::of(t_.gather_weight);
  gather_from_grid = GlBuffer::of(widen(std::span<const std::uint8_t>(t_.gather_from_grid)));
  lm = uploadLinks(t_.lm_links, p.lightmap.valid);
  if (ngrid) grid = uploadLinks(t_.grid_links, p.grid.valid);
  auto lf = levelFill(p.lightmap_fill, "lightmap");
  if (!lf) return lf.status();
  lm_fill = std::move(*lf);
  if (ngrid) {
    auto gf = levelFill(p.grid_fill, "grid");
    if (!gf) return gf.status();
    grid_fill = std::move(*gf);
  }
  auto df = levelFill(p.dilation, "dilation");
  if (!df) return df.status();
  dilation = std::move(*df);
  dummy = GlBuffer(16, nullptr);

  given = GlBuffer(ns * 16, nullptr);
  b0 = GlBuffer(ns * 16, nullptr);
  b = GlBuffer(ns * 16, nullptr);
  albedo_emit = GlBuffer(ns * 32, nullptr);
  flux = GlBuffer(nodes * 16, nullptr);
  rad = GlBuffer(nodes * 16, nullptr);
  cache_direct = GlBuffer(ncache * 16, nullptr);
  emitter_buf = GlBuffer(ncache * 16, nullptr);
  partials = GlBuffer(((ns + kGatherGroup - 1) / kGatherGroup) * 8, nullptr);
  texel_direct = GlBuffer(texels_ * 16, nullptr);
  texel_valid = GlBuffer(texels_ * 4, nullptr);
  return glCheck("gpu relight setup (uploads)");
}

void GpuPasses::ensureBuffers(int stride) {
  if (stride == sized_stride) return;
  sized_stride = stride;
  const std::size_t s = std::size_t(stride) * 4;
  lm_sh = GlBuffer(ncache * s, nullptr);
  grid_sh = GlBuffer(ngrid * s, nullptr);
  texel_sh = GlBuffer(texels_ * s, nullptr);
  // Staging: texel SH, texel direct, texel valid, grid SH, surfel radiosity, bounce partials.
  if (staging_ptr) glUnmapNamedBuffer(staging.id());
  staging_bytes = texels_ * s + texels_ * 16 + texels_ * 4 + ngrid * s + ns * 16 + partials.bytes();
  staging = GlBuffer(staging_bytes, nullptr, GL_MAP_READ_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT |
                                                 GL_CLIENT_STORAGE_BIT);
  staging_ptr = glMapNamedBufferRange(staging.id(), 0, GLsizeiptr(std::max<std::size_t>(staging_bytes, 16)),
                                      GL_MAP_READ_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT);
}

// Leaf flux from per-surfel radiosity, then the pull, level by level (deepest first).
void GpuPasses::pullFlux(const GlBuffer& radiosity_in) {
  radiosity_in.bindStorage(kLfRadiosity);
  surfel_area.bindStorage(kLfArea);
  surfel_leaf.bindStorage(kLfLeaf);
  flux.bindStorage(kLfFlux);
  leaf_flux.set("u_count", std::uint32_t(ns));
  dispatch(leaf_flux, ns, 256);
  tree_nodes.bindStorage(kPuNodes);
  flux.bindStorage(kPuFlux);
  for (const auto& [lb, le] : tree_levels) {
    if (tree_levels.front().first == lb) continue;  // the deepest level holds only leaves
    pull.set("u_begin", lb);
    pull.set("u_end", le);
    dispatch(pull, le - lb, 256);
  }
}

Status GpuPasses::lightCaches(const GpuLinks& links, const GlBuffer& node_rad, const GlBuffer& out,
                                       int bands, LinkForm form, bool sky) {
  if (links.caches == 0) return {};
  std::vector<ShaderDefine> defs = {{"BANDS", std::to_string(bands)},
                                    {"LINK_NC", std::to_string(links.ncl)},
                                    {"LANES", std::to_string(options.lanes)}};
  if (form == LinkForm::kRuntime) defs.push_back({"RUNTIME", "1"});
  auto prog = variant("cache_light.comp", defs);
  if (!prog) return prog.status();
  const GlProgram& pr = **prog;
  links.offsets.bindStorage(kClOffsets);
  links.node.bindStorage(kClNode);
  (form == LinkForm::kRuntime ? links.direction : links.coeffs).bindStorage(kClCoeffs);
  links.omega.bindStorage(kClOmega);
  node_rad.bindStorage(kClRad);
  links.valid.bindStorage(kClValid);
  links.sky.bindStorage(kClSkyVis);
  (sky ? sky_matrix : dummy).bindStorage(kClSkyMatrix);
  out.bindStorage(kClOut);
  pr.set("u_cache_count", std::uint32_t(links.caches));
  pr.set("u_sky", sky ? 1 : 0);
  pr.set("u_link_nc", links.ncl);
  dispatch(pr, links.caches, std::size_t(64 / options.lanes));
  return {};
}

void GpuPasses::applyFill(const GpuFill& f, const GlBuffer& data, int stride) {
  if (f.count == 0) return;
  data.bindStorage(kFiData);
  dispatchLevels(fill, f, stride);
}

// One dispatch per level of a leveled plan, with fill.comp or its DILATE variant.
void GpuPasses::dispatchLevels(const GlProgram& prog, const GpuFill& f, int stride) {
  f.target.bindStorage(kFiTarget);
  f.begin.bindStorage(kFiBegin);
  f.source.bindStorage(kFiSource);
  prog.set("u_stride", std::uint32_t(stride));
  for (const auto& [lb, le] : f.levels) {
    prog.set("u_begin", lb);
    prog.set("u_end", le);
    dispatch(prog, le - lb, 64);
  }
}

Status GpuPasses::begin(const RelightFrame& f) {
  ensureBuffers(int(f.stride));
  timers.reset();
  host_stages.clear();
  lights_ready = false;
  if (bounce_fence) glDeleteSync(bounce_fence), bounce_fence = nullptr;
  return {};
}

Status GpuPasses::setEmission(std::span<const glm::vec3> emission_b, std::uint64_t generation) {
  if (generation == emission_generation) return {};
  std::vector<glm::vec4> ae(2 * ns);
  for (std::size_t s = 0; s < ns; ++s) {
    ae[2 * s] = glm::vec4(p.surfels.albedo[s], 0.0f);
    ae[2 * s + 1] = glm::vec4(s < emission_b.size() ? emission_b[s] : glm::vec3(0.0f), 0.0f);
  }
  albedo_emit.upload(ae.data(), ae.size() * 16);
  emission_generation = generation;
  return {};
}

// The relight's lights and, for those a pass evaluates, their shadow maps: all emitting
// lights for the surfels (unless the surfel light is given), baked ones for the texels.
Status GpuPasses::prepareLights(const RelightFrame& f) {
  if (lights_ready) return {};
  lights_ready = true;
  const auto& L = f.lights.lights();
  const bool given_e = !f.options.surfel_irradiance.empty();
  std::vector<GpuLight> gl(L.size());
  emits.assign(L.size(), 0);
  for (std::size_t i = 0; i < L.size(); ++i) {
    const scene::Light& l = L[i].light;
    emits[i] = relight::detail::lightEmits(l);
    GpuLight& g = gl[i];
    g.position_range = glm::vec4(l.position, l.range);
    g.direction_cos_outer = glm::vec4(l.direction, std::cos(l.outer_cone_angle));
    g.color_intensity = glm::vec4(l.color, emits[i] ? l.intensity : 0.0f);
    g.cos_inner_baked = glm::vec4(std::cos(l.inner_cone_angle), L[i].baked ? 1.0f : 0.0f, 0.0f, 0.0f);
    g.kind_views = glm::ivec4(l.kind == scene::Light::Kind::kPoint  ? kLightPoint
                              : l.kind == scene::Light::Kind::kSpot ? kLightSpot
                                                                    : kLightDirectional,
                              0, 0, 0);
  }
  std::vector<std::uint8_t> mapped(L.size());
  for (std::size_t i = 0; i < L.size(); ++i)
    mapped[i] = emits[i] && ((!given_e && f.plan.punctual) || (f.plan.baked_direct && f.coarse_direct && L[i].baked));
  std::vector<GpuShadowView> views;
  const bool any_mapped = std::find(mapped.begin(), mapped.end(), 1) != mapped.end();
  if (any_mapped) {
    std::vector<scene::Light> raw(L.size());
    for (std::size_t i = 0; i < L.size(); ++i) raw[i] = L[i].light;
    if (Status st = stage("shadow_maps", [&] { return shadows->render(raw, mapped, gl, views); }); !st) return st;
  }
  const float scene_size = std::max(scene.scale, 1e-6f);
  for (GlProgram* prog : {&light_surfels, &light_caches}) {
    prog->set("u_bias", options.bias_scene * scene_size);
    prog->set("u_normal_offset", options.normal_offset_texels);
    prog->set("u_slope_bias", options.slope_bias_texels);
  }
  if (lights_buf.bytes() < std::max<std::size_t>(gl.size(), 1) * sizeof(GpuLight))
    lights_buf = GlBuffer(std::max<std::size_t>(gl.size(), 8) * sizeof(GpuLight), nullptr);
  lights_buf.upload(gl.data(), gl.size() * sizeof(GpuLight));
  if (views_buf.bytes() < std::max<std::size_t>(views.size(), 1) * sizeof(GpuShadowView))
    views_buf = GlBuffer(std::max<std::size_t>(views.size(), 12) * sizeof(GpuShadowView), nullptr);
  views_buf.upload(views.data(), views.size() * sizeof(GpuShadowView));
  if (any_mapped) glBindTextureUnit(kLpShadowUnit, shadows->texture());
  return {};
}

Status GpuPasses::surfelDirect(const RelightFrame& f, std::span<const glm::vec3> surfel_emit, RelightResult& res) {
  if (Status st = prepareLights(f); !st) return st;
  const auto& given_e = f.options.surfel_irradiance;
  // The emitters' direct light at the surfels starts the sum the shader adds punctual
  // lights to (docs/relight.md, the surfel_emitter pass).
  const bool surfel_emits =
      std::any_of(surfel_emit.begin(), surfel_emit.end(), [](const glm::vec3& e) { return e != glm::vec3(0.0f); });
  const bool use_given = !given_e.empty() || surfel_emits;
  if (f.plan.sky) {
    // The sky matrix is ready now (the pipeline builds it before the first cache lighting).
    std::vector<float> all;
    for (int ch = 0; ch < 3; ++ch) all.insert(all.end(), f.sky_matrix[ch].begin(), f.sky_matrix[ch].end());
    if (sky_matrix.bytes() < all.size() * 4) sky_matrix = GlBuffer(all.size() * 4, nullptr);
    sky_matrix.upload(all.data(), all.size() * 4);
  }
  if (Status st = stage("surfel_direct", [&]() -> Status {
        if (use_given) {
          std::vector<glm::vec4> e(ns);
          for (std::size_t s = 0; s < ns; ++s)
            e[s] = glm::vec4((given_e.empty() ? glm::vec3(0.0f) : given_e[s]) +
                                 (s < surfel_emit.size() ? surfel_emit[s] : glm::vec3(0.0f)),
                             0.0f);
          given.upload(e.data(), e.size() * 16);
        }
        surfel_pos.bindStorage(kLpPositions);
        surfel_normal.bindStorage(kLpNormals);
        lights_buf.bindStorage(kLpLights);
        views_buf.bindStorage(kLpViews);
        dummy.bindStorage(kLpValid);
        surfel_albedo.bindStorage(kLpAlbedo);
        given.bindStorage(kLpGiven);
        b0.bindStorage(kLpOut);
        b.bindStorage(kLpOut2);
        light_surfels.set("u_count", std::uint32_t(ns));
        light_surfels.set("u_light_count", !given_e.empty() || !f.plan.punctual ? 0 : int(f.lights.lights().size()));
        light_surfels.set("u_use_given", use_given ? 1 : 0);
        light_surfels.set("u_keep_out2", f.warm ? 1 : 0);
        dispatch(light_surfels, ns, 64);
        return {};
      });
      !st)
    return st;
  res.counts.surfels_lit = f.plan.punctual ? ns : 0;
  res.passes.surfel_direct = f.plan.punctual ? 1 : 0;
  debugSum("b0", b0);
  return {};
}

Status GpuPasses::pullAndLight(const RelightFrame& f, const std::string& prefix, bool light_grid,
                               RelightResult& res) {
  if (Status st = stage(prefix + "pull", [&] {
        pullFlux(b);
        return Status{};
      });
      !st)
    return st;
  if (Status st = stage(prefix + "node_radiosity", [&] {
        tree_nodes.bindStorage(kPuNodes);
        flux.bindStorage(kPuFlux);
        rad.bindStorage(kPuRad);
        radiosity.set("u_count", std::uint32_t(nodes));
        dispatch(radiosity, nodes, 256);
        debugSum("rad", rad);
        return Status{};
      });
      !st)
    return st;
  res.passes.pulls++;
  res.counts.nodes_pulled = nodes;
  const int bands = f.bands;
  return stage(prefix + "cache_lighting", [&]() -> Status {
    if (Status st = lightCaches(lm, rad, lm_sh, bands, f.options.link_form, f.plan.sky); !st) return st;
    debugSum("lm_sh", lm_sh);
    res.passes.cache_lighting++;
    res.passes.sky += f.plan.sky ? 1 : 0;
    res.counts.caches_summed = lm.caches;
    res.counts.links_read += lm.links;
    if (light_grid) {
      if (Status st = lightCaches(grid, rad, grid_sh, bands, f.options.link_form, f.plan.sky); !st) return st;
      debugSum("grid_sh", grid_sh);
      res.passes.grid_lighting++;
      res.counts.grid_caches_summed = grid.caches;
      res.counts.links_read += grid.links;
    }
    return {};
  });
}

Status GpuPasses::gather(const RelightFrame& f, int bounce, bool fill_grid, RelightResult&) {
  auto program = variant("gather.comp", {{"BANDS", std::to_string(f.bands)}});
  if (!program) return program.status();
  const GlProgram& gp = **program;
  const int stride = int(f.stride);
  if (Status st = stage(fmt::format("bounce{}_gather", bounce), [&]() -> Status {
        applyFill(lm_fill, lm_sh, stride);
        if (fill_grid) applyFill(grid_fill, grid_sh, stride);
        gather_begin.bindStorage(kGaBegin);
        gather_cache.bindStorage(kGaCache);
        gather_weight.bindStorage(kGaWeight);
        gather_from_grid.bindStorage(kGaFromGrid);
        lm_sh.bindStorage(kGaLightmapSh);
        (f.plan.grid ? grid_sh : dummy).bindStorage(kGaGridSh);
        surfel_normal_area.bindStorage(kGaSurfel);
        albedo_emit.bindStorage(kGaAlbedoEmit);
        b0.bindStorage(kGaB0);
        b.bindStorage(kGaB);
        partials.bindStorage(kGaPartials);
        gp.set("u_count", std::uint32_t(ns));
        dispatch(gp, ns, kGatherGroup);
        return {};
      });
      !st)
    return st;
  // The stop test's two sums travel behind a fence while the GPU pulls and lights.
  const std::size_t groups = (ns + kGatherGroup - 1) / kGatherGroup;
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_CLIENT_MAPPED_BUFFER_BARRIER_BIT);
  glCopyNamedBufferSubData(partials.id(), staging.id(), 0, GLintptr(staging_bytes - partials.bytes()),
                           GLsizeiptr(groups * 8));
  if (bounce_fence) glDeleteSync(bounce_fence);
  bounce_fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
  return {};
}

Expected<relight::BounceSums> GpuPasses::bounceSums() {
  if (!bounce_fence) return internalError("gpu: bounce sums asked for before a gather");
  const GLenum w = glClientWaitSync(bounce_fence, GL_SYNC_FLUSH_COMMANDS_BIT, 60'000'000'000ull);
  glDeleteSync(bounce_fence);
  bounce_fence = nullptr;
  if (w == GL_TIMEOUT_EXPIRED || w == GL_WAIT_FAILED) return internalError("gpu: a bounce did not finish");
  const std::size_t groups = (ns + kGatherGroup - 1) / kGatherGroup;
  const auto* part =
      reinterpret_cast<const float*>(static_cast<const char*>(staging_ptr) + (staging_bytes - partials.bytes()));
  relight::BounceSums sums;  // group order: the CPU's chunk order
  for (std::size_t g = 0; g < groups; ++g) sums.added += part[2 * g], sums.total += part[2 * g + 1];
  return sums;
}

Status GpuPasses::cacheDirect(const RelightFrame& f, const relight::EmitterTexels& emitter, RelightResult& res) {
  const bool baked = f.plan.baked_direct && f.coarse_direct;
  const bool emitted = !emitter.value.empty();
  if (emitted && emitter.generation != emitter_generation) {
    std::vector<glm::vec4> e(ncache);
    for (std::size_t c = 0; c < ncache && c < emitter.value.size(); ++c) e[c] = glm::vec4(emitter.value[c], 0.0f);
    emitter_buf.upload(e.data(), e.size() * 16);
    emitter_generation = emitter.generation;
  }
  if (baked)
    if (Status st = prepareLights(f); !st) return st;
  const auto& L = f.lights.lights();
  if (Status st = stage("baked_direct", [&]() -> Status {
        if (!baked && !emitted) {
          cache_direct.zero();
          return {};
        }
        cache_pos.bindStorage(kLpPositions);
        cache_normal.bindStorage(kLpNormals);
        lights_buf.bindStorage(kLpLights);
        views_buf.bindStorage(kLpViews);
        cache_valid.bindStorage(kLpValid);
        dummy.bindStorage(kLpAlbedo);
        (emitted ? emitter_buf : dummy).bindStorage(kLpGiven);
        cache_direct.bindStorage(kLpOut);
        dummy.bindStorage(kLpOut2);
        light_caches.set("u_count", std::uint32_t(ncache));
        light_caches.set("u_light_count", baked ? int(L.size()) : 0);
        light_caches.set("u_use_given", emitted ? 1 : 0);
        dispatch(light_caches, ncache, 64);
        return {};
      });
      !st)
    return st;
  if (baked)
    for (std::size_t i = 0; i < L.size(); ++i) res.passes.baked_direct += L[i].baked && emits[i];
  return {};
}

Status GpuPasses::texels(const RelightFrame& f, RelightResult& res) {
  const int stride = int(f.stride);
  if (Status st = stage("fill_dilate", [&]() -> Status {
        applyFill(lm_fill, lm_sh, stride);
        applyFill(lm_fill, cache_direct, 4);
        if (f.plan.grid) applyFill(grid_fill, grid_sh, stride);
        cache_of_texel.bindStorage(kTxCacheOfTexel);
        lm_has_value.bindStorage(kTxHasValue);
        lm_sh.bindStorage(kTxCacheSh);
        cache_direct.bindStorage(kTxCacheDirect);
        texel_sh.bindStorage(kTxTexelSh);
        texel_direct.bindStorage(kTxTexelDirect);
        texel_valid.bindStorage(kTxTexelValid);
        texel_pass.set("u_count", std::uint32_t(texels_));
        texel_pass.set("u_stride", std::uint32_t(stride));
        dispatch(texel_pass, texels_, 64);
        if (dilation.count) {
          texel_sh.bindStorage(kFiData);
          texel_valid.bindStorage(kFiValid);
          texel_direct.bindStorage(kFiDirect);
          dispatchLevels(dilate, dilation, stride);
        }
        return {};
      });
      !st)
    return st;
  res.passes.fill = 1;
  readBack(f, res);
  for (auto& [name, sec] : timers.resolve()) res.timings.push_back({name, sec});
  for (auto& [name, sec] : host_stages) res.timings.push_back({name, sec});
  return glCheck("gpu relight");
}

// One copy of everything RelightResult carries into the mapped staging buffer, one fence.
void GpuPasses::readBack(const RelightFrame& f, RelightResult& res) {
  const auto t_read = Clock::now();
  const std::size_t stride = f.stride;
  const std::size_t sh_bytes = texels_ * stride * 4;
  const std::size_t grid_bytes = f.plan.grid ? ngrid * stride * 4 : 0;
  const std::size_t off_sh = 0, off_dir = off_sh + sh_bytes, off_valid = off_dir + texels_ * 16;
  const std::size_t off_grid = off_valid + texels_ * 4, off_b = off_grid + ngrid * stride * 4;
  timers.begin("readback_copy");
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_CLIENT_MAPPED_BUFFER_BARRIER_BIT);
  auto copy = [&](const GlBuffer& src, std::size_t dst_off, std::size_t bytes) {
    if (bytes) glCopyNamedBufferSubData(src.id(), staging.id(), 0, GLintptr(dst_off), GLsizeiptr(bytes));
  };
  copy(texel_sh, off_sh, sh_bytes);
  copy(texel_direct, off_dir, texels_ * 16);
  copy(texel_valid, off_valid, texels_ * 4);
  copy(grid_sh, off_grid, grid_bytes);
  copy(b, off_b, ns * 16);
  timers.end();
  GLsync fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
  const GLenum w = glClientWaitSync(fence, GL_SYNC_FLUSH_COMMANDS_BIT, 120'000'000'000ull);
  glDeleteSync(fence);
  if (w == GL_TIMEOUT_EXPIRED || w == GL_WAIT_FAILED) {
    res.warnings.push_back("gpu: the readback did not finish");
    return;
  }
  const char* base = static_cast<const char*>(staging_ptr);
  res.lightmap_sh.resize(texels_ * stride);
  std::memcpy(res.lightmap_sh.data(), base + off_sh, sh_bytes);
  if (f.coarse_direct) {
    res.direct.resize(texels_);
    res.direct_width = res.width, res.direct_height = res.height;
    res.direct_valid.clear();
  }
  res.texel_valid.resize(texels_);
  const auto* dir4 = reinterpret_cast<const glm::vec4*>(base + off_dir);
  const auto* valid4 = reinterpret_cast<const std::uint32_t*>(base + off_valid);
  std::size_t filled = 0;
  for (std::size_t t = 0; t < texels_; ++t) {
    if (f.coarse_direct) res.direct[t] = glm::vec3(dir4[t]);
    res.texel_valid[t] = valid4[t] ? 1 : 0;
    filled += res.texel_valid[t];
  }
  res.counts.texels = texels_;
  res.counts.texels_filled = filled;
  if (f.plan.grid) {
    res.grid_sh.resize(ngrid * stride);
    std::memcpy(res.grid_sh.data(), base + off_grid, grid_bytes);
  } else {
    res.grid_sh.clear();
  }
  res.surfel_radiosity.resize(ns);
  const auto* b4 = reinterpret_cast<const glm::vec4*>(base + off_b);
  for (std::size_t s = 0; s < ns; ++s) res.surfel_radiosity[s] = glm::vec3(b4[s]);
  host_stages.emplace_back("readback", secondsSince(t_read));
}

// ---- GpuRelighter: the relight pipeline with the GPU passes ----------------------------------

struct GpuRelighter::Impl {
  std::unique_ptr<GlContext> ctx;
  std::unique_ptr<relight::SceneTables> tables;
  GpuPasses* passes = nullptr;  // owned by the pipeline
  std::unique_ptr<relight::RelightPipeline> pipeline;
};

GpuRelighter::GpuRelighter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

GpuRelighter::~GpuRelighter() {
  if (!impl_ || !impl_->ctx) return;
  // GL objects die with the context current; the context itself last, once released.
  std::unique_ptr<GlContext> ctx = std::move(impl_->ctx);
  {
    GlContext::Current cur(*ctx);
    impl_.reset();
  }
}

const GlContextInfo& GpuRelighter::info() const { return impl_->ctx->info(); }

Expected<std::unique_ptr<GpuRelighter>> GpuRelighter::create(const scene::Scene& scene, const rt::Accel& accel,
                                                             const precompute::Precomputation& p,
                                                             links::LinksView lightmap_links,
                                                             links::LinksView grid_links, const GpuOptions& options) {
  GpuOptions opts = options;
  // Driver triage without a rebuild: LIGHTLINK_GPU_LANES overrides the threads per cache.
  if (const char* lanes = std::getenv("LIGHTLINK_GPU_LANES")) opts.lanes = std::atoi(lanes);
  if (opts.lanes < 1 || opts.lanes > 64 || (opts.lanes & (opts.lanes - 1)) != 0)
    return invalidInput("gpu: lanes {} must be a power of two in 1..64", opts.lanes);
  if (opts.emitter_lanes < 1 || opts.emitter_lanes > 32 || (opts.emitter_lanes & (opts.emitter_lanes - 1)) != 0)
    return invalidInput("gpu: emitter_lanes {} must be a power of two in 1..32", opts.emitter_lanes);
  if (!(opts.bias_scene >= 0.0f) || !(opts.normal_offset_texels >= 0.0f) || !(opts.slope_bias_texels >= 0.0f))
    return invalidInput("gpu: shadow biases must be finite and >= 0");
  auto tables = relight::SceneTables::build(scene, accel, p, lightmap_links, grid_links);
  if (!tables) return tables.status();
  auto ctx = GlContext::create();
  if (!ctx) return ctx.status();
  auto impl = std::make_unique<Impl>();
  impl->ctx = std::move(*ctx);
  impl->tables = std::make_unique<relight::SceneTables>(std::move(*tables));
  std::unique_ptr<GpuRelighter> r(new GpuRelighter(std::move(impl)));
  Impl& m = *r->impl_;
  GlContext::Current cur(*m.ctx);
  if (!cur.status()) return cur.status();
  auto passes = std::make_unique<GpuPasses>(*m.tables, opts);
  if (Status s = passes->setup(); !s) return s;
  m.passes = passes.get();
  m.pipeline = std::make_unique<relight::RelightPipeline>(*m.tables, std::move(passes));
  return r;
}

EffectsPlan GpuRelighter::plan(const LightSet& lights, const RelightOptions& options) const {
  return impl_->pipeline->plan(lights, options);
}

bool GpuRelighter::incrementalFor(const LightSet& lights, const RelightOptions& options) const {
  return impl_->pipeline->incrementalFor(lights, options);
}

void GpuRelighter::invalidate() { impl_->pipeline->invalidate(true); }

Status GpuRelighter::relightInto(const LightSet& lights, const RelightOptions& o, RelightResult& res) {
  GlContext::Current cur(*impl_->ctx);
  if (!cur.status()) return cur.status();
  return impl_->pipeline->relightInto(lights, o, res);
}

Expected<double> GpuRelighter::measureStream(std::size_t bytes, bool copy, int repeats) {
  GlContext::Current cur(*impl_->ctx);
  if (!cur.status()) return cur.status();
  return impl_->passes->measureStream(bytes, copy, repeats);
}

Expected<double> GpuPasses::measureStream(std::size_t bytes, bool copy, int repeats) {
  bytes = std::max<std::size_t>(bytes / 16 * 16, 16);
  auto prog = variant("bandwidth.comp", copy ? std::vector<ShaderDefine>{{"COPY", "1"}} : std::vector<ShaderDefine>{});
  if (!prog) return prog.status();
  GlBuffer src(bytes, nullptr), dst(copy ? bytes : 1 << 20, nullptr);
  src.bindStorage(kBwSource);
  dst.bindStorage(kBwDest);
  (*prog)->set("u_count", std::uint32_t(bytes / 16));
  (*prog)->use();
  // Enough groups to fill any GPU, few enough that each thread streams many elements.
  const GLuint groups = GLuint(std::min<std::size_t>(std::max<std::size_t>(bytes / 16 / 256 / 8, 1), 65535));
  std::vector<double> t;
  for (int r = 0; r <= repeats; ++r) {
    timers.reset();
    timers.begin("stream");
    glDispatchCompute(groups, 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    timers.end();
    const auto res = timers.resolve();
    if (r > 0) t.push_back(res[0].second);  // the first is a warm-up
  }
  if (Status s = glCheck("bandwidth kernel"); !s) return s;
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

}  // namespace lightlink::gpu
