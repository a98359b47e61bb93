// `lightlink bake`: the CI job. Scene -> (unwrap) -> precompute (or a matching cached
// artifact) -> relight with the scene's lights (+ a light-set file) -> EXR lightmap and
// grid, PNG preview, the glTF with TEXCOORD_1, and one JSON report.
#include <cstdio>
#include <filesystem>
#include <optional>

#include <fmt/format.h>

#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"
#include "clients/lightlink/progress_bar.h"
#include "core/charts/gltf_writer.h"
#include "core/output/output.h"
#include "core/precompute/precompute.h"
#include "core/relight/relight.h"
#include "core/rt/accel.h"
#include "core/scene/load.h"

namespace lightlink::cli {
namespace {

namespace fs = std::filesystem;

Status makeDirectory(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return ioError("cannot create directory {}: {}", dir.string(), ec.message());
  return {};
}

}  // namespace

int runBake(const BakeArgs& args) {
  constexpr const char* kCmd = "bake";
  auto options = precompute::preset(args.preset);
  if (!options) return reportError(kCmd, options.status());
  relight::RelightOptions relight_options;
  if (args.link_form == "projected") relight_options.link_form = relight::LinkForm::kProjected;
  else if (args.link_form == "runtime") relight_options.link_form = relight::LinkForm::kRuntime;
  else return reportError(kCmd, invalidInput("--link-form '{}' must be 'projected' or 'runtime'", args.link_form));
  if (args.max_bounces < 0 || args.max_bounces > 64)
    return reportError(kCmd, invalidInput("--bounces {} is out of range (0..64)", args.max_bounces));
  relight_options.max_bounces = args.max_bounces;

  auto scene = scene::loadGltf(args.scene_path);
  if (!scene) return reportError(kCmd, scene.status());
  auto lights = relight::LightSet::fromScene(*scene);
  if (!args.lights_path.empty()) {
    if (Status s = lights.applyFile(args.lights_path); !s) return reportError(kCmd, s);
  }
  const fs::path out(args.output_dir);
  const fs::path cache_dir = args.cache_dir.empty() ? out / "cache" : fs::path(args.cache_dir);
  if (Status s = makeDirectory(out); !s) return reportError(kCmd, s);
  if (Status s = makeDirectory(cache_dir); !s) return reportError(kCmd, s);

  auto key = precompute::cacheKeyFor(args.scene_path, *options);
  if (!key) return reportError(kCmd, key.status());
  const fs::path artifact_path = cache_dir / (artifact::cacheKeyHex(*key) + ".llk");
  ProgressBar bar(!args.quiet);

  // Reuse a matching artifact when one opens cleanly; a damaged one is recomputed (and
  // replaced atomically), never used.
  std::optional<precompute::LoadedPrecomputation> loaded;
  std::string artifact_note;
  if (!args.no_cache && fs::exists(artifact_path)) {
    auto opened = precompute::open(artifact_path.string());
    if (opened && opened->file.cacheKey() == *key) {
      loaded.emplace(std::move(opened).value());
      artifact_note = "reused " + artifact_path.string();
    } else {
      artifact_note = fmt::format("recomputed: cached artifact unusable ({})",
                                  opened ? "key mismatch" : opened.status().message());
    }
  }
  std::optional<precompute::Precomputation> computed;
  charts::LightmapAtlas atlas;
  if (loaded) {
    auto unwrapped = precompute::unwrapFor(*scene, *options);
    if (!unwrapped) return reportError(kCmd, unwrapped.status());
    atlas = unwrapped->atlas;
  } else {
    auto p = precompute::run(*scene, *options, &bar);
    if (!p) return reportError(kCmd, p.status());
    computed.emplace(std::move(p).value());
    atlas = computed->atlas;
    if (Status s = precompute::save(*computed, artifact_path.string(), *key); !s) return reportError(kCmd, s);
    if (artifact_note.empty()) artifact_note = "computed " + artifact_path.string();
  }
  const precompute::Precomputation& p = loaded ? loaded->p : *computed;
  const links::LinksView lm_links = loaded ? loaded->lightmap_links : computed->lightmap_links.view();
  const links::LinksView grid_links = loaded ? loaded->grid_links : computed->grid_links.view();

  auto accel = rt::Accel::build(*scene);
  if (!accel) return reportError(kCmd, accel.status());
  auto relighter = relight::Relighter::create(*scene, *accel, p, lm_links, grid_links);
  if (!relighter) return reportError(kCmd, relighter.status());
  bar.begin("relight", 0);
  auto result = relighter->relight(lights, relight_options);
  bar.end();
  if (!result) return reportError(kCmd, result.status());

  output::ExrOptions exr;
  exr.half = !args.float_exr;
  exr.scene_hash = artifact::cacheKeyHex(*key);
  auto lm_stats = output::writeLightmapExr(*result, (out / "lightmap.exr").string(), exr);
  if (!lm_stats) return reportError(kCmd, lm_stats.status());
  if (Status s = output::writeIrradiancePng(*result, p.lightmap, (out / "lightmap.png").string()); !s)
    return reportError(kCmd, s);
  std::size_t grid_clamped = 0;
  if (p.has_grid) {
    auto g = output::writeGridExr(*result, p.grid, (out / "grid.exr").string(), exr);
    if (!g) return reportError(kCmd, g.status());
    grid_clamped = g->clamped;
    if (Status s = output::writeGridJson(*result, p.grid, (out / "grid.json").string()); !s) return reportError(kCmd, s);
    if (Status s = output::writeGridRaw(*result, p.grid, (out / "grid.raw").string()); !s) return reportError(kCmd, s);
  }
  const std::string gltf_name = fs::path(args.scene_path).stem().string() + "_lm" +
                                (fs::path(args.scene_path).extension() == ".glb" ? ".glb" : ".gltf");
  if (atlas.generated) {
    if (Status s = charts::writeGltfWithLightmapUv(args.scene_path, *scene, atlas, (out / gltf_name).string()); !s)
      return reportError(kCmd, s);
  }

  nlohmann::ordered_json report;
  report["scene"] = args.scene_path;
  report["preset"] = args.preset;
  report["artifact"] = artifact_note;
  report["cache_key"] = artifact::cacheKeyHex(*key);
  report["precompute"] = computed ? computed->report() : nlohmann::ordered_json(loaded->meta);
  report["relight"] = result->report();
  report["effects_plan"] = result->plan.toJson();
  report["half_clamped_values"] = {{"lightmap", lm_stats->clamped}, {"grid", grid_clamped}};
  std::vector<std::string> outputs = {"lightmap.exr", "lightmap.png", "report.json"};
  if (p.has_grid) outputs.insert(outputs.end(), {"grid.exr", "grid.json", "grid.raw"});
  if (atlas.generated) outputs.push_back(gltf_name);
  report["outputs"] = outputs;
  if (Status s = output::writeReportJson(report, (out / "report.json").string()); !s) return reportError(kCmd, s);

  if (!args.quiet) {
    std::string text = result->plan.toText();
    text += fmt::format("artifact     {}\n", artifact_note);
    text += fmt::format("relight      {:.2f} ms ({} backend, {} kernel), bounces {} ({})\n",
                        result->totalSeconds() * 1e3, result->backend, result->kernel, result->bounce_log.size(),
                        result->bounce_stop);
    if (lm_stats->clamped + grid_clamped > 0)
      text += fmt::format("warning      {} values beyond the half range were clamped (use --float)\n",
                          lm_stats->clamped + grid_clamped);
    text += fmt::format("wrote        {}: ", out.string());
    for (std::size_t i = 0; i < outputs.size(); ++i) text += (i ? ", " : "") + outputs[i];
    text += "\n";
    std::fwrite(text.data(), 1, text.size(), stdout);
  }
  return kExitOk;
}

}  // namespace lightlink::cli
