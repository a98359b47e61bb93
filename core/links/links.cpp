#include "core/links/links.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <queue>

#include <tbb/parallel_for.h>

#include "core/common/sampling.h"
#include "core/links/surfel_locator.h"
#include "core/sh/sh.h"

namespace lightlink::links {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;
// Caches per parallel work item. Fixed (not derived from the thread count) so results are
// concatenated in the same order whatever the scheduling.
constexpr std::size_t kChunk = 32;

// Rays per cache form a strata x strata stratified grid.
std::uint32_t strataFor(const LinkOptions& options) {
  return static_cast<std::uint32_t>(std::max(1.0, std::floor(std::sqrt(double(options.rays)))));
}

// A credited hit as one sortable key: owner surfel in the high half, ray in the low half,
// so sorting the keys groups hits by surfel (tree order) with a fixed order inside.
using Sample = std::uint64_t;
inline Sample makeSample(std::uint32_t surfel, std::uint32_t ray) { return (Sample(surfel) << 32) | ray; }
inline std::uint32_t surfelOf(Sample s) { return static_cast<std::uint32_t>(s >> 32); }
inline std::uint32_t rayOf(Sample s) { return static_cast<std::uint32_t>(s); }

// Per-thread scratch, reused across caches so the hot loop never allocates.
struct Scratch {
  std::vector<rt::Ray> rays;
  std::vector<rt::Hit> hits;
  std::vector<Sample> samples;
  std::vector<std::uint32_t> cut;
};

struct ChunkResult {
  std::vector<std::uint32_t> count;  // links per cache
  std::vector<std::uint32_t> node;
  std::vector<half_bits> coeffs;
  std::vector<std::uint32_t> direction;
  std::vector<half_bits> solid_angle;
  std::vector<float> sky;
  LinkStats stats;
};

// Number of samples whose surfel lies in [begin, end): samples are sorted by surfel.
std::uint32_t samplesIn(const std::vector<Sample>& s, std::uint32_t begin, std::uint32_t end) {
  auto lo = std::lower_bound(s.begin(), s.end(), makeSample(begin, 0));
  auto hi = std::lower_bound(lo, s.end(), makeSample(end, 0));
  return static_cast<std::uint32_t>(hi - lo);
}

// Cut selection (seed 000 sec 4.5): refine the node with the most visible samples until
// max_links nodes are in the cut or nothing visible can be refined. Nodes without samples
// are dropped, so the cut covers exactly the visible surfels. All samples carry the same
// solid angle, so sample counts order nodes exactly as visible solid angle does.
void chooseCut(const hierarchy::Tree& tree, const std::vector<Sample>& samples, int max_links,
               std::vector<std::uint32_t>& cut) {
  cut.clear();
  if (samples.empty() || tree.nodeCount() == 0) return;
  struct Entry {
    std::uint32_t count, node;
    // Largest count first; ties to the lower node index, for determinism.
    bool operator<(const Entry& o) const { return count != o.count ? count < o.count : node > o.node; }
  };
  std::priority_queue<Entry> open;
  open.push({static_cast<std::uint32_t>(samples.size()), 0});
  const auto limit = static_cast<std::size_t>(max_links);
  while (!open.empty()) {
    const Entry top = open.top();
    if (tree.isLeaf(top.node)) {
      open.pop();
      cut.push_back(top.node);
      continue;
    }
    const auto l = static_cast<std::uint32_t>(tree.left[top.node]);
    const auto r = static_cast<std::uint32_t>(tree.right[top.node]);
    const std::uint32_t cl = samplesIn(samples, tree.begin[l], tree.end[l]);
    const std::uint32_t cr = top.count - cl;
    const std::size_t grow = (cl > 0 && cr > 0) ? 1 : 0;
    if (open.size() + cut.size() + grow > limit) break;
    open.pop();
    if (cl > 0) open.push({cl, l});
    if (cr > 0) open.push({cr, r});
  }
  while (!open.empty()) {
    cut.push_back(open.top().node);
    open.pop();
  }
  // Order by surfel range so the projection walks the sorted samples once.
  std::sort(cut.begin(), cut.end(), [&](std::uint32_t a, std::uint32_t b) { return tree.begin[a] < tree.begin[b]; });
}

template <int Bands>
void linkCache(std::size_t cache, const glm::vec3& p, const glm::vec3& normal, const scene::Scene& scene,
               const rt::Accel& accel, const hierarchy::Tree& tree, const SurfelLocator& locator,
               const LinkOptions& options, std::uint32_t strata, Scratch& s, ChunkResult& out) {
  constexpr int kCoeffs = Bands * Bands;
  const bool hemisphere = glm::dot(normal, normal) > 0.0f;
  const std::uint32_t count = strata * strata;
  const glm::vec3 n = hemisphere ? glm::normalize(normal) : glm::vec3(0, 0, 1);
  cacheRays(accel, cache, p, normal, options, std::span<rt::Ray>(s.rays.data(), count));
  accel.intersect(std::span<const rt::Ray>(s.rays.data(), count), std::span<rt::Hit>(s.hits.data(), count),
                  rt::Coherence::kCoherent);

  const float omega = hemisphere ? 2.0f * kPi : 4.0f * kPi;
  const float w = omega / static_cast<float>(count) / kPi;  // per-ray weight of V/pi
  float basis[kCoeffs];
  float sky[kCoeffs] = {};
  s.samples.clear();
  for (std::uint32_t i = 0; i < count; ++i) {
    const rt::Hit& h = s.hits[i];
    const glm::vec3& dir = s.rays[i].dir;
    if (!h.hit()) {
      ++out.stats.escaped;
      sh::evalBasis<Bands>(dir, basis);
      for (int k = 0; k < kCoeffs; ++k) sky[k] += w * basis[k];
      continue;
    }
    const bool back = h.backFacing(dir);
    if (back && !scene.materialOf(scene.meshes[h.mesh]).double_sided) {
      ++out.stats.back_hits;
      continue;
    }
    // The visible side's normal faces the cache (left unnormalised: the locator only
    // needs it when it falls back to its grid).
    const std::uint32_t owner =
        locator.ownerOfHit(h.mesh, h.triangle, s.rays[i].origin + h.t * dir, back ? -h.ng : h.ng);
    if (owner == kNoSurfel) {
      ++out.stats.unowned;
      continue;
    }
    ++out.stats.front_hits;
    s.samples.push_back(makeSample(owner, i));
  }
  out.stats.rays += count;
  std::sort(s.samples.begin(), s.samples.end());
  chooseCut(tree, s.samples, options.max_links, s.cut);

  std::size_t k = 0;
  for (std::uint32_t node : s.cut) {
    while (k < s.samples.size() && surfelOf(s.samples[k]) < tree.begin[node]) ++k;
    float c[kCoeffs] = {};
    glm::vec3 mean_dir(0.0f);
    std::uint32_t hits = 0;
    for (; k < s.samples.size() && surfelOf(s.samples[k]) < tree.end[node]; ++k) {
      const glm::vec3& dir = s.rays[rayOf(s.samples[k])].dir;
      sh::evalBasis<Bands>(dir, basis);
      for (int q = 0; q < kCoeffs; ++q) c[q] += w * basis[q];
      mean_dir += dir;
      ++hits;
    }
    out.node.push_back(node);
    for (int q = 0; q < kCoeffs; ++q) out.coeffs.push_back(toHalf(c[q]));
    const float len = glm::length(mean_dir);
    out.direction.push_back(encodeOctahedral(len > 0.0f ? mean_dir / len : n));
    out.solid_angle.push_back(toHalf(w * static_cast<float>(hits)));
  }
  out.count.push_back(static_cast<std::uint32_t>(s.cut.size()));
  out.sky.insert(out.sky.end(), sky, sky + kCoeffs);
}

using LinkCacheFn = decltype(&linkCache<1>);
LinkCacheFn linkCacheFor(int bands) {
  switch (bands) {
    case 1: return &linkCache<1>;
    case 2: return &linkCache<2>;
    case 3: return &linkCache<3>;
    default: return &linkCache<4>;
  }
}

}  // namespace

std::uint32_t raysPerCache(const LinkOptions& options) {
  const std::uint32_t strata = strataFor(options);
  return strata * strata;
}

void cacheRays(const rt::Accel& accel, std::size_t cache, const glm::vec3& p, const glm::vec3& normal,
               const LinkOptions& options, std::span<rt::Ray> rays) {
  const bool hemisphere = glm::dot(normal, normal) > 0.0f;
  const std::uint32_t strata = strataFor(options);
  const std::uint32_t count = strata * strata;
  glm::vec3 t(1, 0, 0), b(0, 1, 0), n(0, 0, 1);
  if (hemisphere) {
    n = glm::normalize(normal);
    orthonormalBasis(n, t, b);
  }
  const std::uint64_t seed = mixBits(options.seed ^ (std::uint64_t(cache) * 0xd1b54a32d192ed03ULL));
  for (std::uint32_t i = 0; i < count; ++i) {
    const glm::vec2 u = stratifiedSample(i, strata, seed);
    const glm::vec3 local = hemisphere ? uniformHemisphere(u.x, u.y) : uniformSphere(u.x, u.y);
    const glm::vec3 dir = glm::normalize(local.x * t + local.y * b + local.z * n);
    rays[i].origin = hemisphere ? accel.offsetOrigin(p, n, dir) : p;
    rays[i].dir = dir;
    rays[i].tnear = 0.0f;
    rays[i].tfar = std::numeric_limits<float>::infinity();
  }
}

void capZonal(float omega, int bands, float* z) {
  const float cos_half = std::clamp(1.0f - omega / (2.0f * kPi), -1.0f, 1.0f);
  const auto zonal = sh::coneZonal(std::acos(cos_half));
  for (int l = 0; l < bands; ++l) z[l] = zonal[l] / kPi;
}

void projectRuntimeLink(const glm::vec3& direction, float omega_over_pi, int bands, float* coeffs) {
  float z[sh::kMaxBands];
  capZonal(omega_over_pi * kPi, bands, z);
  sh::evalBasis(bands, direction, coeffs);
  for (int i = 0; i < bands * bands; ++i) {
    const int l = sh::bandOf(i);
    coeffs[i] *= std::sqrt(4.0f * kPi / float(2 * l + 1)) * z[l];
  }
}

std::uint32_t encodeOctahedral(const glm::vec3& d) {
  const float inv = 1.0f / (std::abs(d.x) + std::abs(d.y) + std::abs(d.z));
  glm::vec2 o(d.x * inv, d.y * inv);
  if (d.z < 0.0f) {
    o = glm::vec2((1.0f - std::abs(o.y)) * (o.x >= 0.0f ? 1.0f : -1.0f),
                  (1.0f - std::abs(o.x)) * (o.y >= 0.0f ? 1.0f : -1.0f));
  }
  auto q = [](float v) {
    return static_cast<std::uint32_t>(static_cast<std::uint16_t>(
        static_cast<std::int16_t>(std::lround(std::clamp(v, -1.0f, 1.0f) * 32767.0f))));
  };
  return q(o.x) | (q(o.y) << 16);
}

glm::vec3 decodeOctahedral(std::uint32_t packed) {
  const float x = static_cast<float>(static_cast<std::int16_t>(packed & 0xffffu)) / 32767.0f;
  const float y = static_cast<float>(static_cast<std::int16_t>(packed >> 16)) / 32767.0f;
  glm::vec3 v(x, y, 1.0f - std::abs(x) - std::abs(y));
  if (v.z < 0.0f) {
    v.x = (1.0f - std::abs(y)) * (x >= 0.0f ? 1.0f : -1.0f);
    v.y = (1.0f - std::abs(x)) * (y >= 0.0f ? 1.0f : -1.0f);
  }
  return glm::normalize(v);
}

Expected<Links> generateLinks(const scene::Scene& scene, const rt::Accel& accel, const surfels::Surfels& surfels,
                              const hierarchy::Tree& tree, const CacheQuery& caches, const LinkOptions& options,
                              Progress* progress) {
  if (options.bands < 1 || options.bands > sh::kMaxBands)
    return invalidInput("SH bands {} is out of range (1..{})", options.bands, sh::kMaxBands);
  if (options.rays < 1 || options.rays > (1 << 20))
    return invalidInput("link rays per cache {} is out of range (1..1048576)", options.rays);
  if (options.max_links < 1 || options.max_links > (1 << 16))
    return invalidInput("links per cache {} is out of range (1..65536)", options.max_links);
  if (caches.position.size() != caches.normal.size())
    return invalidInput("caches: {} positions but {} normals", caches.position.size(), caches.normal.size());
  if (tree.surfelCount() != surfels.size())
    return invalidInput("links: the tree covers {} surfels but {} were given", tree.surfelCount(), surfels.size());

  const auto start = std::chrono::steady_clock::now();
  const SurfelLocator locator(surfels, scene);
  const LinkCacheFn link_cache = linkCacheFor(options.bands);
  const std::uint32_t strata = strataFor(options);
  const std::size_t n = caches.position.size();
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  std::vector<ChunkResult> results(chunks);
  NullProgress null_progress;
  Progress& sink = progress ? *progress : null_progress;
  sink.begin(options.progress_label, n);
  ProgressCounter counter(sink, std::max<std::size_t>(1, n / 200));
  tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t chunk) {
    thread_local Scratch scratch;
    const std::uint32_t count = strata * strata;
    scratch.rays.resize(count);
    scratch.hits.resize(count);
    ChunkResult& out = results[chunk];
    const std::size_t end = std::min(n, (chunk + 1) * kChunk);
    if (sink.cancelled()) return;
    for (std::size_t c = chunk * kChunk; c < end; ++c)
      link_cache(c, caches.position[c], caches.normal[c], scene, accel, tree, locator, options, strata,
                scratch, out);
    counter.add(end - chunk * kChunk);
  });
  sink.end();
  if (sink.cancelled()) return Status(Code::kInternal, "link generation cancelled");

  Links links;
  links.bands = options.bands;
  links.offsets.reserve(n + 1);
  links.offsets.push_back(0);
  for (auto& r : results) {
    for (std::uint32_t c : r.count) links.offsets.push_back(links.offsets.back() + c);
    links.node.insert(links.node.end(), r.node.begin(), r.node.end());
    links.coeffs.insert(links.coeffs.end(), r.coeffs.begin(), r.coeffs.end());
    links.direction.insert(links.direction.end(), r.direction.begin(), r.direction.end());
    links.solid_angle.insert(links.solid_angle.end(), r.solid_angle.begin(), r.solid_angle.end());
    links.sky.insert(links.sky.end(), r.sky.begin(), r.sky.end());
    links.stats.rays += r.stats.rays;
    links.stats.front_hits += r.stats.front_hits;
    links.stats.back_hits += r.stats.back_hits;
    links.stats.escaped += r.stats.escaped;
    links.stats.unowned += r.stats.unowned;
    r = ChunkResult();  // release as we go: peak memory stays ~1x the links
  }
  links.stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return links;
}

}  // namespace lightlink::links
