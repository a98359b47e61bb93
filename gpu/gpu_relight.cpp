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
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/common/sampling.h"
#include "core/relight/direct_layer.h"
#include "core/relight/emitter_direct.h"
#include "core/sh/sh.h"
#include "gpu/gl_objects.h"
#include "gpu/shadow_maps.h"
#include "shaders/gpu_layout.h"

namespace lightlink::gpu {

using namespace glsl;
using relight::EffectsPlan;
using relight::LightSet;
using relight::LinkForm;
using relight::RelightOptions;
using relight::RelightResult;

namespace {

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

template <typename T>
std::vector<std::uint32_t> widen(std::span<const T> v) {
  return std::vector<std::uint32_t>(v.begin(), v.end());
}

bool lightEmits(const scene::Light& l) {
  return l.intensity > 0.0f && (l.color.x > 0.0f || l.color.y > 0.0f || l.color.z > 0.0f);
}

bool sameEmissive(const std::vector<relight::EmissiveOverride>& a, const std::vector<relight::EmissiveOverride>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a[i].material != b[i].material || a[i].mode != b[i].mode || a[i].value != b[i].value) return false;
  return true;
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

struct GpuRelighter::Impl {
  const scene::Scene& scene;
  const rt::Accel& accel;
  const precompute::Precomputation& p;
  links::LinksView lm_view, grid_view;
  GpuOptions options;
  std::unique_ptr<GlContext> ctx;
  std::unique_ptr<relight::Relighter> cpu;  // the effects plan, gather tables, sky matrix, emission
  // A finer direct layer is traced on the CPU (core/relight/direct_layer.h), as the CPU
  // backend does, so both write the same direct.exr; the GPU's own direct is then unused.
  std::unique_ptr<relight::DirectLayer> layer;
  relight::SeamStitch seams;  // applied to the read-back texels, as the CPU backend does
  std::unique_ptr<ShadowMaps> shadows;
  GpuTimers timers;

  std::size_t ns = 0, nodes = 0, ncache = 0, ngrid = 0, texels = 0;
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

  // Emission state on the host (uploaded when it changes).
  bool emission_valid = false;
  std::vector<relight::EmissiveOverride> emission_overrides;
  std::vector<glm::vec3> emission_b;
  // The emitters' direct light at the surfels (the CPU relighter's sampling, so both backends
  // light surfels with identical values), reused while emission is unchanged.
  bool surfel_emit_valid = false;
  std::vector<relight::EmissiveOverride> surfel_emit_overrides;
  std::vector<glm::vec3> surfel_emit;
  // Emitter direct light per lightmap cache (CPU code), reused while emission is unchanged.
  bool emitter_valid = false;
  std::vector<relight::EmissiveOverride> emitter_overrides;
  int emitter_samples = 0;
  std::size_t emitter_triangles = 0;
  std::vector<glm::vec4> emitter_cache;
  // The emitters' SH per grid cache (the CPU relighter's gridEmitterRadiance), added to the
  // grid's link result at readback; kept while the emission state and bands are.
  bool grid_emit_valid = false;
  std::vector<relight::EmissiveOverride> grid_emit_overrides;
  int grid_emit_bands = 0;
  std::vector<float> grid_emit;

  Impl(const scene::Scene& s, const rt::Accel& a, const precompute::Precomputation& pc, links::LinksView lmv,
       links::LinksView gv, const GpuOptions& o)
      : scene(s), accel(a), p(pc), lm_view(lmv), grid_view(gv), options(o) {}

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

  void ensureBuffers(int stride);
  Status setup();
  void pullFlux(const GlBuffer& radiosity_in);
  Status lightCaches(const GpuLinks& links, const GlBuffer& node_rad, const GlBuffer& out, int bands, LinkForm form,
                     bool sky);
  void applyFill(const GpuFill& f, const GlBuffer& data, int stride);
  Status run(const LightSet& lights, const RelightOptions& o, RelightResult& res);
};

GpuRelighter::GpuRelighter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

GpuRelighter::~GpuRelighter() {
  if (!impl_ || !impl_->ctx) return;
  // GL objects die with the context current; the context itself last, once released.
  std::unique_ptr<GlContext> ctx = std::move(impl_->ctx);
  {
    GlContext::Current cur(*ctx);
    if (impl_->staging_ptr) glUnmapNamedBuffer(impl_->staging.id());
    impl_.reset();
  }
}

const GlContextInfo& GpuRelighter::info() const { return impl_->ctx->info(); }

Expected<std::unique_ptr<GpuRelighter>> GpuRelighter::create(const scene::Scene& scene, const rt::Accel& accel,
                                                             const precompute::Precomputation& p,
                                                             links::LinksView lightmap_links,
                                                             links::LinksView grid_links, const GpuOptions& options) {
  if (options.lanes < 1 || options.lanes > 64 || (options.lanes & (options.lanes - 1)) != 0)
    return invalidInput("gpu: lanes {} must be a power of two in 1..64", options.lanes);
  if (!(options.bias_scene >= 0.0f) || !(options.normal_offset_texels >= 0.0f) || !(options.slope_bias_texels >= 0.0f))
    return invalidInput("gpu: shadow biases must be finite and >= 0");
  auto cpu = relight::Relighter::create(scene, accel, p, lightmap_links, grid_links);
  if (!cpu) return cpu.status();
  auto ctx = GlContext::create();
  if (!ctx) return ctx.status();
  GpuOptions opts = options;
  // Driver triage without a rebuild: LIGHTLINK_GPU_LANES overrides the threads per cache.
  if (const char* lanes = std::getenv("LIGHTLINK_GPU_LANES")) opts.lanes = std::atoi(lanes);
  if (opts.lanes < 1 || opts.lanes > 64 || (opts.lanes & (opts.lanes - 1)) != 0)
    return invalidInput("gpu: lanes {} must be a power of two in 1..64", opts.lanes);
  auto impl = std::make_unique<Impl>(scene, accel, p, lightmap_links, grid_links, opts);
  impl->cpu = std::make_unique<relight::Relighter>(std::move(*cpu));
  impl->layer = std::make_unique<relight::DirectLayer>(scene, accel, p);
  impl->seams = relight::SeamStitch::build(scene, p.lightmap.width, p.lightmap.height);
  impl->ctx = std::move(*ctx);
  std::unique_ptr<GpuRelighter> r(new GpuRelighter(std::move(impl)));
  GlContext::Current cur(*r->impl_->ctx);
  if (!cur.status()) return cur.status();
  if (Status s = r->impl_->setup(); !s) return s;
  return r;
}

Status GpuRelighter::Impl::setup() {
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
  ngrid = p.has_grid ? grid_view.cacheCount() : 0;
  texels = std::size_t(p.lightmap.width) * p.lightmap.height;
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
  auto pull_areas = relight::pullAreas(p);
  if (!pull_areas) return pull_areas.status();
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
  const auto gt = cpu->gatherTables();
  lm_has_value = GlBuffer::of(widen(gt.lightmap_has_value));
  gather_begin = GlBuffer(gt.begin.size() * 4, gt.begin.data());
  gather_cache = GlBuffer(gt.cache.size() * 4, gt.cache.data());
  gather_weight = GlBuffer(gt.weight.size() * 4, gt.weight.data());
  gather_from_grid = GlBuffer::of(widen(gt.from_grid));
  lm = uploadLinks(lm_view, p.lightmap.valid);
  if (ngrid) grid = uploadLinks(grid_view, p.grid.valid);
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
  texel_direct = GlBuffer(texels * 16, nullptr);
  texel_valid = GlBuffer(texels * 4, nullptr);
  return glCheck("gpu relight setup (uploads)");
}

void GpuRelighter::Impl::ensureBuffers(int stride) {
  if (stride == sized_stride) return;
  sized_stride = stride;
  const std::size_t s = std::size_t(stride) * 4;
  lm_sh = GlBuffer(ncache * s, nullptr);
  grid_sh = GlBuffer(ngrid * s, nullptr);
  texel_sh = GlBuffer(texels * s, nullptr);
  // Staging: texel SH, texel direct, texel valid, grid SH, surfel radiosity, bounce partials.
  if (staging_ptr) glUnmapNamedBuffer(staging.id());
  staging_bytes = texels * s + texels * 16 + texels * 4 + ngrid * s + ns * 16 + partials.bytes();
  staging = GlBuffer(staging_bytes, nullptr, GL_MAP_READ_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT |
                                                 GL_CLIENT_STORAGE_BIT);
  staging_ptr = glMapNamedBufferRange(staging.id(), 0, GLsizeiptr(std::max<std::size_t>(staging_bytes, 16)),
                                      GL_MAP_READ_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT);
}

// Leaf flux from per-surfel radiosity, then the pull, level by level (deepest first).
void GpuRelighter::Impl::pullFlux(const GlBuffer& radiosity_in) {
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

Status GpuRelighter::Impl::lightCaches(const GpuLinks& links, const GlBuffer& node_rad, const GlBuffer& out,
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

void GpuRelighter::Impl::applyFill(const GpuFill& f, const GlBuffer& data, int stride) {
  if (f.count == 0) return;
  f.target.bindStorage(kFiTarget);
  f.begin.bindStorage(kFiBegin);
  f.source.bindStorage(kFiSource);
  data.bindStorage(kFiData);
  fill.set("u_stride", std::uint32_t(stride));
  for (const auto& [lb, le] : f.levels) {
    fill.set("u_begin", lb);
    fill.set("u_end", le);
    dispatch(fill, le - lb, 64);
  }
}

EffectsPlan GpuRelighter::plan(const LightSet& lights, const RelightOptions& options) const {
  return impl_->cpu->plan(lights, options);
}

void GpuRelighter::invalidate() {
  impl_->emission_valid = false;
  impl_->emitter_valid = false;
  impl_->surfel_emit_valid = false;
  impl_->grid_emit_valid = false;
  impl_->layer->invalidate(true);
}

Status GpuRelighter::relightInto(const LightSet& lights, const RelightOptions& o, RelightResult& res) {
  Impl& m = *impl_;
  const int link_bands = m.lm_view.bands;
  if (Status s = validateRequest(lights, o, link_bands, m.ns, m.scene.materials.size()); !s) return s;
  GlContext::Current cur(*m.ctx);
  if (!cur.status()) return cur.status();
  Status s = m.run(lights, o, res);
  if (s) s = glCheck("gpu relight");
  return s;
}

Status GpuRelighter::Impl::run(const LightSet& lights, const RelightOptions& o, RelightResult& res) {
  const int link_bands = lm_view.bands;
  const int bands = o.bands == 0 ? link_bands : o.bands;
  const int nc = bands * bands;
  const int stride = 3 * nc;
  res.timings.clear(), res.bounce_log.clear(), res.warnings.clear();
  res.passes = {}, res.counts = {}, res.bounce_stop.clear();
  res.backend = "gpu";
  res.kernel = fmt::format("glsl-lanes{}", options.lanes);
  res.version = lights.version();
  res.link_form = o.link_form;
  res.bands = bands;
  res.width = p.lightmap.width;
  res.height = p.lightmap.height;
  res.plan = cpu->plan(lights, o);
  const EffectsPlan& plan = res.plan;
  res.counts.surfels = ns;
  res.counts.nodes = nodes;
  res.counts.caches = ncache;
  res.counts.grid_caches = plan.grid ? ngrid : 0;
  const auto gt = cpu->gatherTables();
  res.counts.surfels_without_gather = gt.surfels_without_gather;
  ensureBuffers(stride);
  timers.reset();
  std::vector<std::pair<std::string, double>> host_stages;  // CPU-side stages, host seconds
  auto gpuStage = [&](std::string name, auto&& body) -> Status {
    timers.begin(std::move(name));
    Status st = body();
    timers.end();
    return st;
  };

  // ---- lights and shadow maps --------------------------------------------------------
  const auto& L = lights.lights();
  const bool given_e = !o.surfel_irradiance.empty();
  std::vector<GpuLight> gl(L.size());
  std::vector<std::uint8_t> emits(L.size());
  for (std::size_t i = 0; i < L.size(); ++i) {
    const scene::Light& l = L[i].light;
    emits[i] = lightEmits(l);
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
  // Only lights the passes evaluate need maps: all emitting ones for the surfels (unless the
  // surfel light is given), baked ones for the texels.
  std::vector<std::uint8_t> mapped(L.size());
  for (std::size_t i = 0; i < L.size(); ++i)
    mapped[i] = emits[i] && ((!given_e && plan.punctual) || (plan.baked_direct && L[i].baked));
  std::vector<GpuShadowView> views;
  const bool any_mapped = std::find(mapped.begin(), mapped.end(), 1) != mapped.end();
  if (any_mapped) {
    std::vector<scene::Light> raw(L.size());
    for (std::size_t i = 0; i < L.size(); ++i) raw[i] = L[i].light;
    if (Status st = gpuStage("shadow_maps", [&] { return shadows->render(raw, mapped, gl, views); }); !st) return st;
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

  // ---- surfel direct radiosity b0 (and b = b0) ----------------------------------------
  // The emitters' direct light at the surfels starts the sum the shader adds punctual lights
  // to (the CPU relighter's surfel_emit, docs/quality.md "Where the energy went").
  if (!surfel_emit_valid || !sameEmissive(surfel_emit_overrides, lights.emissive())) {
    cpu->surfelEmitterIrradiance(lights, surfel_emit);
    surfel_emit_valid = true;
    surfel_emit_overrides = lights.emissive();
  }
  const bool surfel_emits =
      std::any_of(surfel_emit.begin(), surfel_emit.end(), [](const glm::vec3& e) { return e != glm::vec3(0.0f); });
  const bool use_given = given_e || surfel_emits;
  if (Status st = gpuStage("surfel_direct", [&]() -> Status {
        if (use_given) {
          std::vector<glm::vec4> e(ns);
          for (std::size_t s = 0; s < ns; ++s)
            e[s] = glm::vec4((given_e ? o.surfel_irradiance[s] : glm::vec3(0.0f)) + surfel_emit[s], 0.0f);
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
        light_surfels.set("u_light_count", given_e || !plan.punctual ? 0 : int(L.size()));
        light_surfels.set("u_use_given", use_given ? 1 : 0);
        dispatch(light_surfels, ns, 64);
        return {};
      });
      !st)
    return st;
  res.counts.surfels_lit = plan.punctual ? ns : 0;
  res.passes.surfel_direct = plan.punctual ? 1 : 0;
  debugSum("b0", b0);
  debugSum("b", b);

  // ---- emission: host-side per surfel after overrides --------------------------------
  const bool has_emission = plan.emissive;
  if (!emission_valid || !sameEmissive(emission_overrides, lights.emissive())) {
    cpu->surfelEmission(lights, emission_b);
    std::vector<glm::vec4> ae(2 * ns);
    for (std::size_t s = 0; s < ns; ++s) {
      ae[2 * s] = glm::vec4(p.surfels.albedo[s], 0.0f);
      ae[2 * s + 1] = glm::vec4(has_emission ? emission_b[s] : glm::vec3(0.0f), 0.0f);
    }
    albedo_emit.upload(ae.data(), ae.size() * 16);
    emission_valid = true;
    emission_overrides = lights.emissive();
  }
  // Every cache's links read reflected radiosity only: the emitters' light reaches the
  // texels as sampled direct and the grid as sampled SH (added at readback).
  if (has_emission) res.passes.emission = 1;
  if (plan.sky) {
    std::vector<float> m[3];
    cpu->skyMatrix(lights.sky(), bands, m);
    std::vector<float> all;
    for (auto& ch : m) all.insert(all.end(), ch.begin(), ch.end());
    if (sky_matrix.bytes() < all.size() * 4) sky_matrix = GlBuffer(all.size() * 4, nullptr);
    sky_matrix.upload(all.data(), all.size() * 4);
  }

  auto pullAndLight = [&](const std::string& pull_stage, const std::string& rad_stage,
                          const std::string& cache_stage) -> Status {
    if (Status st = gpuStage(pull_stage, [&] {
          pullFlux(b);
          return Status{};
        });
        !st)
      return st;
    if (Status st = gpuStage(rad_stage, [&] {
          tree_nodes.bindStorage(kPuNodes);
          flux.bindStorage(kPuFlux);
          rad.bindStorage(kPuRad);
          radiosity.set("u_count", std::uint32_t(nodes));
          dispatch(radiosity, nodes, 256);
          debugSum("flux", flux);
          debugSum("rad", rad);
          return Status{};
        });
        !st)
      return st;
    res.passes.pulls++;
    res.counts.nodes_pulled = nodes;
    return gpuStage(cache_stage, [&]() -> Status {
      if (Status st = lightCaches(lm, rad, lm_sh, bands, o.link_form, plan.sky); !st) return st;
      debugSum("lm_sh", lm_sh);
      res.passes.cache_lighting++;
      res.passes.sky += plan.sky ? 1 : 0;
      res.counts.caches_summed = lm.caches;
      res.counts.links_read += lm.links;
      if (plan.grid) {
        if (Status st = lightCaches(grid, rad, grid_sh, bands, o.link_form, plan.sky); !st)
          return st;
        debugSum("grid_sh", grid_sh);
        res.passes.grid_lighting++;
        res.counts.grid_caches_summed = grid.caches;
        res.counts.links_read += grid.links;
      }
      return {};
    });
  };
  if (Status st = pullAndLight("pull", "node_radiosity", "cache_lighting"); !st) return st;
  // The emitters' light reached the surfels as direct light (surfel_emit): the bounces
  // gather reflected light only, as on the CPU.

  if (!(plan.punctual || plan.emissive || plan.sky)) res.bounce_stop = "no light";
  else if (o.max_bounces == 0) res.bounce_stop = "disabled";
  else res.bounce_stop = "cap";
  const std::size_t groups = (ns + kGatherGroup - 1) / kGatherGroup;
  const std::size_t partials_offset = staging_bytes - partials.bytes();
  if (plan.bounces) {
    auto gather = variant("gather.comp", {{"BANDS", std::to_string(bands)}});
    if (!gather) return gather.status();
    const GlProgram& gp = **gather;
    for (int k = 1; k <= plan.max_bounces; ++k) {
      const auto t0 = Clock::now();
      if (Status st = gpuStage(fmt::format("bounce{}_gather", k), [&]() -> Status {
            applyFill(lm_fill, lm_sh, stride);
            if (plan.grid) applyFill(grid_fill, grid_sh, stride);
            gather_begin.bindStorage(kGaBegin);
            gather_cache.bindStorage(kGaCache);
            gather_weight.bindStorage(kGaWeight);
            gather_from_grid.bindStorage(kGaFromGrid);
            lm_sh.bindStorage(kGaLightmapSh);
            (plan.grid ? grid_sh : dummy).bindStorage(kGaGridSh);
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
      glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_CLIENT_MAPPED_BUFFER_BARRIER_BIT);
      glCopyNamedBufferSubData(partials.id(), staging.id(), 0, GLintptr(partials_offset), GLsizeiptr(groups * 8));
      GLsync fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
      Status st = pullAndLight(fmt::format("bounce{}_pull", k), fmt::format("bounce{}_node_radiosity", k),
                               fmt::format("bounce{}_cache_lighting", k));
      if (!st) {
        glDeleteSync(fence);
        return st;
      }
      const GLenum w = glClientWaitSync(fence, GL_SYNC_FLUSH_COMMANDS_BIT, 60'000'000'000ull);
      glDeleteSync(fence);
      if (w == GL_TIMEOUT_EXPIRED || w == GL_WAIT_FAILED) return internalError("gpu: bounce {} did not finish", k);
      const auto* part = reinterpret_cast<const float*>(static_cast<const char*>(staging_ptr) + partials_offset);
      double added = 0.0, total = 0.0;  // group order: the CPU's chunk order
      for (std::size_t g = 0; g < groups; ++g) added += part[2 * g], total += part[2 * g + 1];
      res.passes.bounces++;
      res.bounce_log.push_back({k, added, total, secondsSince(t0)});
      if (added < double(o.bounce_threshold) * total) {
        res.bounce_stop = "threshold";
        break;
      }
    }
  }

  // ---- the emitters' light at the grid caches: the CPU relighter's sampling -----------
  if (plan.grid) {
    const auto t0 = Clock::now();
    if (grid_emit_valid && grid_emit_bands == bands && sameEmissive(grid_emit_overrides, lights.emissive())) {
      res.counts.grid_emitter_reused = grid_emit.empty() ? 0 : 1;
    } else {
      res.counts.shadow_rays += cpu->gridEmitterRadiance(lights, bands, grid_emit);
      grid_emit_valid = true;
      grid_emit_overrides = lights.emissive();
      grid_emit_bands = bands;
      res.passes.grid_emitter = grid_emit.empty() ? 0 : 1;
    }
    host_stages.emplace_back("grid_emitter", secondsSince(t0));
  }

  // ---- baked direct at lightmap caches: GPU punctual lights + CPU emitter sampling ---
  if (plan.emissive_direct) {
    const auto t0 = Clock::now();
    if (emitter_valid && emitter_samples == o.emitter_samples && sameEmissive(emitter_overrides, lights.emissive())) {
      res.counts.emitter_direct_reused = 1;
    } else {
      const relight::detail::EmitterSampler sampler(scene, accel, lights.emissive());
      emitter_triangles = sampler.triangleCount();
      emitter_cache.assign(ncache, glm::vec4(0.0f));
      constexpr std::size_t kChunk = 64;
      const std::size_t chunks = (ncache + kChunk - 1) / kChunk;
      std::vector<std::size_t> chunk_rays(chunks, 0);
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks, 1), [&](const tbb::blocked_range<std::size_t>& r) {
        relight::detail::EmitterSampler::Scratch scratch;
        for (std::size_t ch = r.begin(); ch < r.end(); ++ch) {
          std::size_t rays = 0;
          for (std::size_t c = ch * kChunk; c < std::min(ncache, (ch + 1) * kChunk); ++c) {
            if (!p.lightmap.valid[c]) continue;
            // The CPU backend's seed per texel: the same noise on both backends.
            const std::uint64_t seed = mixBits(0x6c6c656d69747465ULL ^ p.lightmap.texel[c]);
            emitter_cache[c] = glm::vec4(
                sampler.irradiance(p.lightmap.position[c], p.lightmap.normal[c], o.emitter_samples, seed, scratch, rays),
                0.0f);
          }
          chunk_rays[ch] = rays;
        }
      });
      for (std::size_t r : chunk_rays) res.counts.shadow_rays += r;
      emitter_buf.upload(emitter_cache.data(), emitter_cache.size() * 16);
      emitter_valid = true;
      emitter_samples = o.emitter_samples;
      emitter_overrides = lights.emissive();
      res.passes.emissive_direct = 1;
    }
    res.counts.emitter_triangles = emitter_triangles;
    host_stages.emplace_back("emissive_direct", secondsSince(t0));
  } else {
    emitter_valid = false;
  }
  if (Status st = gpuStage("baked_direct", [&]() -> Status {
        if (!plan.baked_direct && !plan.emissive_direct) {
          cache_direct.zero();
          return {};
        }
        cache_pos.bindStorage(kLpPositions);
        cache_normal.bindStorage(kLpNormals);
        lights_buf.bindStorage(kLpLights);
        views_buf.bindStorage(kLpViews);
        cache_valid.bindStorage(kLpValid);
        dummy.bindStorage(kLpAlbedo);
        (plan.emissive_direct ? emitter_buf : dummy).bindStorage(kLpGiven);
        cache_direct.bindStorage(kLpOut);
        dummy.bindStorage(kLpOut2);
        light_caches.set("u_count", std::uint32_t(ncache));
        light_caches.set("u_light_count", plan.baked_direct ? int(L.size()) : 0);
        light_caches.set("u_use_given", plan.emissive_direct ? 1 : 0);
        dispatch(light_caches, ncache, 64);
        return {};
      });
      !st)
    return st;
  for (std::size_t i = 0; i < L.size(); ++i) res.passes.baked_direct += plan.baked_direct && L[i].baked && emits[i];

  // ---- fill, texels, dilation -----------------------------------------------------------
  if (Status st = gpuStage("fill_dilate", [&]() -> Status {
        applyFill(lm_fill, lm_sh, stride);
        applyFill(lm_fill, cache_direct, 4);
        if (plan.grid) applyFill(grid_fill, grid_sh, stride);
        cache_of_texel.bindStorage(kTxCacheOfTexel);
        lm_has_value.bindStorage(kTxHasValue);
        lm_sh.bindStorage(kTxCacheSh);
        cache_direct.bindStorage(kTxCacheDirect);
        texel_sh.bindStorage(kTxTexelSh);
        texel_direct.bindStorage(kTxTexelDirect);
        texel_valid.bindStorage(kTxTexelValid);
        texel_pass.set("u_count", std::uint32_t(texels));
        texel_pass.set("u_stride", std::uint32_t(stride));
        dispatch(texel_pass, texels, 64);
        if (dilation.count) {
          dilation.target.bindStorage(kFiTarget);
          dilation.begin.bindStorage(kFiBegin);
          dilation.source.bindStorage(kFiSource);
          texel_sh.bindStorage(kFiData);
          texel_valid.bindStorage(kFiValid);
          texel_direct.bindStorage(kFiDirect);
          dilate.set("u_stride", std::uint32_t(stride));
          for (const auto& [lb, le] : dilation.levels) {
            dilate.set("u_begin", lb);
            dilate.set("u_end", le);
            dispatch(dilate, le - lb, 64);
          }
        }
        return {};
      });
      !st)
    return st;
  res.passes.fill = 1;

  // ---- readback: one copy into the mapped staging buffer, one fence ---------------------
  const auto t_read = Clock::now();
  const std::size_t sh_bytes = texels * std::size_t(stride) * 4;
  const std::size_t grid_bytes = plan.grid ? ngrid * std::size_t(stride) * 4 : 0;
  std::size_t off = 0;
  const std::size_t off_sh = off;
  off += texels * std::size_t(stride) * 4;
  const std::size_t off_dir = off;
  off += texels * 16;
  const std::size_t off_valid = off;
  off += texels * 4;
  const std::size_t off_grid = off;
  off += ngrid * std::size_t(stride) * 4;
  const std::size_t off_b = off;
  timers.begin("readback_copy");
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_CLIENT_MAPPED_BUFFER_BARRIER_BIT);
  auto copy = [&](const GlBuffer& src, std::size_t dst_off, std::size_t bytes) {
    if (bytes) glCopyNamedBufferSubData(src.id(), staging.id(), 0, GLintptr(dst_off), GLsizeiptr(bytes));
  };
  copy(texel_sh, off_sh, sh_bytes);
  copy(texel_direct, off_dir, texels * 16);
  copy(texel_valid, off_valid, texels * 4);
  copy(grid_sh, off_grid, grid_bytes);
  copy(b, off_b, ns * 16);
  timers.end();
  GLsync fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
  const GLenum w = glClientWaitSync(fence, GL_SYNC_FLUSH_COMMANDS_BIT, 120'000'000'000ull);
  glDeleteSync(fence);
  if (w == GL_TIMEOUT_EXPIRED || w == GL_WAIT_FAILED) return internalError("gpu: relight did not finish");
  const char* base = static_cast<const char*>(staging_ptr);
  res.lightmap_sh.resize(texels * std::size_t(stride));
  std::memcpy(res.lightmap_sh.data(), base + off_sh, sh_bytes);
  res.direct.resize(texels);
  res.texel_valid.resize(texels);
  const auto* dir4 = reinterpret_cast<const glm::vec4*>(base + off_dir);
  const auto* valid4 = reinterpret_cast<const std::uint32_t*>(base + off_valid);
  std::size_t filled = 0;
  for (std::size_t t = 0; t < texels; ++t) {
    res.direct[t] = glm::vec3(dir4[t]);
    res.texel_valid[t] = valid4[t] ? 1 : 0;
    filled += res.texel_valid[t];
  }
  res.counts.texels = texels;
  res.counts.texels_filled = filled;
  if (plan.grid) {
    res.grid_sh.resize(ngrid * std::size_t(stride));
    std::memcpy(res.grid_sh.data(), base + off_grid, grid_bytes);
    if (!grid_emit.empty())
      for (std::size_t i = 0; i < res.grid_sh.size(); ++i) res.grid_sh[i] += grid_emit[i];
  } else {
    res.grid_sh.clear();
  }
  res.surfel_radiosity.resize(ns);
  const auto* b4 = reinterpret_cast<const glm::vec4*>(base + off_b);
  for (std::size_t s = 0; s < ns; ++s)
    res.surfel_radiosity[s] = glm::vec3(b4[s]) + (has_emission ? emission_b[s] : glm::vec3(0.0f));
  host_stages.emplace_back("readback", secondsSince(t_read));

  res.direct_width = res.width, res.direct_height = res.height;
  res.direct_valid.clear();
  res.seams = {}, res.direct_seams = {};
  if (o.smooth_indirect) cpu->smoothIndirect(res);  // the CPU backend's filter, on the read-back texels
  if (o.stitch_seams) {
    seams.apply(res.lightmap_sh.data(), std::size_t(stride), &res.seams);
    if (!layer->active()) seams.apply(reinterpret_cast<float*>(res.direct.data()), 3, &res.direct_seams);
  }
  for (auto& [name, sec] : timers.resolve()) res.timings.push_back({name, sec});
  for (auto& [name, sec] : host_stages) res.timings.push_back({name, sec});
  if (layer->active()) layer->compute(lights, o, plan, res);
  if (gt.surfels_without_gather > 0 && plan.bounces)
    res.warnings.push_back(fmt::format("{} surfels have no lightmap texel or grid cache to gather bounces from",
                                       gt.surfels_without_gather));
  return {};
}

Expected<double> GpuRelighter::measureStream(std::size_t bytes, bool copy, int repeats) {
  Impl& m = *impl_;
  GlContext::Current cur(*m.ctx);
  if (!cur.status()) return cur.status();
  bytes = std::max<std::size_t>(bytes / 16 * 16, 16);
  auto prog = m.variant("bandwidth.comp", copy ? std::vector<ShaderDefine>{{"COPY", "1"}} : std::vector<ShaderDefine>{});
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
    m.timers.reset();
    m.timers.begin("stream");
    glDispatchCompute(groups, 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    m.timers.end();
    const auto res = m.timers.resolve();
    if (r > 0) t.push_back(res[0].second);  // the first is a warm-up
  }
  if (Status s = glCheck("bandwidth kernel"); !s) return s;
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

}  // namespace lightlink::gpu
