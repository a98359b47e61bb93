#include "core/precompute/precompute.h"

#include <chrono>
#include <cmath>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "core/rt/accel.h"

namespace lightlink::precompute {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

template <typename T>
std::size_t bytesOf(const std::vector<T>& v) {
  return v.size() * sizeof(T);
}

// The one list of the small arrays an artifact holds (copied on load), by section name.
// Works on const (save) and mutable (load) precomputations alike.
template <typename P, typename V>
void visitSmallArrays(P& p, V&& v) {
  v("surfel.position", p.surfels.position);
  v("surfel.normal", p.surfels.normal);
  v("surfel.area", p.surfels.area);
  v("surfel.albedo", p.surfels.albedo);
  v("surfel.emission", p.surfels.emission);
  v("surfel.lightmap_uv", p.surfels.lightmap_uv);
  v("surfel.mesh", p.surfels.mesh);
  v("surfel.triangle", p.surfels.triangle);
  v("surfel.barycentric", p.surfels.barycentric);
  v("tree.left", p.tree.left);
  v("tree.right", p.tree.right);
  v("tree.parent", p.tree.parent);
  v("tree.begin", p.tree.begin);
  v("tree.end", p.tree.end);
  v("tree.depth", p.tree.depth);
  v("tree.area", p.tree.area);
  v("tree.bounds_min", p.tree.bounds_min);
  v("tree.bounds_max", p.tree.bounds_max);
  v("tree.centroid", p.tree.centroid);
  v("tree.mean_normal", p.tree.mean_normal);
  v("tree.level_begin", p.tree.level_begin);
  v("tree.leaf_of_surfel", p.tree.leaf_of_surfel);
  v("tree.original_index", p.tree.original_index);
  v("lm.position", p.lightmap.position);
  v("lm.normal", p.lightmap.normal);
  v("lm.texel", p.lightmap.texel);
  v("lm.mesh", p.lightmap.mesh);
  v("lm.triangle", p.lightmap.triangle);
  v("lm.valid", p.lightmap.valid);
  v("lm.pushed", p.lightmap.pushed);
  v("lm.cache_of_texel", p.lightmap.cache_of_texel);
  v("grid.position", p.grid.position);
  v("grid.valid", p.grid.valid);
  for (auto* plan : {&p.lightmap_fill, &p.grid_fill, &p.dilation}) {
    const char* prefix = plan == &p.lightmap_fill ? "lmfill" : plan == &p.grid_fill ? "gridfill" : "dilate";
    v(fmt::format("{}.target", prefix), plan->target);
    v(fmt::format("{}.begin", prefix), plan->source_begin);
    v(fmt::format("{}.source", prefix), plan->source);
  }
}

// The big link arrays, by section name (zero-copy on load).
template <typename L, typename V>
void visitLinkArrays(const char* prefix, L& links, V&& v) {
  v(fmt::format("{}.offsets", prefix), links.offsets);
  v(fmt::format("{}.node", prefix), links.node);
  v(fmt::format("{}.coeffs", prefix), links.coeffs);
  v(fmt::format("{}.direction", prefix), links.direction);
  v(fmt::format("{}.solid_angle", prefix), links.solid_angle);
  v(fmt::format("{}.sky", prefix), links.sky);
}

nlohmann::ordered_json linkStatsJson(const links::Links& l) {
  nlohmann::ordered_json j;
  j["caches"] = l.cacheCount();
  j["links"] = l.linkCount();
  j["mean_links_per_cache"] = l.cacheCount() ? double(l.linkCount()) / double(l.cacheCount()) : 0.0;
  j["rays"] = l.stats.rays;
  j["front_hits"] = l.stats.front_hits;
  j["back_hits"] = l.stats.back_hits;
  j["escaped"] = l.stats.escaped;
  j["unowned"] = l.stats.unowned;
  j["seconds"] = l.stats.seconds;
  j["rays_per_second"] = l.stats.seconds > 0 ? double(l.stats.rays) / l.stats.seconds : 0.0;
  j["bytes_per_link_projected"] = l.bytesPerLinkProjected();
  j["bytes_per_link_runtime"] = links::Links::bytesPerLinkRuntime();
  return j;
}

}  // namespace

Status PrecomputeOptions::validate() const {
  if (surfels < 1 || surfels > (1u << 24)) return invalidInput("--surfels {} is out of range (1..16777216)", surfels);
  if (links < 1 || links > 65536) return invalidInput("--links {} is out of range (1..65536)", links);
  if (bands < 1 || bands > 4) return invalidInput("--bands {} is out of range (1..4)", bands);
  if (rays < 1 || rays > (1 << 20)) return invalidInput("--rays {} is out of range (1..1048576)", rays);
  if (!(grid_spacing_m >= 0.0f) || !std::isfinite(grid_spacing_m))
    return invalidInput("--grid-spacing {} must be a finite number >= 0 (0 = derive)", grid_spacing_m);
  if (grid_resolution < 2 || grid_resolution > 1024)
    return invalidInput("grid resolution {} is out of range (2..1024)", grid_resolution);
  if (texel_size_m && !(*texel_size_m > 0.0f && std::isfinite(*texel_size_m)))
    return invalidInput("--texel-size {} must be a finite number > 0", *texel_size_m);
  if (lightmap_resolution && (*lightmap_resolution < 1 || *lightmap_resolution > charts::kMaxAtlasResolution))
    return invalidInput("lightmap resolution {} is out of range (1..{})", *lightmap_resolution,
                        charts::kMaxAtlasResolution);
  if (validity_rays < 1 || validity_rays > 65536)
    return invalidInput("validity rays {} is out of range (1..65536)", validity_rays);
  return {};
}

Expected<PrecomputeOptions> preset(std::string_view name) {
  PrecomputeOptions o;
  if (name == "draft") {
    o.surfels = 8192;
    o.links = 64;
    o.rays = 256;
    o.target_resolution = 64;
  } else if (name == "medium") {
    o.surfels = 32768;
    o.links = 128;
    o.rays = 1024;
    o.target_resolution = 128;
  } else if (name == "high") {
    o.surfels = 131072;
    o.links = 254;
    o.bands = 4;
    o.rays = 4096;
    o.target_resolution = 256;
  } else {
    return invalidInput("--preset '{}' must be draft, medium or high", name);
  }
  return o;
}

std::string PrecomputeOptions::canonical() const {
  return fmt::format(
      "surfels={};links={};bands={};rays={};builder={};grid={};grid_spacing={:a};grid_resolution={};"
      "texel_size={};lightmap_resolution={};target_resolution={};validity_rays={};seed={}",
      surfels, links, bands, rays, builder == hierarchy::Builder::kAgglomerative ? "hac" : "kd",
      static_cast<int>(grid), grid_spacing_m, grid_resolution,
      texel_size_m ? fmt::format("{:a}", *texel_size_m) : "auto",
      lightmap_resolution ? std::to_string(*lightmap_resolution) : "auto", target_resolution, validity_rays, seed);
}

Expected<charts::UnwrapResult> unwrapFor(scene::Scene& scene, const PrecomputeOptions& options) {
  charts::UnwrapOptions u;
  u.texel_size_m = options.texel_size_m;
  u.resolution = options.lightmap_resolution;
  u.target_resolution = options.target_resolution;
  return charts::unwrap(scene, u);
}

Expected<Precomputation> run(scene::Scene& scene, const PrecomputeOptions& options, Progress* progress) {
  if (Status s = options.validate(); !s) return s;
  NullProgress null_progress;
  Progress& sink = progress ? *progress : null_progress;
  Precomputation p;
  p.options = options;
  // Stages that report their own progress (links) get no begin/end of their own here.
  auto stage = [&](const char* name, auto&& body, bool self_reporting = false) -> Status {
    const auto t0 = Clock::now();
    if (!self_reporting) sink.begin(name, 0);
    Status s = body();
    if (!self_reporting) sink.end();
    p.timings.push_back({name, secondsSince(t0)});
    return s;
  };

  Status s = stage("unwrap", [&]() -> Status {
    auto r = unwrapFor(scene, options);
    if (!r) return r.status();
    p.atlas = std::move(r->atlas);
    p.notes.push_back(p.atlas.generated ? fmt::format("lightmap UVs generated: {} charts in {}x{}",
                                                      p.atlas.chart_count, p.atlas.resolution, p.atlas.resolution)
                                        : "lightmap UVs: every static mesh has TEXCOORD_1, kept");
    return {};
  });
  if (!s) return s;

  s = stage("surfels", [&]() -> Status {
    auto r = surfels::placeSurfels(scene, {.count = options.surfels, .seed = static_cast<std::uint32_t>(options.seed)});
    if (!r) return r.status();
    p.surfels = std::move(r).value();
    if (p.surfels.empty()) return invalidInput("{}: the scene has no static surface area to place surfels on",
                                               scene.source_path);
    return {};
  });
  if (!s) return s;

  s = stage("hierarchy", [&]() -> Status {
    auto r = hierarchy::buildTree(p.surfels, {.builder = options.builder});
    if (!r) return r.status();
    p.tree = std::move(r).value();
    return {};
  });
  if (!s) return s;

  std::optional<rt::Accel> accel;
  s = stage("bvh", [&]() -> Status {
    auto r = rt::Accel::build(scene);
    if (!r) return r.status();
    accel.emplace(std::move(r).value());
    return {};
  });
  if (!s) return s;

  const caches::ValidityOptions validity{.rays = options.validity_rays};
  s = stage("caches", [&]() -> Status {
    auto lm = caches::placeLightmapCaches(scene, *accel, {.resolution = p.atlas.resolution, .validity = validity});
    if (!lm) return lm.status();
    p.lightmap = std::move(lm).value();
    bool dynamic = false;
    for (const auto& m : scene.meshes) dynamic |= !m.is_static;
    p.has_grid = options.grid == GridMode::kOn || (options.grid == GridMode::kAuto && dynamic);
    if (options.grid == GridMode::kAuto)
      p.notes.push_back(dynamic ? "grid caches: the scene has dynamic meshes"
                                : "grid caches skipped: no dynamic meshes and no grid requested");
    if (p.has_grid) {
      caches::GridCacheOptions g;
      g.spacing_m = options.grid_spacing_m;
      g.resolution = options.grid_resolution;
      g.validity = validity;
      auto grid = caches::placeGridCaches(scene, *accel, g);
      if (!grid) return grid.status();
      p.grid = std::move(grid).value();
    }
    p.lightmap_fill = caches::planLightmapFill(p.lightmap);
    p.grid_fill = p.has_grid ? caches::planGridFill(p.grid) : caches::FillPlan{};
    p.dilation = caches::planDilation(p.lightmap, std::max(1, p.atlas.gutter_texels));
    return {};
  });
  if (!s) return s;

  const links::LinkOptions link_options{
      .rays = options.rays, .max_links = options.links, .bands = options.bands, .seed = options.seed};
  s = stage("links", [&]() -> Status {
    links::LinkOptions lm_options = link_options;
    lm_options.progress_label = "links lightmap";
    auto lm = links::generateLinks(scene, *accel, p.surfels, p.tree, {p.lightmap.position, p.lightmap.normal},
                                   lm_options, &sink);
    if (!lm) return lm.status();
    p.lightmap_links = std::move(lm).value();
    if (p.has_grid) {
      const std::vector<glm::vec3> sphere(p.grid.size(), glm::vec3(0.0f));
      links::LinkOptions grid_options = link_options;
      grid_options.progress_label = "links grid";
      auto g = links::generateLinks(scene, *accel, p.surfels, p.tree, {p.grid.position, sphere}, grid_options, &sink);
      if (!g) return g.status();
      p.grid_links = std::move(g).value();
    }
    return {};
  }, /*self_reporting=*/true);
  if (!s) return s;
  return p;
}

nlohmann::ordered_json Precomputation::report() const {
  nlohmann::ordered_json j;
  j["options"] = options.canonical();
  j["counts"] = {{"surfels", surfels.size()},
                 {"tree_nodes", tree.nodeCount()},
                 {"tree_levels", tree.levelCount()},
                 {"lightmap_resolution", atlas.resolution},
                 {"texel_size_m", atlas.texel_size_m},
                 {"lightmap_caches", lightmap.size()},
                 {"lightmap_caches_valid", lightmap.validCount()},
                 {"lightmap_caches_pushed", std::count(lightmap.pushed.begin(), lightmap.pushed.end(), 1)},
                 {"grid_caches", grid.size()},
                 {"grid_caches_valid", grid.validCount()},
                 {"grid_dims", {grid.dims.x, grid.dims.y, grid.dims.z}},
                 {"grid_spacing_m", grid.spacing_m}};
  nlohmann::ordered_json t = nlohmann::ordered_json::object();
  double total = 0.0;
  for (const auto& st : timings) {
    t[st.stage] = st.seconds;
    total += st.seconds;
  }
  t["total"] = total;
  j["seconds"] = t;
  const std::size_t surfel_bytes = bytesOf(surfels.position) + bytesOf(surfels.normal) + bytesOf(surfels.area) +
                                   bytesOf(surfels.albedo) + bytesOf(surfels.emission) +
                                   bytesOf(surfels.lightmap_uv) + bytesOf(surfels.mesh) + bytesOf(surfels.triangle) +
                                   bytesOf(surfels.barycentric);
  const std::size_t tree_bytes = bytesOf(tree.left) + bytesOf(tree.right) + bytesOf(tree.parent) +
                                 bytesOf(tree.begin) + bytesOf(tree.end) + bytesOf(tree.depth) + bytesOf(tree.area) +
                                 bytesOf(tree.bounds_min) + bytesOf(tree.bounds_max) + bytesOf(tree.centroid) +
                                 bytesOf(tree.mean_normal) + bytesOf(tree.level_begin) +
                                 bytesOf(tree.leaf_of_surfel) + bytesOf(tree.original_index);
  auto link_bytes = [](const links::Links& l) {
    return std::pair{l.linkCount() * l.bytesPerLinkProjected() + bytesOf(l.offsets),
                     l.linkCount() * links::Links::bytesPerLinkRuntime() + bytesOf(l.offsets)};
  };
  const auto [lm_sh, lm_rt] = link_bytes(lightmap_links);
  const auto [grid_sh, grid_rt] = link_bytes(grid_links);
  const int nc = options.bands * options.bands;
  j["memory_bytes"] = {
      {"surfels", surfel_bytes},
      {"tree", tree_bytes},
      {"lightmap_caches_sh_half", lightmap.size() * nc * 3 * 2},
      {"grid_caches_sh_half", grid.size() * nc * 3 * 2},
      {"lightmap_links_projected", lm_sh},
      {"lightmap_links_runtime", lm_rt},
      {"grid_links_projected", grid_sh},
      {"grid_links_runtime", grid_rt},
      {"sky_visibility", bytesOf(lightmap_links.sky) + bytesOf(grid_links.sky)}};
  j["links"] = {{"lightmap", linkStatsJson(lightmap_links)}, {"grid", linkStatsJson(grid_links)}};
  j["notes"] = notes;
  return j;
}

Status save(const Precomputation& p, const std::string& path, std::uint64_t cache_key) {
  artifact::Writer w(cache_key);
  Status status;
  auto add = [&](const std::string& name, const auto& vec) {
    using T = typename std::decay_t<decltype(vec)>::value_type;
    if (status) status = w.addArray<T>(name, std::span<const T>(vec));
  };
  visitSmallArrays(p, add);
  visitLinkArrays("lmlink", p.lightmap_links, add);
  visitLinkArrays("gridlink", p.grid_links, add);
  nlohmann::ordered_json meta;
  meta["options"] = p.options.canonical();
  meta["bands"] = p.options.bands;
  meta["has_grid"] = p.has_grid;
  meta["lightmap"] = {{"width", p.lightmap.width}, {"height", p.lightmap.height},
                      {"texel_size_m", p.atlas.texel_size_m}, {"gutter_texels", p.atlas.gutter_texels},
                      {"generated_uv", p.atlas.generated}};
  meta["grid"] = {{"origin", {p.grid.origin.x, p.grid.origin.y, p.grid.origin.z}},
                  {"spacing_m", p.grid.spacing_m},
                  {"dims", {p.grid.dims.x, p.grid.dims.y, p.grid.dims.z}}};
  meta["unreachable_fills"] = {{"lightmap", p.lightmap_fill.unreachable}, {"grid", p.grid_fill.unreachable}};
  // No timings in here: the same scene and options must give a bit-identical file.
  meta["notes"] = p.notes;
  const std::string meta_text = meta.dump();
  if (status) status = w.addString("meta", meta_text);
  if (!status) return status;
  return w.write(path);
}

Expected<LoadedPrecomputation> open(const std::string& path) {
  auto file = artifact::Artifact::open(path);
  if (!file) return file.status();
  LoadedPrecomputation out{std::move(file).value(), {}, {}, {}, {}};
  auto meta_text = out.file.string("meta");
  if (!meta_text) return meta_text.status();
  out.meta = nlohmann::json::parse(*meta_text, nullptr, /*allow_exceptions=*/false);
  if (out.meta.is_discarded() || !out.meta.contains("bands") || !out.meta.contains("lightmap"))
    return invalidInput("artifact {}: the 'meta' section is not valid lightlink metadata", path);
  Status status;
  auto copy = [&](const std::string& name, auto& vec) {
    using T = typename std::decay_t<decltype(vec)>::value_type;
    if (!status) return;
    auto s = out.file.array<T>(name);
    if (!s) {
      status = s.status();
      return;
    }
    vec.assign(s->begin(), s->end());
  };
  visitSmallArrays(out.p, copy);
  if (!status) return status;
  auto view = [&](const char* prefix, links::LinksView& spans) {
    spans.bands = out.meta["bands"].get<int>();
    auto bind = [&](const std::string& name, auto& span) {
      using T = typename std::decay_t<decltype(span)>::element_type;
      if (!status) return;
      auto s = out.file.array<std::remove_const_t<T>>(name);
      if (!s) status = s.status();
      else span = *s;
    };
    visitLinkArrays(prefix, spans, bind);
  };
  view("lmlink", out.lightmap_links);
  view("gridlink", out.grid_links);
  if (!status) return status;
  const auto& lm = out.meta["lightmap"];
  out.p.lightmap.width = lm["width"].get<int>();
  out.p.lightmap.height = lm["height"].get<int>();
  out.p.atlas.resolution = out.p.lightmap.width;
  out.p.atlas.texel_size_m = lm["texel_size_m"].get<float>();
  out.p.atlas.gutter_texels = lm["gutter_texels"].get<int>();
  out.p.atlas.generated = lm["generated_uv"].get<bool>();
  out.p.options.bands = out.meta["bands"].get<int>();
  out.p.has_grid = out.meta["has_grid"].get<bool>();
  const auto& g = out.meta["grid"];
  out.p.grid.origin = {g["origin"][0].get<float>(), g["origin"][1].get<float>(), g["origin"][2].get<float>()};
  out.p.grid.spacing_m = g["spacing_m"].get<float>();
  out.p.grid.dims = {g["dims"][0].get<int>(), g["dims"][1].get<int>(), g["dims"][2].get<int>()};
  // Cross-checks that catch an artifact whose sections do not belong together.
  const std::size_t nc = static_cast<std::size_t>(out.lightmap_links.bands) * out.lightmap_links.bands;
  if (out.lightmap_links.offsets.size() != out.p.lightmap.size() + 1 ||
      out.lightmap_links.coeffs.size() != out.lightmap_links.node.size() * nc ||
      out.p.tree.nodeCount() != (out.p.surfels.size() ? 2 * out.p.surfels.size() - 1 : 0))
    return invalidInput("artifact {}: sections are inconsistent with each other", path);
  return out;
}

Expected<std::uint64_t> cacheKeyFor(const std::string& scene_path, const PrecomputeOptions& options) {
  std::ifstream in(scene_path, std::ios::binary);
  if (!in) return notFound("cannot read scene {}", scene_path);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  const std::string data = bytes.str();
  return artifact::cacheKey(std::as_bytes(std::span<const char>(data.data(), data.size())), options.canonical());
}

}  // namespace lightlink::precompute
