// `lightlink precompute`: scene -> surfels, tree, caches, links -> one artifact (.llk).
#include <chrono>
#include <cstdio>
#include <fstream>

#include <fmt/format.h>

#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"
#include "clients/lightlink/scene_access.h"
#include "clients/lightlink/progress_bar.h"
#include "core/bake/bake_options.h"
#include "core/common/process_memory.h"
#include "core/precompute/precompute.h"
#include "core/scene/load.h"
#include "core/scene/subdivide.h"

namespace lightlink::cli {
namespace {

std::string humanBytes(double b) {
  const char* units[] = {"B", "KiB", "MiB", "GiB"};
  int u = 0;
  while (b >= 1024.0 && u < 3) {
    b /= 1024.0;
    ++u;
  }
  return fmt::format("{:.1f} {}", b, units[u]);
}

std::string formatReport(const nlohmann::ordered_json& r) {
  std::string out;
  const auto& c = r["counts"];
  out += fmt::format("surfels      {}   tree nodes {} ({} levels)\n", c["surfels"].get<std::size_t>(),
                     c["tree_nodes"].get<std::size_t>(), c["tree_levels"].get<std::size_t>());
  out += fmt::format("lightmap     {}x{} texels of {:.4g} m, {} caches ({} valid, {} pushed)\n",
                     c["lightmap_resolution"].get<int>(), c["lightmap_resolution"].get<int>(),
                     c["texel_size_m"].get<double>(), c["lightmap_caches"].get<std::size_t>(),
                     c["lightmap_caches_valid"].get<std::size_t>(), c["lightmap_caches_pushed"].get<std::size_t>());
  out += fmt::format("grid         {} caches ({} valid)\n", c["grid_caches"].get<std::size_t>(),
                     c["grid_caches_valid"].get<std::size_t>());
  for (const char* set : {"lightmap", "grid"}) {
    const auto& l = r["links"][set];
    if (l["caches"].get<std::size_t>() == 0) continue;
    out += fmt::format("links {:<7} {} ({:.1f}/cache), {} rays at {:.2f} Mrays/s\n", set, l["links"].get<std::size_t>(),
                       l["mean_links_per_cache"].get<double>(), l["rays"].get<std::uint64_t>(),
                       l["rays_per_second"].get<double>() * 1e-6);
  }
  out += "seconds     ";
  for (const auto& [stage, s] : r["seconds"].items()) out += fmt::format(" {} {:.3f}", stage, s.get<double>());
  out += "\nmemory      ";
  for (const auto& [what, b] : r["memory_bytes"].items())
    out += fmt::format(" {} {}", what, humanBytes(b.get<double>()));
  out += "\n";
  for (const auto& note : r["notes"]) out += fmt::format("note         {}\n", note.get<std::string>());
  return out;
}

}  // namespace

int runPrecompute(const PrecomputeArgs& args) {
  for (const auto& [name, value] : args.options)
    if (name == "bounces" || name == "link-form")
      return reportError("precompute", invalidInput("--{}: a relight option; precompute does not relight (use bake)", name));
  // No preset unless one is given: precompute's defaults are PrecomputeOptions'.
  auto bake_options = bake::buildBakeOptions(args.options, "");
  if (!bake_options) return reportError("precompute", bake_options.status());
  precompute::PrecomputeOptions& options = bake_options->precompute;
  if (!args.shard.empty()) {
    auto shard = precompute::parseShard(args.shard);
    if (!shard) return reportError("precompute", shard.status());
    options.shard = *shard;
  }
  if (args.subdivide < 0 || args.subdivide > 4)
    return reportError("precompute", invalidInput("--subdivide {} is out of range (0..4)", args.subdivide));
  scene::LoadOptions load;
  load.files = sceneFileAccess(args.allow_outside_scene);
  const auto load_start = std::chrono::steady_clock::now();
  const std::uint64_t rss_before_load = residentBytes();
  auto scene = scene::loadScene(args.scene_path, load);
  if (!scene) return reportError("precompute", scene.status());
  scene::applySurfaceRules(*scene, options.surfaces);
  const double load_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - load_start).count();
  const std::uint64_t peak_after_load = peakResidentBytes();
  // Warnings are not errors (a missing texture: the factor is used), but the user hears them.
  for (const std::string& w : scene->warnings) std::fprintf(stderr, "lightlink precompute: warning: %s\n", w.c_str());
  if (args.subdivide > 0) scene::subdivide(*scene, args.subdivide);
  auto key = precompute::cacheKeyFor(args.scene_path, options, load.files);
  if (!key) return reportError("precompute", key.status());
  ProgressBar bar(!args.quiet);
  auto p = precompute::run(*scene, options, &bar);
  if (!p) return reportError("precompute", p.status());
  if (Status s = options.shard ? precompute::savePart(*p, args.output_path, *key, args.scene_path)
                               : precompute::save(*p, args.output_path, *key);
      !s)
    return reportError("precompute", s);
  auto report = p->report();
  report["artifact"] = args.output_path;
  report["cache_key"] = artifact::cacheKeyHex(*key);
  report["scene"] = args.scene_path;
  report["triangles"] = scene->triangleCount();
  if (options.shard)
    report["shard"] = {{"shard", options.shard->index},
                       {"shards", options.shard->count},
                       {"lightmap_caches", {p->lightmap_linked.begin, p->lightmap_linked.end}},
                       {"grid_caches", {p->grid_linked.begin, p->grid_linked.end}}};
  report["warnings"] = scene->warnings;
  report["load"] = {{"seconds", load_seconds},
                    {"rss_before_bytes", rss_before_load},
                    {"peak_rss_after_bytes", peak_after_load},
                    {"images_decoded", scene->stats.images_decoded},
                    {"images_skipped", scene->stats.images_skipped},
                    {"image_bytes", scene->stats.image_bytes}};
  if (!args.report_json.empty()) {
    std::ofstream out(args.report_json, std::ios::binary | std::ios::trunc);
    out << report.dump(2) << "\n";
    if (!out) return reportError("precompute", ioError("cannot write report {}", args.report_json));
  }
  if (!args.quiet) {
    std::string text = formatReport(report);
    if (options.shard)
      text += fmt::format("shard        {}/{}: linked lightmap caches [{}, {}), grid caches [{}, {})\n",
                          options.shard->index, options.shard->count, p->lightmap_linked.begin,
                          p->lightmap_linked.end, p->grid_linked.begin, p->grid_linked.end);
    text += fmt::format("wrote        {}{}\n", args.output_path, options.shard ? " (shard part: lightlink merge)" : "");
    std::fwrite(text.data(), 1, text.size(), stdout);
  }
  return kExitOk;
}

}  // namespace lightlink::cli
