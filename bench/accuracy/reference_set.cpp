#include "bench/accuracy/reference_set.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>

#include <fmt/format.h>

#include "core/artifact/artifact.h"
#include "core/reference/compare.h"

namespace lightlink::bench {
namespace {

// One point of the cache file: plain floats, written and read as is (little-endian hosts).
struct Record {
  float position[3], normal[3];
  std::uint32_t cache_a, cache_b;
  std::uint64_t rays;
  float total[3], direct[3], indirect[3], direct_punctual[3];
  float se_total[3], se_direct[3], se_indirect[3];
  std::uint32_t samples, truncated_paths, converged;
};
static_assert(sizeof(Record) == 136);

constexpr char kMagic[8] = {'L', 'L', 'R', 'E', 'F', 'v', '1', '\0'};

void put(float* dst, const glm::vec3& v) { dst[0] = v.x, dst[1] = v.y, dst[2] = v.z; }
glm::vec3 get(const float* src) { return {src[0], src[1], src[2]}; }

Record toRecord(const ComparePoint& p, const reference::IrradianceEstimate& e) {
  Record r{};
  put(r.position, p.position);
  put(r.normal, p.normal);
  r.cache_a = p.cache_a;
  r.cache_b = p.cache_b;
  put(r.total, e.total);
  put(r.direct, e.direct);
  put(r.indirect, e.indirect);
  put(r.direct_punctual, e.direct_punctual);
  put(r.se_total, e.std_error_total);
  put(r.se_direct, e.std_error_direct);
  put(r.se_indirect, e.std_error_indirect);
  r.samples = e.samples;
  r.truncated_paths = e.truncated_paths;
  r.rays = e.rays;
  r.converged = e.converged ? 1 : 0;
  return r;
}

reference::IrradianceEstimate toEstimate(const Record& r) {
  reference::IrradianceEstimate e;
  e.total = get(r.total);
  e.direct = get(r.direct);
  e.indirect = get(r.indirect);
  e.direct_punctual = get(r.direct_punctual);
  e.std_error_total = get(r.se_total);
  e.std_error_direct = get(r.se_direct);
  e.std_error_indirect = get(r.se_indirect);
  e.samples = r.samples;
  e.truncated_paths = r.truncated_paths;
  e.rays = r.rays;
  e.converged = r.converged != 0;
  return e;
}

bool sameBits(const glm::vec3& a, const float* b) { return std::memcmp(&a[0], b, 3 * sizeof(float)) == 0; }

// The cached estimates when the file exists, has this key and exactly these points.
std::optional<std::vector<reference::IrradianceEstimate>> readCache(const std::string& file, std::uint64_t key,
                                                                    const std::vector<ComparePoint>& points) {
  std::FILE* f = std::fopen(file.c_str(), "rb");
  if (!f) return std::nullopt;
  char magic[8];
  std::uint64_t file_key = 0, n = 0;
  std::vector<Record> records;
  bool ok = std::fread(magic, 1, 8, f) == 8 && std::memcmp(magic, kMagic, 8) == 0 &&
            std::fread(&file_key, 8, 1, f) == 1 && std::fread(&n, 8, 1, f) == 1 && file_key == key &&
            n == points.size();
  if (ok) {
    records.resize(n);
    ok = std::fread(records.data(), sizeof(Record), n, f) == n;
  }
  std::fclose(f);
  if (!ok) return std::nullopt;
  std::vector<reference::IrradianceEstimate> out;
  for (std::size_t i = 0; i < n; ++i) {
    const Record& r = records[i];
    if (!sameBits(points[i].position, r.position) || !sameBits(points[i].normal, r.normal) ||
        points[i].cache_a != r.cache_a || points[i].cache_b != r.cache_b)
      return std::nullopt;
    out.push_back(toEstimate(r));
  }
  return out;
}

Status writeCache(const std::string& file, std::uint64_t key, const std::vector<ComparePoint>& points,
                  const std::vector<reference::IrradianceEstimate>& estimates) {
  const std::string tmp = file + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) return ioError("cannot write reference cache {}", tmp);
  const std::uint64_t n = points.size();
  bool ok = std::fwrite(kMagic, 1, 8, f) == 8 && std::fwrite(&key, 8, 1, f) == 1 && std::fwrite(&n, 8, 1, f) == 1;
  for (std::size_t i = 0; ok && i < n; ++i) {
    const Record r = toRecord(points[i], estimates[i]);
    ok = std::fwrite(&r, sizeof(Record), 1, f) == 1;
  }
  ok = (std::fclose(f) == 0) && ok;
  std::error_code ec;
  if (ok) std::filesystem::rename(tmp, file, ec);
  if (!ok || ec) return ioError("cannot write reference cache {}", file);
  return {};
}

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

std::vector<ComparePoint> selectPoints(const precompute::Precomputation& p, int centres, int midpoints) {
  const auto& lm = p.lightmap;
  std::vector<std::uint32_t> valid;
  for (std::uint32_t c = 0; c < lm.size(); ++c)
    if (lm.valid[c]) valid.push_back(c);
  std::vector<ComparePoint> out;
  auto strided = [](std::size_t n, int want) {
    return want <= 0 ? n + 1 : std::max<std::size_t>(1, (n + want - 1) / std::size_t(want));
  };
  const std::size_t cs = strided(valid.size(), centres);
  for (std::size_t k = 0; k < valid.size(); k += cs)
    out.push_back({lm.position[valid[k]], lm.normal[valid[k]], valid[k], valid[k]});

  // Pairs (x, y) - (x + 1, y) of valid, unpushed caches of one mesh on one plane and at most
  // 3 texels apart: the midpoint is on the surface and bilinear lookup there averages them.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  const float max_gap = p.atlas.texel_size_m > 0.0f ? 3.0f * p.atlas.texel_size_m : 0.0f;
  for (std::uint32_t a : valid) {
    if (lm.pushed[a]) continue;
    const std::uint32_t t = lm.texel[a];
    if (int(t % std::uint32_t(lm.width)) + 1 >= lm.width) continue;
    const std::int32_t b = lm.cache_of_texel[t + 1];
    if (b < 0 || !lm.valid[b] || lm.pushed[b] || lm.mesh[b] != lm.mesh[a]) continue;
    if (glm::dot(lm.normal[a], lm.normal[b]) < 0.999f) continue;
    const glm::vec3 d = lm.position[b] - lm.position[a];
    const float len = glm::length(d);
    if (!(len > 0.0f) || std::abs(glm::dot(d, lm.normal[a])) > 1e-3f * len) continue;
    if (max_gap > 0.0f && len > max_gap) continue;
    pairs.emplace_back(a, std::uint32_t(b));
  }
  const std::size_t ms = strided(pairs.size(), midpoints);
  for (std::size_t k = 0; k < pairs.size(); k += ms) {
    const auto [a, b] = pairs[k];
    out.push_back({0.5f * (lm.position[a] + lm.position[b]), glm::normalize(lm.normal[a] + lm.normal[b]), a, b});
  }
  return out;
}

Expected<ReferenceSet> referenceFor(const scene::Scene& scene, const rt::Accel& accel,
                                    const relight::LightSet& lights, std::vector<ComparePoint> points,
                                    const std::string& key_text, const ReferenceSetOptions& options) {
  ReferenceSet set;
  set.points = std::move(points);
  const std::string full_key =
      fmt::format("{}|ref:target={},indirect={},min={},centres={},midpoints={},bounces={}", key_text,
                  options.target_rel_error, options.indirect_target, options.min_target, options.centres,
                  options.midpoints, options.max_bounces);
  const std::uint64_t key = artifact::hashBytes(full_key.data(), full_key.size());
  if (!options.cache_dir.empty()) {
    set.file = (std::filesystem::path(options.cache_dir) / fmt::format("ref_{:016x}.bin", key)).string();
    if (auto cached = readCache(set.file, key, set.points)) {
      set.estimates = std::move(*cached);
      set.from_disk = true;
      return set;
    }
  }

  const auto t0 = std::chrono::steady_clock::now();
  auto ref = reference::ReferenceRenderer::create(scene, accel, lights);
  if (!ref) return ref.status();
  std::vector<glm::vec3> pos, nrm;
  for (const auto& p : set.points) pos.push_back(p.position), nrm.push_back(p.normal);
  reference::ReferenceOptions ro;
  ro.target_rel_error = options.target_rel_error;
  ro.time_budget_s = options.time_budget_s;
  ro.max_bounces = options.max_bounces;
  auto est = ref->irradiance({pos, nrm}, ro);
  if (!est) return est.status();
  set.estimates = std::move(est).value();

  // Second pass: the stopping rule bounds the error of the total, and the indirect is only
  // part of it, so points whose indirect is still noisier than wanted are re-run with a
  // total target tightened by the factor they miss by (bucketed, so a few calls do it).
  double mean_ind = 0.0;
  for (const auto& e : set.estimates) mean_ind += reference::luminance(e.indirect);
  mean_ind /= std::max<std::size_t>(1, set.estimates.size());
  std::map<float, std::vector<std::size_t>, std::greater<float>> buckets;
  constexpr float kBuckets[] = {0.007f, 0.005f, 0.0035f, 0.0025f, 0.0018f};  // then min_target
  for (std::size_t i = 0; i < set.estimates.size(); ++i) {
    const auto& e = set.estimates[i];
    const float ind = reference::luminance(e.indirect), se = reference::luminance(e.std_error_indirect);
    const float peak = std::max({e.total.x, e.total.y, e.total.z});
    const float se_total = std::max({e.std_error_total.x, e.std_error_total.y, e.std_error_total.z});
    if (!(ind > 1e-3 * mean_ind) || !(peak > 0.0f) || se <= options.indirect_target * ind) continue;
    const float achieved = se_total / peak;  // the total's relative error the first pass reached
    const float wanted = 0.9f * achieved * options.indirect_target * ind / se;
    float pick = options.min_target;
    for (float b : kBuckets)
      if (b <= wanted && b >= options.min_target) {
        pick = b;
        break;
      }
    if (pick < options.target_rel_error) buckets[pick].push_back(i);
  }
  for (const auto& [target, idx] : buckets) {
    std::vector<glm::vec3> bp, bn;
    for (std::size_t i : idx) bp.push_back(pos[i]), bn.push_back(nrm[i]);
    reference::ReferenceOptions tight = ro;
    tight.target_rel_error = target;
    tight.seed = ro.seed + 1;  // independent of the first pass
    auto re = ref->irradiance({bp, bn}, tight);
    if (!re) return re.status();
    for (std::size_t k = 0; k < idx.size(); ++k) set.estimates[idx[k]] = (*re)[k];
  }
  set.seconds = secondsSince(t0);
  if (!set.file.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(options.cache_dir, ec);
    if (Status s = writeCache(set.file, key, set.points, set.estimates); !s) return s;
  }
  return set;
}

}  // namespace lightlink::bench
