#include "core/charts/unwrap.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <numeric>
#include <unordered_map>

#include <tbb/parallel_for.h>

#include "core/charts/flatten.h"
#include "core/charts/mesh_prep.h"
#include "core/charts/pack.h"
#include "core/charts/rasterize.h"
#include "core/charts/segment.h"

namespace lightlink::charts {
namespace {

bool finitePositive(float v) { return std::isfinite(v) && v > 0.0f; }

// A vertex of a generated mesh: the original vertex it copies, the chart it lies in and
// the prepared vertex it was parameterised as (one original vertex can be two prepared
// vertices of one chart when a non-manifold face was moved onto a copy).
struct NewVertexKey {
  std::uint32_t source, chart, prepared;
  bool operator==(const NewVertexKey&) const = default;
};
struct NewVertexHash {
  std::size_t operator()(const NewVertexKey& k) const {
    return static_cast<std::size_t>((static_cast<std::uint64_t>(k.source) * 0x9e3779b97f4a7c15ull) ^
                                    (static_cast<std::uint64_t>(k.chart) * 0xc2b2ae3d27d4eb4full) ^ k.prepared);
  }
};

// A segmented chart waiting to be flattened: its faces in one prepared mesh.
struct SegmentWork {
  std::uint32_t mesh;
  std::vector<std::uint32_t> faces;
};

// Searches the texel size for a fixed resolution: the smallest one (finest texels) whose
// packing fits. The packer reports the strip height it used; height goes roughly as a
// power of the texel size (-2 for pure area, flatter where gutters dominate), so each
// guess is a secant step in log-log space through the last two packs (the first assumes
// -2), kept inside the bracket of sizes known to fail and to fit. Stops once a packing
// fills 98 % of the height: a handful of packs where bisection needs a dozen. Returns 0
// if nothing fits.
double fitTexelSize(const std::vector<Chart>& charts, double area_m2, int resolution, int gutter,
                    std::vector<Placement>& placements, const Progress* progress) {
  const double limit = resolution - gutter;
  const double target = 0.99 * limit;
  std::vector<Placement> trial;
  double fit = 0.0, fail = 0.0;  // smallest size that fitted, largest that did not
  double prev_ts = 0.0, prev_used = 0.0;
  // First guess: the minimal boxes plus one texel of conservative border and the gutter
  // fill 80 % of the atlas, i.e. x = 1/texel solves sum (w x + c)(h x + c) = 0.8 R^2 with
  // c = 1 + gutter; gutters dominate small charts, which pure area would ignore.
  double a = 0.0, b = 0.0, c0 = 0.0;
  const double c = 1.0 + gutter;
  for (const Chart& chart : charts) {
    glm::dvec2 ext(0.0);
    for (const glm::dvec2& q : chart.uv) ext = glm::max(ext, q);
    a += ext.x * ext.y;
    b += (ext.x + ext.y) * c;
    c0 += c * c;
  }
  const double free_texels = 0.8 * resolution * resolution - c0;
  double ts = std::sqrt(area_m2 / (0.6 * resolution * resolution));
  if (free_texels > 0.0 && a > 0.0) ts = 2.0 * a / (-b + std::sqrt(b * b + 4.0 * a * free_texels));
  for (int iter = 0; iter < 80; ++iter) {
    if (stopRequested(progress)) return 0.0;
    // The texel size is a float in the scene's result: pack at exactly that value.
    ts = static_cast<double>(static_cast<float>(ts));
    const int used = packCharts(charts, ts, resolution, gutter, trial, progress);
    const bool fits = used >= 0 && used <= limit;
    if (fits && (fit == 0.0 || ts < fit)) {
      fit = ts;
      placements.swap(trial);
    }
    if (!fits) fail = std::max(fail, ts);
    if (fits && used >= 0.98 * limit) break;
    if (fit > 0.0 && fail > 0.0 && fit / fail < 1.002) break;
    double next;
    if (used < 0) {
      next = ts * 1.5;
    } else {
      double exponent = -2.0;
      if (prev_ts > 0.0 && prev_ts != ts && prev_used > 0.0 && prev_used != used) {
        const double k = std::log(used / prev_used) / std::log(ts / prev_ts);
        if (k < -0.25 && k > -8.0) exponent = k;
      }
      next = ts * std::pow(target / used, 1.0 / exponent);
      prev_ts = ts;
      prev_used = used;
    }
    if (fit > 0.0 && next >= fit) next = fail > 0.0 ? std::sqrt(fail * fit) : fit * 0.98;
    if (fail > 0.0 && next <= fail) next = fit > 0.0 ? std::sqrt(fail * fit) : fail * 1.25;
    ts = next;
  }
  return fit;
}

double signedUvArea(const glm::vec2& a, const glm::vec2& b, const glm::vec2& c) {
  return 0.5 * (static_cast<double>(b.x - a.x) * (c.y - a.y) - static_cast<double>(b.y - a.y) * (c.x - a.x));
}

// Existing uv1 as atlas triangles at `resolution`, each triangle's chart its uv island:
// triangles joined by a shared vertex or by vertices at bitwise-equal uv1 within a mesh
// (a layout split for normals is still one island). Islands of different meshes differ.
AtlasTriangles existingTriangles(const scene::Scene& scene, const std::vector<std::uint32_t>& statics,
                                 int resolution) {
  AtlasTriangles tris;
  for (std::uint32_t m : statics) {
    const scene::MeshInstance& mesh = scene.meshes[m];
    std::vector<std::uint32_t> parent(mesh.uv1.size());
    std::iota(parent.begin(), parent.end(), 0u);
    const auto find = [&](std::uint32_t v) {
      while (parent[v] != v) v = parent[v] = parent[parent[v]];
      return v;
    };
    const auto join = [&](std::uint32_t a, std::uint32_t b) {
      a = find(a), b = find(b);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    };
    std::unordered_map<std::uint64_t, std::uint32_t> first_at;
    for (std::uint32_t v = 0; v < mesh.uv1.size(); ++v) {
      std::uint32_t bits[2];
      std::memcpy(bits, &mesh.uv1[v], sizeof bits);
      const auto [it, inserted] = first_at.try_emplace((std::uint64_t(bits[0]) << 32) | bits[1], v);
      if (!inserted) join(it->second, v);
    }
    for (std::size_t t = 0; t < mesh.triangleCount(); ++t) {
      join(mesh.indices[3 * t], mesh.indices[3 * t + 1]);
      join(mesh.indices[3 * t], mesh.indices[3 * t + 2]);
    }
    std::unordered_map<std::uint32_t, std::uint32_t> island;
    for (std::size_t t = 0; t < mesh.triangleCount(); ++t) {
      const auto [it, inserted] = island.try_emplace(find(mesh.indices[3 * t]), tris.chart_count);
      if (inserted) ++tris.chart_count;
      tris.chart.push_back(it->second);
      for (int k = 0; k < 3; ++k)
        tris.texels.emplace_back(glm::dvec2(mesh.uv1[mesh.indices[3 * t + k]]) * static_cast<double>(resolution));
    }
  }
  return tris;
}

AtlasTriangles rescaled(AtlasTriangles tris, double factor) {
  for (glm::dvec2& q : tris.texels) q *= factor;
  return tris;
}

// The resolution an existing layout was packed for: the smallest power of two from 64 to
// 4096 (within `max_texels`) at which its islands neither overlap nor come within `gutter`
// texels of each other. 0 when none does: triangles that overlap (a texel centre in two),
// which no resolution separates, end the search at once.
int packedResolution(const AtlasTriangles& unit_tris, int gutter, std::uint64_t max_texels) {
  for (int r = 64; r <= 4096; r *= 2) {
    if (max_texels != 0 && std::uint64_t(r) * std::uint64_t(r) > max_texels) break;
    const AtlasCheck check = checkAtlas(rescaled(unit_tris, r), r, r, gutter);
    if (check.triangle_overlap_texels > 0) return 0;
    if (check.chart_overlap_texels == 0 && check.gutter_violations == 0) return r;
  }
  return 0;
}

// Existing uv1: checked at `resolution`, never modified.
void checkExisting(const scene::Scene& scene, const std::vector<std::uint32_t>& statics, int resolution,
                   UnwrapReport& report) {
  double surface_m2 = 0.0, uv_texels = 0.0;
  for (std::uint32_t m : statics) {
    const scene::MeshInstance& mesh = scene.meshes[m];
    std::size_t out_of_range = 0, positive = 0, negative = 0;
    for (const glm::vec2& t : mesh.uv1)
      out_of_range += !(t.x >= 0.0f && t.x <= 1.0f && t.y >= 0.0f && t.y <= 1.0f);
    for (std::size_t t = 0; t < mesh.triangleCount(); ++t) {
      const glm::vec2 a = mesh.uv1[mesh.indices[3 * t]], b = mesh.uv1[mesh.indices[3 * t + 1]],
                      c = mesh.uv1[mesh.indices[3 * t + 2]];
      const double area = signedUvArea(a, b, c);
      positive += area > 0.0;
      negative += area < 0.0;
      uv_texels += std::abs(area) * resolution * resolution;
      const glm::dvec3 p0(mesh.positions[mesh.indices[3 * t]]), p1(mesh.positions[mesh.indices[3 * t + 1]]),
          p2(mesh.positions[mesh.indices[3 * t + 2]]);
      surface_m2 += 0.5 * glm::length(glm::cross(p1 - p0, p2 - p0));
    }
    // Mirrored uv1 is legitimate; triangles against the mesh's majority, or of zero area, are not.
    const std::size_t flipped = mesh.triangleCount() - std::max(positive, negative);
    report.flipped += flipped;
    report.out_of_range += out_of_range;
    if (out_of_range > 0)
      report.warnings.push_back(fmt::format("mesh '{}': {} TEXCOORD_1 values outside [0,1]", mesh.name, out_of_range));
    if (flipped > 0)
      report.warnings.push_back(fmt::format("mesh '{}': {} TEXCOORD_1 triangles flipped or of zero area", mesh.name, flipped));
    report.triangles += mesh.triangleCount();
  }
  // Mean metres per texel of the existing layout, for the precompute's spacing.
  report.texel_size_m = uv_texels > 0.0 ? static_cast<float>(std::sqrt(surface_m2 / uv_texels)) : 0.0f;
  const AtlasCheck check = checkAtlas(existingTriangles(scene, statics, resolution), resolution, resolution, 0);
  report.overlaps = check.triangle_overlap_texels + check.chart_overlap_texels;
  report.charts = static_cast<int>(check.chart_texels.size());
  report.utilisation = static_cast<double>(check.center_texels) / (static_cast<double>(resolution) * resolution);
  if (report.overlaps > 0)
    report.warnings.push_back(fmt::format(
        "existing TEXCOORD_1: {} texels at {}x{} lie in two or more uv islands or triangles (overlapping lightmap uv)",
        report.overlaps, resolution, resolution));
}

}  // namespace

Status validate(const UnwrapOptions& o) {
  if (o.texel_size_m && !finitePositive(*o.texel_size_m))
    return invalidInput("unwrap: texel size must be > 0 metres, got {}", *o.texel_size_m);
  if (o.resolution && (*o.resolution < 1 || *o.resolution > kMaxAtlasResolution))
    return invalidInput("unwrap: resolution must be in [1, {}] texels, got {}", kMaxAtlasResolution, *o.resolution);
  if (o.target_resolution < 1 || o.target_resolution > kMaxAtlasResolution)
    return invalidInput("unwrap: target resolution must be in [1, {}] texels, got {}", kMaxAtlasResolution,
                        o.target_resolution);
  if (o.max_atlas < 16 || o.max_atlas > kMaxAtlasResolution)
    return invalidInput("unwrap: --max-atlas must be in [16, {}] texels, got {}", kMaxAtlasResolution, o.max_atlas);
  if (o.max_pages < 0 || o.max_pages > 1024)
    return invalidInput("unwrap: --max-pages must be in [0, 1024] (0 = as many as needed), got {}", o.max_pages);
  if (o.texel_budget > (std::uint64_t(1) << 32))
    return invalidInput("unwrap: texel budget {} is above 2^32", o.texel_budget);
  if (o.gutter_texels < 0 || o.gutter_texels > 64)
    return invalidInput("unwrap: gutter must be in [0, 64] texels, got {}", o.gutter_texels);
  if (!(o.normal_cone_deg > 0.0f && o.normal_cone_deg < 90.0f))
    return invalidInput("unwrap: normal cone must be in (0, 90) degrees, got {}", o.normal_cone_deg);
  if (!(o.hard_edge_deg > 0.0f && o.hard_edge_deg <= 180.0f))
    return invalidInput("unwrap: hard edge angle must be in (0, 180] degrees, got {}", o.hard_edge_deg);
  if (!(o.planar_deg >= 0.0f && o.planar_deg < 90.0f))
    return invalidInput("unwrap: planar angle must be in [0, 90) degrees, got {}", o.planar_deg);
  if (!(o.max_stretch > 1.0f) || !std::isfinite(o.max_stretch))
    return invalidInput("unwrap: max stretch must be a finite number > 1, got {}", o.max_stretch);
  if (!(o.min_chart_fill >= 0.0f && o.min_chart_fill < 1.0f))
    return invalidInput("unwrap: min chart fill must be in [0, 1), got {}", o.min_chart_fill);
  if (!(o.weld_tolerance >= 0.0f && o.weld_tolerance < 0.01f))
    return invalidInput("unwrap: weld tolerance must be in [0, 0.01) of the scene size, got {}", o.weld_tolerance);
  return Status::ok();
}

double texelSizeForBudget(double area_sum, double perimeter_sum, std::size_t charts, std::uint64_t budget) {
  const double n = static_cast<double>(charts);
  const double room = std::max(static_cast<double>(budget), 2.0 * n) - n;
  if (!(area_sum > 0.0) || !(room > 0.0)) return 0.0;
  const double x = (-perimeter_sum + std::sqrt(perimeter_sum * perimeter_sum + 4.0 * area_sum * room)) /
                   (2.0 * area_sum);
  return x > 0.0 ? 1.0 / x : 0.0;
}

Expected<UnwrapResult> unwrap(scene::Scene& scene, const UnwrapOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  if (Status s = validate(options); !s) return s;

  UnwrapResult result;
  UnwrapReport& report = result.report;
  LightmapAtlas& atlas = result.atlas;
  atlas.meshes.resize(scene.meshes.size());
  atlas.gutter_texels = options.gutter_texels;
  report.gutter_texels = options.gutter_texels;

  std::vector<std::uint32_t> statics;
  std::size_t with_uv1 = 0;
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    scene::MeshInstance& mesh = scene.meshes[m];
    if (!mesh.is_static || mesh.triangleCount() == 0) continue;
    if (mesh.probe_lit) {  // flagged in the scene: never in the atlas
      mesh.uv1.clear();
      atlas.probe_lit.push_back(static_cast<std::uint32_t>(m));
      continue;
    }
    statics.push_back(static_cast<std::uint32_t>(m));
    with_uv1 += mesh.hasLightmapUv();
  }
  report.meshes = static_cast<int>(statics.size());
  if (statics.empty())
    return invalidInput("unwrap: '{}' has no static triangle meshes{}", scene.source_path,
                        atlas.probe_lit.empty() ? "" : " that are lightmapped (all are marked lightmap: false)");

  const Progress* progress = options.progress;
  const auto stopped = [&] { return cancelled("unwrap: cancelled"); };
  // An atlas of res x res texels costs memory in every later stage (per-texel arrays,
  // caches, links): refused before packing when over the budget.
  const auto overBudget = [&](int res) -> Status {
    const std::uint64_t texels = std::uint64_t(res) * std::uint64_t(res);
    if (options.max_texels == 0 || texels <= options.max_texels) return {};
    return resourceExhausted("lightmap: {}x{} = {} texels is above the limit of {} texels (max_texels); lower the "
                             "resolution or raise the texel size",
                             res, res, texels, options.max_texels);
  };

  auto finish = [&]() {
    report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return Expected<UnwrapResult>(std::move(result));
  };

  if (options.resolution || (!options.texel_size_m && options.texel_budget == 0))
    if (Status s = overBudget(options.resolution.value_or(options.target_resolution)); !s) return s;
  if (options.uv_mode != UvMode::kGenerate && with_uv1 == statics.size()) {
    int res = options.resolution.value_or(0);
    if (res == 0) {
      res = packedResolution(existingTriangles(scene, statics, 1), options.gutter_texels, options.max_texels);
      if (res == 0) res = std::max(options.max_atlas, 64);  // islands touch at every size: checked below
    }
    UnwrapReport kept;
    kept.gutter_texels = options.gutter_texels;
    kept.meshes = report.meshes;
    checkExisting(scene, statics, res, kept);
    const bool broken = kept.overlaps > 0 || kept.out_of_range > 0;
    if (options.uv_mode == UvMode::kKeep || !broken) {
      report = std::move(kept);
      atlas.generated = false;
      atlas.resolution = res;
      report.resolution = res;
      for (std::uint32_t m : statics)
        atlas.meshes[m].triangle_chart.assign(scene.meshes[m].triangleCount(), kNoChart);
      atlas.texel_size_m = report.texel_size_m;
      return finish();
    }
    report.warnings.push_back(fmt::format(
        "existing TEXCOORD_1 regenerated: {} overlapping texels at {}x{}, {} values outside [0,1] (--uv keep keeps it)",
        kept.overlaps, res, res, kept.out_of_range));
  } else if (with_uv1 > 0) {
    for (std::uint32_t m : statics) {
      if (!scene.meshes[m].hasLightmapUv()) continue;
      report.warnings.push_back(
          options.uv_mode == UvMode::kGenerate
              ? fmt::format("mesh '{}': existing TEXCOORD_1 replaced (--uv generate)", scene.meshes[m].name)
              : fmt::format("mesh '{}': existing TEXCOORD_1 replaced ({} of {} static meshes have none; one atlas is "
                            "generated for all)",
                            scene.meshes[m].name, statics.size() - with_uv1, statics.size()));
    }
  }
  // 1-2. Prepare and segment each static mesh (independent: parallel over meshes).
  const double weld_m = static_cast<double>(options.weld_tolerance) * scene.scale;
  std::vector<PreparedMesh> prepared(statics.size());
  std::vector<Segmentation> segments(statics.size());
  SegmentOptions seg_options;
  seg_options.normal_cone_deg = options.normal_cone_deg;
  seg_options.hard_edge_deg = options.hard_edge_deg;
  tbb::parallel_for(std::size_t{0}, statics.size(), [&](std::size_t i) {
    if (stopRequested(progress)) return;
    prepared[i] = prepareMesh(scene.meshes[statics[i]], weld_m);
    segments[i] = segmentCharts(prepared[i], seg_options);
  });
  if (stopRequested(progress)) return stopped();

  // 3. Flatten every segmented chart (parallel over charts, results kept in chart order).
  std::vector<SegmentWork> work;
  for (std::size_t i = 0; i < statics.size(); ++i) {
    report.degenerate_removed += prepared[i].degenerate_removed;
    report.nonmanifold_split += prepared[i].nonmanifold_split;
    const std::size_t first = work.size();
    work.resize(first + segments[i].chart_count);
    for (std::size_t c = first; c < work.size(); ++c) work[c].mesh = static_cast<std::uint32_t>(i);
    for (std::size_t f = 0; f < segments[i].face_chart.size(); ++f)
      work[first + segments[i].face_chart[f]].faces.push_back(static_cast<std::uint32_t>(f));
  }
  FlattenOptions flat_options;
  flat_options.planar_deg = options.planar_deg;
  flat_options.max_area_stretch = options.max_stretch;
  flat_options.min_box_fill = options.min_chart_fill;
  std::vector<std::vector<Chart>> flattened(work.size());
  std::vector<FlattenStats> flat_stats(work.size());
  tbb::parallel_for(std::size_t{0}, work.size(), [&](std::size_t w) {
    if (stopRequested(progress)) return;
    flattenChart(prepared[work[w].mesh], std::move(work[w].faces), work[w].mesh, flat_options, flattened[w],
                 flat_stats[w]);
    for (Chart& c : flattened[w]) alignToMinimalBox(c);
  });
  std::vector<Chart> charts;
  for (std::size_t w = 0; w < work.size(); ++w) {
    report.planar_charts += flat_stats[w].planar;
    report.lscm_charts += flat_stats[w].lscm;
    report.chart_splits += flat_stats[w].splits;
    for (Chart& c : flattened[w]) charts.push_back(std::move(c));
  }
  flattened.clear();
  if (stopRequested(progress)) return stopped();

  // 4. Texel size, probe-lit objects, page size and pages, then pack.
  const int gutter = options.gutter_texels;
  // Per chart: texels per metre relative to the atlas's texel size (the mesh's
  // lightmap_scale, times the scale-down of a chart larger than a page).
  std::vector<double> chart_density(charts.size(), 1.0);
  for (std::size_t c = 0; c < charts.size(); ++c) {
    const double k = scene.meshes[statics[charts[c].mesh]].lightmap_scale;
    if (!(k > 0.0) || k == 1.0) continue;
    for (glm::dvec2& q : charts[c].uv) q *= k;
    chart_density[c] = k;
  }
  std::vector<glm::dvec2> extent(charts.size(), glm::dvec2(0.0));
  double area_m2 = 0.0, scaled_area = 0.0, perimeter = 0.0;
  for (std::size_t c = 0; c < charts.size(); ++c) {
    for (const glm::dvec2& q : charts[c].uv) extent[c] = glm::max(extent[c], q);
    area_m2 += charts[c].area_m2;
    scaled_area += charts[c].area_m2 * chart_density[c] * chart_density[c];
    perimeter += extent[c].x + extent[c].y;
  }
  std::vector<Placement> placements;
  int res = 0, pages = 1;
  double texel_m = 0.0;
  std::vector<char> mesh_probe_lit(statics.size(), 0);
  if (options.texel_size_m || options.texel_budget > 0) {
    texel_m = options.texel_size_m ? double(*options.texel_size_m)
                                   : texelSizeForBudget(scaled_area, perimeter, charts.size(), options.texel_budget);
    texel_m = static_cast<double>(static_cast<float>(texel_m));  // the float the atlas reports
    if (!(texel_m > 0.0) || !std::isfinite(texel_m))
      return invalidInput("unwrap: '{}' has no chart area to lay out", scene.source_path);
    // Objects too small for the lightmap: every chart of the mesh under 2 texels a side.
    if (options.probe_lit_small) {
      std::vector<char> big(statics.size(), 0);
      for (std::size_t c = 0; c < charts.size(); ++c)
        if (std::max(extent[c].x, extent[c].y) >= 2.0 * texel_m) big[charts[c].mesh] = 1;
      std::size_t kept = 0;
      for (std::size_t i = 0; i < statics.size(); ++i) kept += big[i];
      if (kept > 0)  // an atlas needs one mesh: a scene of only tiny objects keeps them all
        for (std::size_t i = 0; i < statics.size(); ++i) mesh_probe_lit[i] = !big[i];
    }
    if (std::count(mesh_probe_lit.begin(), mesh_probe_lit.end(), 1) > 0) {
      std::vector<Chart> kept;
      std::vector<double> kept_density;
      std::vector<glm::dvec2> kept_extent;
      area_m2 = 0.0;
      for (std::size_t c = 0; c < charts.size(); ++c) {
        if (mesh_probe_lit[charts[c].mesh]) continue;
        area_m2 += charts[c].area_m2;
        kept.push_back(std::move(charts[c]));
        kept_density.push_back(chart_density[c]);
        kept_extent.push_back(extent[c]);
      }
      charts = std::move(kept);
      chart_density = std::move(kept_density);
      extent = std::move(kept_extent);
      for (std::size_t i = 0; i < statics.size(); ++i)
        if (mesh_probe_lit[i]) atlas.probe_lit.push_back(statics[i]);
      std::sort(atlas.probe_lit.begin(), atlas.probe_lit.end());
    }
    // The charts alone need area / texel^2 texels: a tiny texel size is refused here, before
    // any packing or scaling down, rather than searched for pages that cannot exist.
    double needed = 0.0;
    for (std::size_t c = 0; c < charts.size(); ++c)
      needed += charts[c].area_m2 * chart_density[c] * chart_density[c] / (texel_m * texel_m);
    const double limit = options.max_texels ? double(options.max_texels)
                                            : double(kMaxAtlasResolution) * double(kMaxAtlasResolution);
    if (!(needed <= limit))
      return (options.max_texels ? resourceExhausted("lightmap: a texel size of {} m needs at least {:.3g} texels for "
                                                     "{:.4g} m^2 of charts, above the limit of {} texels (max_texels); "
                                                     "raise the texel size",
                                                     texel_m, needed, area_m2, options.max_texels)
                                 : invalidInput("unwrap: {} charts at {} m/texel need at least {:.3g} texels, more than "
                                                "the {} texels the largest atlas holds; raise the texel size",
                                                charts.size(), texel_m, needed, limit));
    const int page = options.resolution.value_or(options.max_atlas);
    // A chart larger than a page is scaled down to fit one: its texels are coarser, never
    // "cannot fit". Named per mesh so a user can split the mesh or raise --max-atlas.
    const double max_side = double(page - 2 * gutter - 2) * texel_m;
    if (!(max_side > 0.0))
      return invalidInput("unwrap: a {}-texel page with a {}-texel gutter has no room for a chart", page, gutter);
    std::vector<std::size_t> shrunk(statics.size(), 0);
    std::vector<double> coarsest(statics.size(), 0.0);
    for (std::size_t c = 0; c < charts.size(); ++c) {
      const double side = std::max(extent[c].x, extent[c].y);
      if (side <= max_side) continue;
      const double f = max_side / side;
      for (glm::dvec2& q : charts[c].uv) q *= f;
      extent[c] *= f;
      chart_density[c] *= f;
      ++shrunk[charts[c].mesh];
      coarsest[charts[c].mesh] = std::max(coarsest[charts[c].mesh], texel_m / chart_density[c]);
    }
    for (std::size_t i = 0; i < statics.size(); ++i)
      if (shrunk[i] > 0)
        report.warnings.push_back(fmt::format(
            "mesh '{}': {} chart(s) larger than a {}x{} page at {:.4g} m/texel were scaled down to fit (texels up to "
            "{:.4g} m there); raise --max-atlas or split the mesh",
            scene.meshes[statics[i]].name, shrunk[i], page, page, texel_m, coarsest[i]));
    // One page when one fits: the smallest power of two (or the given resolution) that
    // holds every chart; else as many pages of the page size as needed.
    if (!options.resolution) {
      for (int r = 16; r <= page && res == 0; r *= 2) {
        if (double(r) * r < needed) continue;
        if (const int used = packCharts(charts, texel_m, r, gutter, placements, progress); used >= 0 && used <= r - gutter)
          res = r;
        if (stopRequested(progress)) return stopped();
      }
    } else if (const int used = packCharts(charts, texel_m, page, gutter, placements, progress);
               used >= 0 && used <= page - gutter) {
      res = page;
    }
    if (stopRequested(progress)) return stopped();
    if (res == 0) {
      res = page;
      const double asked = texel_m;
      for (int attempt = 0;; ++attempt) {
        pages = packChartsPaged(charts, texel_m, page, gutter, placements, progress);
        if (stopRequested(progress)) return stopped();
        if (pages < 0) return internalError("unwrap: a chart scaled to fit a {}x{} page did not fit one", page, page);
        if (options.max_pages == 0 || pages <= options.max_pages) break;
        if (attempt == 16)
          return invalidInput("unwrap: {} charts do not fit {} page(s) of {}x{} even at {:.4g} m/texel; raise "
                              "--max-pages or --max-atlas",
                              charts.size(), options.max_pages, page, page, texel_m);
        // Fewer pages: coarser texels, by the square root of the page ratio and a little more.
        texel_m = static_cast<float>(texel_m * std::sqrt(double(pages) / double(options.max_pages)) * 1.02);
      }
      if (texel_m != asked)
        report.warnings.push_back(fmt::format("texel size raised from {:.4g} to {:.4g} m to fit --max-pages {}", asked,
                                              texel_m, options.max_pages));
    }
    if (std::uint64_t(res) * std::uint64_t(pages) > std::uint64_t(kMaxAtlasResolution))
      return invalidInput("unwrap: {} charts at {} m/texel need {} pages of {}x{}, more than the {} rows an atlas may "
                          "have; raise the texel size or --max-atlas",
                          charts.size(), texel_m, pages, res, res, kMaxAtlasResolution);
    if (options.max_texels != 0 && std::uint64_t(res) * res * std::uint64_t(pages) > options.max_texels)
      return resourceExhausted("lightmap: {} pages of {}x{} = {} texels are above the limit of {} texels (max_texels); "
                               "raise the texel size",
                               pages, res, res, std::uint64_t(res) * res * std::uint64_t(pages), options.max_texels);
  } else {
    res = options.resolution.value_or(options.target_resolution);
    texel_m = fitTexelSize(charts, scaled_area, res, gutter, placements, progress);
    if (stopRequested(progress)) return stopped();
    if (texel_m == 0.0)
      return invalidInput("unwrap: {} charts with a {}-texel gutter cannot fit into {}x{} texels at any texel size; "
                          "raise the resolution or lower the gutter", charts.size(), gutter, res, res);
  }
  atlas.generated = report.generated = true;
  atlas.resolution = report.resolution = res;
  atlas.pages = report.pages = pages;
  atlas.texel_size_m = report.texel_size_m = static_cast<float>(texel_m);
  atlas.chart_count = static_cast<std::uint32_t>(charts.size());
  report.charts = static_cast<int>(charts.size());
  report.probe_lit_meshes = atlas.probe_lit.size();
  for (std::uint32_t m : atlas.probe_lit) {
    report.probe_lit.push_back(scene.meshes[m].name);
    scene.meshes[m].probe_lit = true;
    scene.meshes[m].uv1.clear();
    atlas.meshes[m].triangle_chart.assign(scene.meshes[m].triangleCount(), kNoChart);
  }
  tbb::parallel_for(std::size_t{0}, charts.size(),
                    [&](std::size_t c) { applyPlacement(charts[c], placements[c], texel_m); });

  // 5. Rewrite the meshes with seam-split vertices and uv1, one new vertex per NewVertexKey.
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> face_ref(statics.size());  // (chart, index in chart)
  for (std::size_t i = 0; i < statics.size(); ++i)
    if (!mesh_probe_lit[i]) face_ref[i].resize(prepared[i].faceCount());
  for (std::size_t c = 0; c < charts.size(); ++c) {
    const Chart& chart = charts[c];
    for (std::size_t fi = 0; fi < chart.faces.size(); ++fi)
      face_ref[chart.mesh][chart.faces[fi]] = {static_cast<std::uint32_t>(c), static_cast<std::uint32_t>(fi)};
  }
  const glm::dvec2 inv_size(1.0 / res, 1.0 / (double(res) * pages));
  if (stopRequested(progress)) return stopped();
  tbb::parallel_for(std::size_t{0}, statics.size(), [&](std::size_t i) {
    if (mesh_probe_lit[i]) return;
    scene::MeshInstance& mesh = scene.meshes[statics[i]];
    MeshLightmap& lm = atlas.meshes[statics[i]];
    const PreparedMesh& pm = prepared[i];
    std::vector<glm::vec3> positions, normals;
    std::vector<glm::vec2> uv0, uv1;
    std::vector<std::uint32_t> indices;
    std::unordered_map<NewVertexKey, std::uint32_t, NewVertexHash> vertex_of;
    vertex_of.reserve(mesh.positions.size() * 2);
    indices.reserve(pm.faceCount() * 3);
    lm.triangle_chart.reserve(pm.faceCount());
    for (std::size_t f = 0; f < pm.faceCount(); ++f) {
      const auto [c, fi] = face_ref[i][f];
      const Chart& chart = charts[c];
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t src = mesh.indices[3 * pm.source_face[f] + k];
        const NewVertexKey key{src, c, pm.corners[3 * f + k]};
        auto [it, inserted] = vertex_of.try_emplace(key, static_cast<std::uint32_t>(positions.size()));
        if (inserted) {
          positions.push_back(mesh.positions[src]);
          if (!mesh.normals.empty()) normals.push_back(mesh.normals[src]);
          if (!mesh.uv0.empty()) uv0.push_back(mesh.uv0[src]);
          uv1.emplace_back(chart.uv[chart.local_corners[3 * fi + k]] * inv_size);
          lm.source_vertex.push_back(src);
        }
        indices.push_back(it->second);
      }
      lm.triangle_chart.push_back(c);
    }
    mesh.positions = std::move(positions);
    mesh.normals = std::move(normals);
    mesh.uv0 = std::move(uv0);
    mesh.uv1 = std::move(uv1);
    mesh.indices = std::move(indices);
  });

  // 6. Measure what an engine will sample: the float uv1 on the meshes.
  AtlasTriangles tris;
  tris.chart_count = atlas.chart_count;
  double weight = 0.0, sum_stretch = 0.0, sum_angle = 0.0;
  report.max_area_stretch = report.max_angle_distortion = 1.0;
  const double texels_per_m2 = 1.0 / (texel_m * texel_m);
  const glm::dvec2 size(res, double(res) * pages);
  for (std::uint32_t m : statics) {
    const scene::MeshInstance& mesh = scene.meshes[m];
    if (mesh.probe_lit) continue;
    report.triangles += mesh.triangleCount();
    for (std::size_t t = 0; t < mesh.triangleCount(); ++t) {
      glm::dvec3 p[3];
      glm::dvec2 q[3];
      for (int k = 0; k < 3; ++k) {
        p[k] = glm::dvec3(mesh.positions[mesh.indices[3 * t + k]]);
        q[k] = glm::dvec2(mesh.uv1[mesh.indices[3 * t + k]]) * size;
        tris.texels.push_back(q[k]);
      }
      const std::uint32_t chart = atlas.meshes[m].triangle_chart[t];
      tris.chart.push_back(chart);
      // Stretch against the density the chart was laid out at (lightmap_scale, scale-down).
      const double density = chart_density[chart];
      const TriangleDistortion d =
          triangleDistortion(p[0], p[1], p[2], q[0], q[1], q[2], texels_per_m2 * density * density);
      if (!(d.signed_area_ratio > 0.0)) {
        ++report.flipped;
        continue;
      }
      const double area = 0.5 * glm::length(glm::cross(p[1] - p[0], p[2] - p[0]));
      report.max_area_stretch = std::max(report.max_area_stretch, d.area_stretch);
      report.max_angle_distortion = std::max(report.max_angle_distortion, d.angle_distortion);
      sum_stretch += area * d.area_stretch;
      sum_angle += area * d.angle_distortion;
      weight += area;
    }
  }
  if (weight > 0.0) {
    report.mean_area_stretch = sum_stretch / weight;
    report.mean_angle_distortion = sum_angle / weight;
  }
  const AtlasCheck check = checkAtlas(tris, res, res * pages, gutter);
  report.overlaps = check.chart_overlap_texels + check.triangle_overlap_texels;
  report.gutter_violations = check.gutter_violations;
  report.utilisation = static_cast<double>(check.covered_texels) / (static_cast<double>(res) * res * pages);
  std::vector<std::size_t> texels = check.chart_texels;
  std::sort(texels.begin(), texels.end());
  if (!texels.empty()) {
    report.texels_per_chart_min = texels.front();
    report.texels_per_chart_median = texels[texels.size() / 2];
    report.texels_per_chart_max = texels.back();
  }
  if (report.overlaps > 0 || report.gutter_violations > 0 || report.flipped > 0)
    report.warnings.push_back(fmt::format("generated atlas: {} overlapping texels, {} gutter violations, {} flipped "
                                          "triangles after float rounding",
                                          report.overlaps, report.gutter_violations, report.flipped));
  return finish();
}

}  // namespace lightlink::charts
