#include "core/relight/cpu_passes.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <functional>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/common/isa.h"
#include "core/relight/cache_lighting.h"
#include "core/relight/direct_points.h"
#include "core/sh/sh.h"

namespace lightlink::relight {
namespace {

using detail::forChunks;
using detail::kCacheChunk;
using detail::kChunk;
using detail::lightEmits;
using detail::reaches;

class CpuPasses final : public RelightPasses {
 public:
  explicit CpuPasses(const SceneTables& tables) : t_(tables), p_(tables.p) {
    detail::footprintNeighbours(p_.surfels.position, p_.surfels.area, neighbour_begin_, neighbour_);
    const std::size_t nodes = p_.tree.nodeCount();
    for (auto& f : flux_) f.assign(nodes, 0.0f);
    rad_rgbx_.assign(4 * nodes, 0.0f);
  }

  std::string_view backend() const override { return "cpu"; }
  std::string kernelName(const RelightOptions& o) const override {
    return o.kernel == Kernel::kAuto && isaAtLeast(Isa::kAvx2) ? "avx2" : "scalar";
  }
  Status begin(const RelightFrame& f) override {
    simd_ = f.options.kernel == Kernel::kAuto && isaAtLeast(Isa::kAvx2);
    return {};
  }
  Status setEmission(std::span<const glm::vec3> emission_b, std::uint64_t) override {
    emission_b_ = emission_b;
    return {};
  }
  Status surfelDirect(const RelightFrame& f, std::span<const glm::vec3> surfel_emit, RelightResult& res) override;
  Status pullAndLight(const RelightFrame& f, const std::string& prefix, bool grid, RelightResult& res) override;
  Status gather(const RelightFrame& f, int bounce, bool fill_grid, RelightResult& res) override;
  Expected<BounceSums> bounceSums() override { return sums_; }
  Status cacheDirect(const RelightFrame& f, const EmitterTexels& emitter, RelightResult& res) override;
  Status texels(const RelightFrame& f, RelightResult& res) override;
  bool incremental() const override { return true; }
  bool incrementalBounces() const override { return true; }
  Status relightChange(const RelightFrame& f, const LightChange& change, std::span<const glm::vec3> surfel_emit,
                       const EmitterTexels& emitter, RelightResult& res) override;
  Expected<BounceSums> propagateChange(const RelightFrame& f, int round, RelightResult& res) override;

 private:
  // Incremental steps: the surfels the change reaches (re-lit), the tree nodes above them
  // (re-pulled), the caches linked to those nodes (re-lit), the changed light's baked direct.
  std::vector<std::uint32_t> changeSurfels(const LightChange& c, std::span<const glm::vec3> surfel_emit, bool bounced,
                                           int shadow_rays, RelightResult& res);
  // With bounces: pull the surfels whose b changed, and relight the caches linked to nodes
  // whose radiosity moved by more than the tolerance since their caches last read it.
  void pushChange(const RelightFrame& f, const std::vector<std::uint32_t>& changed, const std::string& prefix,
                  RelightResult& res);
  void buildGatherInverse();
  std::vector<std::uint32_t> changeTree(const std::vector<std::uint32_t>& touched, bool dense, RelightResult& res);
  void changeCaches(const RelightFrame& f, const std::vector<std::uint32_t>& changed_nodes, bool dense,
                    RelightResult& res);
  void changeDirect(const RelightFrame& f, const LightChange& c, bool surfels_change, const EmitterTexels& emitter,
                    RelightResult& res);
  void sumCacheDirect(const EmitterTexels& emitter);

  void lightSurfels(const scene::Light& light, int shadow_rays, std::vector<glm::vec3>& out,
                    const std::vector<std::uint32_t>* subset, std::size_t& rays) const;
  void bakedDirect(const scene::Light& light, std::vector<glm::vec3>& out, std::size_t& rays) const;
  void setLeafFlux(std::size_t s);
  // b0 + rho * E of surfel s from the caches it gathers (the bounce gather of one surfel).
  glm::vec3 gatheredRadiosity(std::size_t s, int bands, std::size_t stride) const;
  void pullAll();
  void buildInverted();
  // The caches (in order) linked to any of `nodes`, through an inverted index node -> caches.
  static std::vector<std::uint32_t> linkedCaches(const std::vector<std::uint32_t>& nodes,
                                                 const std::vector<std::uint32_t>& begin,
                                                 const std::vector<std::uint32_t>& inv, std::size_t count);
  void lightCaches(const RelightFrame& f, const links::LinksView& view, std::vector<float>& out,
                   const std::vector<std::uint8_t>& valid, const std::vector<std::uint32_t>* subset);

  const SceneTables& t_;
  const precompute::Precomputation& p_;
  bool simd_ = false;
  std::span<const glm::vec3> emission_b_;  // the pipeline's (setEmission)
  // Each light's irradiance per surfel (lux) and baked direct per lightmap cache, in light
  // order, kept for incremental relights.
  std::vector<std::vector<glm::vec3>> per_light_surfel_, per_light_cache_;
  std::vector<glm::vec3> direct_e_;  // sum of per-light E per surfel, in light order, + the emitters'
  std::vector<glm::vec3> b0_, b_;    // reflected radiosity rho * E without / with indirect
  std::vector<float> flux_[3];       // reflected flux per node, planar (the pull adds channel by channel)
  std::vector<float> rad_rgbx_;      // reflected node radiosity, (R, G, B, 0): what the kernels read
  std::vector<float> lm_sh_, grid_sh_;  // per cache, stride floats: reflected light and sky (links)
  std::vector<glm::vec3> cache_direct_;
  std::vector<double> chunk_added_, chunk_total_;
  BounceSums sums_;
  // Inverted index node -> caches (built on the first sparse incremental relight).
  bool inverted_built_ = false;
  std::vector<std::uint32_t> lm_inv_begin_, lm_inv_, grid_inv_begin_, grid_inv_;
  // Incremental relight with bounces. Per node, the radiosity (R, G, B, 0) every cache linked
  // to it last read; the caches relit since the last gather round (all: relit_all_); the
  // inverse of the gather tables, cache -> surfels reading it, lightmap and grid.
  std::vector<float> rad_lit_;
  // Each surfel's neighbours, for the footprint shadow rays near shadow edges (Footprint).
  std::vector<std::uint32_t> neighbour_begin_, neighbour_;
  std::vector<std::uint32_t> relit_lm_, relit_grid_;
  bool relit_all_ = false;
  bool gather_inverse_built_ = false;
  std::vector<std::uint32_t> lm_readers_begin_, lm_readers_, grid_readers_begin_, grid_readers_;
};

Status CpuPasses::surfelDirect(const RelightFrame& f, std::span<const glm::vec3> surfel_emit, RelightResult& res) {
  const std::size_t ns = p_.surfels.size();
  const auto& L = f.lights.lights();
  const auto& given = f.options.surfel_irradiance;
  direct_e_.assign(ns, glm::vec3(0.0f));
  per_light_surfel_.assign(L.size(), {});
  timedStage(res, "surfel_direct", [&] {
    if (!given.empty()) {
      // Given by the caller (parity runs): no light is evaluated at the surfels.
      for (auto& pl : per_light_surfel_) pl.assign(ns, glm::vec3(0.0f));
      direct_e_.assign(given.begin(), given.end());
      res.counts.surfels_lit = ns;
      return;
    }
    for (std::size_t i = 0; i < L.size(); ++i) {
      if (!lightEmits(L[i].light)) {
        per_light_surfel_[i].assign(ns, glm::vec3(0.0f));
        continue;
      }
      lightSurfels(L[i].light, f.options.surfel_shadow_rays, per_light_surfel_[i], nullptr, res.counts.shadow_rays);
      res.passes.surfel_direct = 1;
    }
    for (std::size_t i = 0; i < L.size(); ++i)
      for (std::size_t s = 0; s < ns; ++s) direct_e_[s] += per_light_surfel_[i][s];
    res.counts.surfels_lit = f.plan.punctual ? ns : 0;
  });
  if (surfel_emit.size() == ns)
    for (std::size_t s = 0; s < ns; ++s) direct_e_[s] += surfel_emit[s];
  b0_.resize(ns);
  for (std::size_t s = 0; s < ns; ++s) b0_[s] = p_.surfels.albedo[s] * direct_e_[s];
  if (!f.warm || b_.size() != ns) b_ = b0_;
  return {};
}

Status CpuPasses::pullAndLight(const RelightFrame& f, const std::string& prefix, bool grid, RelightResult& res) {
  timedStage(res, prefix + "pull", [&] {
    for (std::size_t s = 0; s < p_.surfels.size(); ++s) setLeafFlux(s);
    pullAll();
    res.passes.pulls++;
    res.counts.nodes_pulled = p_.tree.nodeCount();
  });
  timedStage(res, prefix + "cache_lighting", [&] {
    lightCaches(f, t_.lm_links, lm_sh_, p_.lightmap.valid, nullptr);
    rad_lit_ = rad_rgbx_;  // what every cache read (the grid's are lit at least on the last pass)
    res.passes.cache_lighting++;
    res.passes.sky += f.plan.sky ? 1 : 0;
    res.counts.caches_summed = t_.lm_links.cacheCount();
    res.counts.links_read += t_.lm_links.linkCount();
    if (grid) {
      lightCaches(f, t_.grid_links, grid_sh_, p_.grid.valid, nullptr);
      res.passes.grid_lighting++;
      res.counts.grid_caches_summed = t_.grid_links.cacheCount();
      res.counts.links_read += t_.grid_links.linkCount();
    }
  });
  return {};
}

Status CpuPasses::gather(const RelightFrame& f, int bounce, bool fill_grid, RelightResult& res) {
  const std::size_t ns = p_.surfels.size(), stride = f.stride;
  const int bands = f.bands;
  timedStage(res, "bounce" + std::to_string(bounce) + "_gather", [&] {
    // Fill invalid caches first: surfels may gather from them.
    detail::applyFill(p_.lightmap_fill, lm_sh_.data(), stride);
    if (fill_grid) detail::applyFill(p_.grid_fill, grid_sh_.data(), stride);
    const std::size_t chunks = (ns + kChunk - 1) / kChunk;
    chunk_added_.assign(chunks, 0.0);
    chunk_total_.assign(chunks, 0.0);
    forChunks(ns, kChunk, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
      double added = 0.0, total = 0.0;
      for (std::size_t s = begin; s < end; ++s) {
        const glm::vec3 nb = gatheredRadiosity(s, bands, stride);
        const glm::vec3 d = glm::abs(nb - b_[s]) * p_.surfels.area[s];
        added += double(d.x) + d.y + d.z;
        const glm::vec3 phi = (nb + emission_b_[s]) * p_.surfels.area[s];
        total += double(phi.x) + phi.y + phi.z;
        b_[s] = nb;
      }
      chunk_added_[chunk] = added;
      chunk_total_[chunk] = total;
    });
    sums_ = {};  // fixed-order reduction: thread-count independent
    for (std::size_t c = 0; c < chunks; ++c) sums_.added += chunk_added_[c], sums_.total += chunk_total_[c];
  });
  return {};
}

glm::vec3 CpuPasses::gatheredRadiosity(std::size_t s, int bands, std::size_t stride) const {
  const int nc = bands * bands;
  float acc[3 * sh::kMaxCoeffs];
  std::fill(acc, acc + stride, 0.0f);
  const float* base = t_.gather_from_grid[s] ? grid_sh_.data() : lm_sh_.data();
  for (std::uint32_t g = t_.gather_begin[s]; g < t_.gather_begin[s + 1]; ++g) {
    const float* src = base + std::size_t(t_.gather_cache[g]) * stride;
    const float wt = t_.gather_weight[g];
    for (std::size_t i = 0; i < stride; ++i) acc[i] += wt * src[i];
  }
  const glm::vec3 n = p_.surfels.normal[s];
  const glm::vec3 e(sh::irradiance(bands, acc, n), sh::irradiance(bands, acc + nc, n),
                    sh::irradiance(bands, acc + 2 * nc, n));
  return b0_[s] + p_.surfels.albedo[s] * e;
}

void CpuPasses::sumCacheDirect(const EmitterTexels& emitter) {
  std::fill(cache_direct_.begin(), cache_direct_.end(), glm::vec3(0.0f));
  for (const auto& pc : per_light_cache_)
    if (!pc.empty())
      for (std::size_t c = 0; c < cache_direct_.size(); ++c) cache_direct_[c] += pc[c];
  if (emitter.value.size() == cache_direct_.size())
    for (std::size_t c = 0; c < cache_direct_.size(); ++c) cache_direct_[c] += emitter.value[c];
}

Status CpuPasses::cacheDirect(const RelightFrame& f, const EmitterTexels& emitter, RelightResult& res) {
  const auto& L = f.lights.lights();
  timedStage(res, "baked_direct", [&] {
    per_light_cache_.assign(L.size(), {});
    cache_direct_.assign(p_.lightmap.size(), glm::vec3(0.0f));
    if (!f.plan.baked_direct || !f.coarse_direct) return;
    for (std::size_t i = 0; i < L.size(); ++i) {
      if (!L[i].baked || !lightEmits(L[i].light)) continue;
      bakedDirect(L[i].light, per_light_cache_[i], res.counts.shadow_rays);
      res.passes.baked_direct++;
    }
  });
  sumCacheDirect(emitter);
  return {};
}

Status CpuPasses::texels(const RelightFrame& f, RelightResult& res) {
  const std::size_t stride = f.stride;
  cache_direct_.resize(p_.lightmap.size(), glm::vec3(0.0f));
  timedStage(res, "fill_dilate", [&] {
    detail::applyFill(p_.lightmap_fill, lm_sh_.data(), stride);
    detail::applyFill(p_.lightmap_fill, reinterpret_cast<float*>(cache_direct_.data()), 3);
    if (f.plan.grid) detail::applyFill(p_.grid_fill, grid_sh_.data(), stride);
    res.passes.fill = 1;
    const std::size_t texels = std::size_t(res.width) * res.height;
    // Every texel is written below (value or zero), so resize() need not clear.
    res.lightmap_sh.resize(texels * stride);
    const bool coarse = f.coarse_direct;
    if (coarse) {
      res.direct.resize(texels);
      res.direct_width = res.width, res.direct_height = res.height;
      res.direct_valid.clear();
    }
    res.texel_valid.resize(texels);
    const auto& map = t_.texel_map;
    forChunks(texels, 4096, [&](std::size_t, std::size_t begin, std::size_t end) {
      for (std::size_t t = begin; t < end; ++t) {
        float* dst = res.lightmap_sh.data() + t * stride;
        const std::uint32_t b0 = map.begin[t], b1 = map.begin[t + 1];
        if (b0 == b1) {
          std::fill(dst, dst + stride, 0.0f);
          if (coarse) res.direct[t] = glm::vec3(0.0f);
          res.texel_valid[t] = 0;
          continue;
        }
        if (b1 - b0 == 1 && map.weight[b0] == 1.0f) {  // a texel with its own cache
          const std::uint32_t c = map.point[b0];
          std::memcpy(dst, lm_sh_.data() + std::size_t(c) * stride, stride * sizeof(float));
          if (coarse) res.direct[t] = cache_direct_[c];
          res.texel_valid[t] = 1;
          continue;
        }
        std::fill(dst, dst + stride, 0.0f);
        glm::vec3 dir(0.0f);
        for (std::uint32_t k = b0; k < b1; ++k) {
          const std::uint32_t c = map.point[k];
          const float w = map.weight[k];
          const float* src = lm_sh_.data() + std::size_t(c) * stride;
          for (std::size_t i = 0; i < stride; ++i) dst[i] += w * src[i];
          dir += w * cache_direct_[c];
        }
        if (coarse) res.direct[t] = dir;
        res.texel_valid[t] = 1;
      }
    });
    res.counts.texels = texels;
    res.counts.texels_filled = std::size_t(std::count(res.texel_valid.begin(), res.texel_valid.end(), 1));
    if (f.plan.grid) res.grid_sh = grid_sh_;
    else res.grid_sh.clear();
    res.surfel_radiosity = b_;
  });
  return {};
}

// ---- incremental ---------------------------------------------------------------------------

Status CpuPasses::relightChange(const RelightFrame& f, const LightChange& c, std::span<const glm::vec3> surfel_emit,
                                const EmitterTexels& emitter, RelightResult& res) {
  const std::size_t ns = p_.surfels.size();
  const bool surfels_change = !sameLight(c.old_light, c.new_light);
  const bool bounced = f.plan.bounces;
  std::vector<std::uint32_t> touched;
  timedStage(res, "surfel_direct", [&] {
    if (surfels_change) touched = changeSurfels(c, surfel_emit, bounced, f.options.surfel_shadow_rays, res);
  });
  if (!surfels_change) {
    if (c.kind == LightChange::Kind::kRemoved) per_light_surfel_.erase(per_light_surfel_.begin() + c.index);
    if (c.kind == LightChange::Kind::kAdded) per_light_surfel_.emplace_back(ns, glm::vec3(0.0f));
  }
  if (bounced) {
    relit_lm_.clear(), relit_grid_.clear(), relit_all_ = false;
    pushChange(f, touched, "", res);
    timedStage(res, "baked_direct", [&] { changeDirect(f, c, surfels_change, emitter, res); });
    return {};
  }
  // A change that reaches most surfels (a directional or an unranged point light) changes
  // nearly every node and cache, and the sparse walks (serial path marking and sort, the
  // inverted link index) then cost more than the full pull and cache lighting
  // (relight_bench, "incremental"). The sums are the same in the same order either way.
  const bool dense = touched.size() * 2 > ns;
  std::vector<std::uint32_t> changed_nodes;
  timedStage(res, "pull", [&] { changed_nodes = changeTree(touched, dense, res); });
  timedStage(res, "cache_lighting", [&] {
    if (!changed_nodes.empty() || dense) changeCaches(f, changed_nodes, dense, res);
  });
  timedStage(res, "baked_direct", [&] { changeDirect(f, c, surfels_change, emitter, res); });
  return {};
}

std::vector<std::uint32_t> CpuPasses::changeSurfels(const LightChange& c, std::span<const glm::vec3> surfel_emit,
                                                    bool bounced, int shadow_rays, RelightResult& res) {
  const std::size_t ns = p_.surfels.size();
  // In parallel over fixed chunks, concatenated in order: the same list for any thread count.
  std::vector<std::uint32_t> touched;
  {
    const std::size_t chunks = (ns + kChunk - 1) / kChunk;
    std::vector<std::vector<std::uint32_t>> part(chunks);
    forChunks(ns, kChunk, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
      for (std::size_t s = begin; s < end; ++s)
        if (reaches(c.old_light, p_.surfels.position[s]) || reaches(c.new_light, p_.surfels.position[s]))
          part[chunk].push_back(std::uint32_t(s));
    });
    for (const auto& q : part) touched.insert(touched.end(), q.begin(), q.end());
  }
  if (c.kind == LightChange::Kind::kAdded) per_light_surfel_.emplace_back(ns, glm::vec3(0.0f));
  if (c.kind == LightChange::Kind::kRemoved) {
    per_light_surfel_.erase(per_light_surfel_.begin() + c.index);
  } else {
    std::vector<glm::vec3>& contrib = per_light_surfel_[c.index];
    std::fill(contrib.begin(), contrib.end(), glm::vec3(0.0f));
    // Every surfel: the full pass, which visits them in the same order and chunks.
    lightSurfels(c.new_light, shadow_rays, contrib, touched.size() == ns ? nullptr : &touched, res.counts.shadow_rays);
    res.passes.surfel_direct = 1;
  }
  // Re-sum in light order, exactly as the full relight does (per surfel: any order).
  forChunks(touched.size(), kChunk, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      const std::uint32_t s = touched[i];
      glm::vec3 e(0.0f);
      for (const auto& pl : per_light_surfel_) e += pl[s];
      if (!surfel_emit.empty()) e += surfel_emit[s];  // the kept emitter direct
      direct_e_[s] = e;
      const glm::vec3 nb0 = p_.surfels.albedo[s] * e;
      // With bounces, b keeps its gathered indirect part: b = b0 + rho * E_indirect.
      b_[s] = bounced ? b_[s] + (nb0 - b0_[s]) : nb0;
      b0_[s] = nb0;
      setLeafFlux(s);
    }
  });
  res.counts.surfels_lit = touched.size();
  return touched;
}

void CpuPasses::pushChange(const RelightFrame& f, const std::vector<std::uint32_t>& changed,
                           const std::string& prefix, RelightResult& res) {
  const auto& t = p_.tree;
  const std::size_t ns = p_.surfels.size(), nodes = t.nodeCount();
  const bool dense = changed.size() * 2 > ns;
  std::vector<std::uint32_t> marked;
  bool all_marked = false;
  timedStage(res, prefix + "pull", [&] {
    const std::size_t pulled_before = res.counts.nodes_pulled;
    const int pulls_before = res.passes.pulls;
    const std::vector<std::uint32_t> path = changeTree(changed, dense, res);
    res.counts.nodes_pulled += pulled_before;
    res.passes.pulls = pulls_before + 1;
    // A node's change reaches its caches only when it exceeds the tolerance: the root holds
    // the scene's mean radiosity, the scale of the tolerance. What is held back stays in
    // rad_lit_'s difference, so small changes add up until they are pushed (no drift).
    const float* root = rad_rgbx_.data();
    const float tol = f.options.bounce_threshold * std::max({root[0], root[1], root[2]});
    auto moved = [&](std::size_t n) {
      for (int ch = 0; ch < 3; ++ch)
        if (std::abs(rad_rgbx_[4 * n + ch] - rad_lit_[4 * n + ch]) > tol) return true;
      return false;
    };
    if (dense) {
      for (std::size_t n = 0; n < nodes; ++n)
        if (moved(n)) marked.push_back(std::uint32_t(n));
    } else {
      for (std::uint32_t n : path)
        if (moved(n)) marked.push_back(n);
      std::sort(marked.begin(), marked.end());
    }
  });
  timedStage(res, prefix + "cache_lighting", [&] {
    if (marked.empty()) return;
    if (!inverted_built_) buildInverted();
    const auto& lm = t_.lm_links;
    std::size_t marked_links = 0;
    for (std::uint32_t n : marked) marked_links += lm_inv_begin_[n + 1] - lm_inv_begin_[n];
    // Most links touched: the full pass costs less than listing the caches.
    all_marked = marked_links * 2 > lm.linkCount();
    auto affected = [&](const std::vector<std::uint32_t>& begin, const std::vector<std::uint32_t>& inv,
                        std::size_t count) { return linkedCaches(marked, begin, inv, count); };
    if (all_marked) {
      lightCaches(f, lm, lm_sh_, p_.lightmap.valid, nullptr);
      res.counts.caches_summed += lm.cacheCount();
      res.counts.links_read += lm.linkCount();
      if (f.plan.grid) {
        lightCaches(f, t_.grid_links, grid_sh_, p_.grid.valid, nullptr);
        res.counts.grid_caches_summed += t_.grid_links.cacheCount();
        res.counts.links_read += t_.grid_links.linkCount();
      }
      rad_lit_ = rad_rgbx_;
      relit_all_ = true;
    } else {
      const auto lm_list = affected(lm_inv_begin_, lm_inv_, lm.cacheCount());
      lightCaches(f, lm, lm_sh_, p_.lightmap.valid, &lm_list);
      res.counts.caches_summed += lm_list.size();
      for (std::uint32_t c : lm_list) res.counts.links_read += lm.offsets[c + 1] - lm.offsets[c];
      relit_lm_.insert(relit_lm_.end(), lm_list.begin(), lm_list.end());
      if (f.plan.grid) {
        const auto& g = t_.grid_links;
        const auto g_list = affected(grid_inv_begin_, grid_inv_, g.cacheCount());
        lightCaches(f, g, grid_sh_, p_.grid.valid, &g_list);
        res.counts.grid_caches_summed += g_list.size();
        for (std::uint32_t c : g_list) res.counts.links_read += g.offsets[c + 1] - g.offsets[c];
        relit_grid_.insert(relit_grid_.end(), g_list.begin(), g_list.end());
      }
      for (std::uint32_t n : marked) std::memcpy(&rad_lit_[4 * n], &rad_rgbx_[4 * n], 4 * sizeof(float));
    }
    res.passes.cache_lighting++;
    res.passes.grid_lighting += f.plan.grid ? 1 : 0;
    res.passes.sky = f.plan.sky ? 1 : 0;
  });
}

void CpuPasses::buildGatherInverse() {
  const std::size_t ns = p_.surfels.size();
  auto invert = [&](bool grid, std::size_t caches, std::vector<std::uint32_t>& begin,
                    std::vector<std::uint32_t>& out) {
    begin.assign(caches + 1, 0);
    for (std::size_t s = 0; s < ns; ++s)
      if (bool(t_.gather_from_grid[s]) == grid)
        for (std::uint32_t g = t_.gather_begin[s]; g < t_.gather_begin[s + 1]; ++g) ++begin[t_.gather_cache[g] + 1];
    for (std::size_t c = 0; c < caches; ++c) begin[c + 1] += begin[c];
    out.resize(begin[caches]);
    std::vector<std::uint32_t> fill(begin.begin(), begin.end() - 1);
    for (std::size_t s = 0; s < ns; ++s)
      if (bool(t_.gather_from_grid[s]) == grid)
        for (std::uint32_t g = t_.gather_begin[s]; g < t_.gather_begin[s + 1]; ++g)
          out[fill[t_.gather_cache[g]]++] = std::uint32_t(s);
  };
  invert(false, p_.lightmap.size(), lm_readers_begin_, lm_readers_);
  invert(true, p_.has_grid ? p_.grid.size() : 0, grid_readers_begin_, grid_readers_);
  gather_inverse_built_ = true;
}

Expected<BounceSums> CpuPasses::propagateChange(const RelightFrame& f, int round, RelightResult& res) {
  const std::size_t ns = p_.surfels.size(), stride = f.stride;
  const int bands = f.bands;
  std::vector<std::uint32_t> changed;
  BounceSums sums;
  timedStage(res, "bounce" + std::to_string(round) + "_gather", [&] {
    if (!gather_inverse_built_) buildGatherInverse();
    // Invalid caches take their value from the fill plan, so a changed source changes them.
    auto spread = [&](const caches::FillPlan& plan, float* data, std::vector<std::uint8_t>& flag) {
      detail::applyFill(plan, data, stride);
      for (std::size_t i = 0; i < plan.target.size(); ++i)
        for (std::uint32_t k = plan.source_begin[i]; k < plan.source_begin[i + 1] && !flag[plan.target[i]]; ++k)
          if (flag[plan.source[k]]) flag[plan.target[i]] = 1;
    };
    std::vector<std::uint32_t> list;  // surfels to gather again, in order
    if (relit_all_) {
      detail::applyFill(p_.lightmap_fill, lm_sh_.data(), stride);
      if (t_.grid_gathered) detail::applyFill(p_.grid_fill, grid_sh_.data(), stride);
      list.resize(ns);
      for (std::size_t s = 0; s < ns; ++s) list[s] = std::uint32_t(s);
    } else {
      std::vector<std::uint8_t> lm_flag(p_.lightmap.size(), 0), reads(ns, 0);
      for (std::uint32_t c : relit_lm_) lm_flag[c] = 1;
      spread(p_.lightmap_fill, lm_sh_.data(), lm_flag);
      for (std::size_t c = 0; c < lm_flag.size(); ++c)
        if (lm_flag[c])
          for (std::uint32_t k = lm_readers_begin_[c]; k < lm_readers_begin_[c + 1]; ++k) reads[lm_readers_[k]] = 1;
      if (t_.grid_gathered) {
        std::vector<std::uint8_t> g_flag(p_.grid.size(), 0);
        for (std::uint32_t c : relit_grid_) g_flag[c] = 1;
        spread(p_.grid_fill, grid_sh_.data(), g_flag);
        for (std::size_t c = 0; c < g_flag.size(); ++c)
          if (g_flag[c])
            for (std::uint32_t k = grid_readers_begin_[c]; k < grid_readers_begin_[c + 1]; ++k)
              reads[grid_readers_[k]] = 1;
      }
      for (std::size_t s = 0; s < ns; ++s)
        if (reads[s]) list.push_back(std::uint32_t(s));
    }
    relit_lm_.clear(), relit_grid_.clear(), relit_all_ = false;
    // Gather as the full bounce does; fixed chunks and fixed-order sums.
    const std::size_t chunks = (list.size() + kChunk - 1) / kChunk;
    std::vector<std::vector<std::uint32_t>> part(chunks);
    chunk_added_.assign(chunks, 0.0);
    forChunks(list.size(), kChunk, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
      double added = 0.0;
      for (std::size_t i = begin; i < end; ++i) {
        const std::uint32_t s = list[i];
        const glm::vec3 nb = gatheredRadiosity(s, bands, stride);
        if (nb == b_[s]) continue;
        const glm::vec3 d = glm::abs(nb - b_[s]) * p_.surfels.area[s];
        added += double(d.x) + d.y + d.z;
        b_[s] = nb;
        setLeafFlux(s);
        part[chunk].push_back(s);
      }
      chunk_added_[chunk] = added;
    });
    for (std::size_t c = 0; c < chunks; ++c) sums.added += chunk_added_[c];
    for (const auto& q : part) changed.insert(changed.end(), q.begin(), q.end());
    res.counts.surfels_gathered += list.size();
    // The total flux, as the full bounce sums it (fixed chunks over every surfel).
    const std::size_t all_chunks = (ns + kChunk - 1) / kChunk;
    chunk_total_.assign(all_chunks, 0.0);
    forChunks(ns, kChunk, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
      double total = 0.0;
      for (std::size_t s = begin; s < end; ++s) {
        const glm::vec3 phi = (b_[s] + emission_b_[s]) * p_.surfels.area[s];
        total += double(phi.x) + phi.y + phi.z;
      }
      chunk_total_[chunk] = total;
    });
    for (std::size_t c = 0; c < all_chunks; ++c) sums.total += chunk_total_[c];
  });
  pushChange(f, changed, "bounce" + std::to_string(round) + "_", res);
  return sums;
}

std::vector<std::uint32_t> CpuPasses::changeTree(const std::vector<std::uint32_t>& touched, bool dense,
                                                 RelightResult& res) {
  std::vector<std::uint32_t> changed_nodes;
  const auto& t = p_.tree;
  const std::size_t nodes = t.nodeCount();
  if (dense) {
    pullAll();
    res.counts.nodes_pulled = nodes;
    res.passes.pulls = 1;
    return changed_nodes;
  }
  if (touched.empty()) return changed_nodes;
  std::vector<std::uint8_t> mark(nodes, 0);
  for (std::uint32_t s : touched) {
    std::int32_t n = std::int32_t(t.leaf_of_surfel[s]);
    while (n >= 0 && !mark[n]) mark[n] = 1, changed_nodes.push_back(std::uint32_t(n)), n = t.parent[n];
  }
  std::sort(changed_nodes.begin(), changed_nodes.end(), std::greater<>());
  for (std::uint32_t n : changed_nodes) {
    if (t.left[n] >= 0)
      for (int ch = 0; ch < 3; ++ch) flux_[ch][n] = flux_[ch][t.left[n]] + flux_[ch][t.right[n]];
    const float inv_area = t_.pull.inv_node[n];
    for (int ch = 0; ch < 3; ++ch) rad_rgbx_[4 * n + ch] = flux_[ch][n] * inv_area;
  }
  res.counts.nodes_pulled = changed_nodes.size();
  res.passes.pulls = 1;
  return changed_nodes;
}

void CpuPasses::changeCaches(const RelightFrame& f, const std::vector<std::uint32_t>& changed_nodes, bool dense,
                             RelightResult& res) {
  if (!dense && !inverted_built_) buildInverted();
  auto affected = [&](const std::vector<std::uint32_t>& begin, const std::vector<std::uint32_t>& inv,
                      std::size_t count) { return linkedCaches(changed_nodes, begin, inv, count); };
  // dense: every cache (a null subset).
  const auto& lm = t_.lm_links;
  const auto lm_list = dense ? std::vector<std::uint32_t>{} : affected(lm_inv_begin_, lm_inv_, lm.cacheCount());
  lightCaches(f, lm, lm_sh_, p_.lightmap.valid, dense ? nullptr : &lm_list);
  res.counts.caches_summed = dense ? lm.cacheCount() : lm_list.size();
  if (dense) res.counts.links_read += lm.linkCount();
  for (std::uint32_t c : lm_list) res.counts.links_read += lm.offsets[c + 1] - lm.offsets[c];
  res.passes.cache_lighting = 1;
  res.passes.sky = f.plan.sky ? 1 : 0;
  if (f.plan.grid) {
    const auto& g = t_.grid_links;
    const auto g_list = dense ? std::vector<std::uint32_t>{} : affected(grid_inv_begin_, grid_inv_, g.cacheCount());
    lightCaches(f, g, grid_sh_, p_.grid.valid, dense ? nullptr : &g_list);
    res.counts.grid_caches_summed = dense ? g.cacheCount() : g_list.size();
    res.passes.grid_lighting = 1;
  }
}

void CpuPasses::changeDirect(const RelightFrame& f, const LightChange& c, bool surfels_change,
                             const EmitterTexels& emitter, RelightResult& res) {
  if (c.kind == LightChange::Kind::kAdded) per_light_cache_.emplace_back();
  if (c.kind == LightChange::Kind::kRemoved) {
    per_light_cache_.erase(per_light_cache_.begin() + c.index);
  } else if (c.new_baked && f.coarse_direct) {
    if (surfels_change || !c.old_baked || per_light_cache_[c.index].empty()) {
      bakedDirect(c.new_light, per_light_cache_[c.index], res.counts.shadow_rays);
      res.passes.baked_direct = 1;
    }
  } else {
    per_light_cache_[c.index].clear();
  }
  // Emission and its sampling are unchanged (eligibility): the kept emitter direct.
  sumCacheDirect(emitter);
}

// ---- kernels -------------------------------------------------------------------------------

void CpuPasses::lightSurfels(const scene::Light& light, int shadow_rays, std::vector<glm::vec3>& out,
                             const std::vector<std::uint32_t>* subset, std::size_t& rays) const {
  // Surfels in tree order are spatial neighbours and every ray ends at the same light (or is
  // parallel to its neighbours): 16-ray packets traverse nearly the same nodes. Lightmap
  // caches jump between charts, so their rays stay on the stream path (relight_bench).
  detail::shadowedLight(t_.accel, light, p_.surfels.position, p_.surfels.normal, {}, subset, out, rays,
                        rt::Coherence::kCoherent, {p_.surfels.area, shadow_rays, neighbour_begin_, neighbour_});
}

void CpuPasses::bakedDirect(const scene::Light& light, std::vector<glm::vec3>& out, std::size_t& rays) const {
  detail::shadowedLight(t_.accel, light, p_.lightmap.position, p_.lightmap.normal, p_.lightmap.valid, nullptr, out,
                        rays, rt::Coherence::kIncoherent);
}

void CpuPasses::setLeafFlux(std::size_t s) {
  const std::uint32_t leaf = p_.tree.leaf_of_surfel[s];
  const glm::vec3 phi = b_[s] * t_.pull.surfel[s];
  flux_[0][leaf] = phi.x, flux_[1][leaf] = phi.y, flux_[2][leaf] = phi.z;
}

void CpuPasses::pullAll() {
  const auto& t = p_.tree;
  // Children have larger indices than their parent: a reverse loop is a bottom-up pull.
  for (std::size_t n = t.nodeCount(); n-- > 0;) {
    if (t.left[n] >= 0)
      for (int ch = 0; ch < 3; ++ch) flux_[ch][n] = flux_[ch][t.left[n]] + flux_[ch][t.right[n]];
    const float inv_area = t_.pull.inv_node[n];
    for (int ch = 0; ch < 3; ++ch) rad_rgbx_[4 * n + ch] = flux_[ch][n] * inv_area;
  }
}

std::vector<std::uint32_t> CpuPasses::linkedCaches(const std::vector<std::uint32_t>& nodes,
                                                   const std::vector<std::uint32_t>& begin,
                                                   const std::vector<std::uint32_t>& inv, std::size_t count) {
  std::vector<std::uint8_t> hit(count, 0);
  for (std::uint32_t n : nodes)
    for (std::uint32_t k = begin[n]; k < begin[n + 1]; ++k) hit[inv[k]] = 1;
  std::vector<std::uint32_t> list;
  for (std::size_t c = 0; c < count; ++c)
    if (hit[c]) list.push_back(std::uint32_t(c));
  return list;
}

void CpuPasses::buildInverted() {
  auto invert = [&](const links::LinksView& v, std::vector<std::uint32_t>& begin, std::vector<std::uint32_t>& out) {
    const std::size_t nodes = p_.tree.nodeCount();
    begin.assign(nodes + 1, 0);
    for (std::size_t k = 0; k < v.linkCount(); ++k) ++begin[v.node[k] + 1];
    for (std::size_t n = 0; n < nodes; ++n) begin[n + 1] += begin[n];
    out.resize(v.linkCount());
    std::vector<std::uint32_t> fill(begin.begin(), begin.end() - 1);
    for (std::size_t c = 0; c < v.cacheCount(); ++c)
      for (std::uint32_t k = v.offsets[c]; k < v.offsets[c + 1]; ++k) out[fill[v.node[k]]++] = std::uint32_t(c);
  };
  invert(t_.lm_links, lm_inv_begin_, lm_inv_);
  if (p_.has_grid) invert(t_.grid_links, grid_inv_begin_, grid_inv_);
  inverted_built_ = true;
}

void CpuPasses::lightCaches(const RelightFrame& f, const links::LinksView& view, std::vector<float>& out,
                            const std::vector<std::uint8_t>& valid, const std::vector<std::uint32_t>* subset) {
  const int bands = f.bands, nc = bands * bands;
  const int ncl = view.bands * view.bands;
  const std::size_t stride = f.stride;
  const bool sky = f.plan.sky;
  out.resize(view.cacheCount() * stride);
  const std::size_t n = subset ? subset->size() : view.cacheCount();
  const detail::NodeRadiance node{rad_rgbx_.data()};
  auto kernel = f.options.link_form == LinkForm::kProjected
                    ? (simd_ ? detail::lightCacheProjectedAvx2 : detail::lightCacheProjectedScalar)
                    : (simd_ ? detail::lightCacheRuntimeAvx2 : detail::lightCacheRuntimeScalar);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, kCacheChunk),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i < r.end(); ++i) {
                        const std::size_t c = subset ? (*subset)[i] : i;
                        float* o = out.data() + c * stride;
                        if (!valid[c]) {
                          // Invalid caches get their value from the fill plan.
                          std::fill(o, o + stride, 0.0f);
                          continue;
                        }
                        kernel(view, c, bands, node, o);
                        if (sky) {
                          const float* v = view.sky.data() + c * ncl;
                          for (int ch = 0; ch < 3; ++ch) {
                            const float* m = f.sky_matrix[ch].data();
                            for (int a = 0; a < nc; ++a) {
                              float s = 0.0f;
                              for (int j = 0; j < ncl; ++j) s += m[a * ncl + j] * v[j];
                              o[ch * nc + a] += s;
                            }
                          }
                        }
                      }
                    });
}

}  // namespace

Status RelightPasses::relightChange(const RelightFrame&, const LightChange&, std::span<const glm::vec3>,
                                    const EmitterTexels&, RelightResult&) {
  return internalError("relight: the {} backend has no incremental relight", backend());
}

Expected<BounceSums> RelightPasses::propagateChange(const RelightFrame&, int, RelightResult&) {
  return internalError("relight: the {} backend has no incremental relight with bounces", backend());
}

std::unique_ptr<RelightPasses> makeCpuPasses(const SceneTables& tables) {
  return std::make_unique<CpuPasses>(tables);
}

}  // namespace lightlink::relight
