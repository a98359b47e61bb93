// `lightlink bake`: the CI job. Scene -> (unwrap) -> precompute (or a matching cached
// artifact) -> relight with the scene's lights (+ a light-set file) -> EXR lightmap and
// grid in the chosen encoding (l0, l1, l2), PNG preview, the glTF with TEXCOORD_1, and one
// JSON report.
#include <chrono>
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>

#include "clients/lightlink/bake_findings.h"
#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"
#include "clients/lightlink/scene_access.h"
#include "clients/lightlink/progress_bar.h"
#include "clients/lightlink/version.h"
#include "core/common/isa.h"
#include "core/bake/bake_options.h"
#include "core/charts/gltf_writer.h"
#include "core/output/output.h"
#include "core/precompute/resident.h"
#include "core/relight/relight.h"
#include "gpu/backend_factory.h"

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
  auto bake_options = bake::buildBakeOptions(args.options, "medium");
  if (!bake_options) return reportError(kCmd, bake_options.status());
  const relight::RelightOptions relight_options = bake_options->relight;
  auto backend_choice = gpu::parseBackendChoice(args.backend, "--backend");
  if (!backend_choice) return reportError(kCmd, backend_choice.status());

  auto fail_on = parseFailOn(args.fail_on);
  if (!fail_on) return reportError(kCmd, fail_on.status());

  const fs::path out(args.output_dir);
  const fs::path cache_dir = args.cache_dir.empty() ? out / "cache" : fs::path(args.cache_dir);
  if (Status s = makeDirectory(out); !s) return reportError(kCmd, s);
  ProgressBar bar(!args.quiet);

  // Load the scene, then reuse a matching artifact or precompute and save one.
  precompute::ResidentRequest request;
  request.scene_path = args.scene_path;
  request.load.files = sceneFileAccess(args.allow_outside_scene);
  request.options = bake_options->precompute;
  request.cache_dir = cache_dir.string();
  request.use_cache = !args.no_cache;
  auto resident = precompute::ResidentScene::open(request, &bar);
  if (!resident) return reportError(kCmd, resident.status());
  const scene::Scene& scene = resident->scene();
  const precompute::Precomputation& p = resident->precomputation();
  const charts::LightmapAtlas& atlas = resident->atlas();
  const std::string key_hex = resident->cacheKeyHex();
  const std::string& artifact_note = resident->note();

  auto lights = relight::LightSet::fromSceneLights(scene.lights);
  if (!args.lights_path.empty()) {
    if (Status s = lights.applyFile(args.lights_path); !s) return reportError(kCmd, s);
  }
  // cpu, gpu or auto: the note says which ran and, for a fallback, why.
  std::string backend_note;
  auto backend = gpu::makeBackend(*backend_choice, scene, resident->accel(), p, resident->lightmapLinks(),
                                  resident->gridLinks(), &backend_note);
  if (!backend) return reportError(kCmd, backend.status());
  bar.begin("relight", 0);
  Expected<relight::RelightResult> result = relight::RelightResult{};
  const Status relit = (*backend)->relightInto(lights, relight_options, *result);
  bar.end();
  if (!relit) return reportError(kCmd, relit);
  BakeFindings findings = collectFindings(scene, resident->precomputeReport(), *result);

  auto encoding = output::parseEncoding(args.encoding);
  if (!encoding) return reportError(kCmd, encoding.status());
  output::ExrOptions exr;
  exr.half = !args.float_exr;
  exr.scene_hash = key_hex;
  exr.encoding = *encoding;
  if (Status s = output::writeIrradiancePng(*result, p.lightmap, (out / "lightmap.png").string(), {},
                                            p.hasDirectLayer() ? &p.direct_texels : nullptr);
      !s)
    return reportError(kCmd, s);
  const auto t_write = std::chrono::steady_clock::now();
  auto lm = output::writeLightmapExrs(*result, p.lightmap, out.string(), exr,
                                      p.hasDirectLayer() ? &p.direct_texels : nullptr);
  if (!lm) return reportError(kCmd, lm.status());
  output::WrittenExrs grid_files;
  if (p.has_grid) {
    auto g = output::writeGridExrs(*result, p.grid, out.string(), exr);
    if (!g) return reportError(kCmd, g.status());
    grid_files = std::move(*g);
    if (Status s = output::writeGridJson(*result, p.grid, (out / "grid.json").string(), *encoding); !s)
      return reportError(kCmd, s);
    if (Status s = output::writeGridRaw(*result, p.grid, (out / "grid.raw").string(), *encoding); !s)
      return reportError(kCmd, s);
  }
  const double write_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_write).count();
  const output::WriteStats& lm_stats = lm->stats;
  const std::size_t grid_clamped = grid_files.stats.clamped, grid_underflowed = grid_files.stats.underflowed;
  if (lm_stats.clamped + grid_clamped > 0)
    findings.warnings.push_back(fmt::format("EXR outputs: {} values beyond the half range were clamped "
                                            "(use --float)", lm_stats.clamped + grid_clamped));
  if (lm_stats.underflowed + grid_underflowed > 0)
    findings.warnings.push_back(fmt::format("EXR outputs: {} non-zero values below the smallest normal "
                                            "half lost precision (use --float)",
                                            lm_stats.underflowed + grid_underflowed));
  // After the progress bar's last line, so no redraw hides them; with -q too.
  printWarnings(findings, stderr);
  const std::string gltf_name = fs::path(args.scene_path).stem().string() + "_lm" +
                                (fs::path(args.scene_path).extension() == ".glb" ? ".glb" : ".gltf");
  if (atlas.generated) {
    if (Status s = charts::writeGltfWithLightmapUv(args.scene_path, scene, atlas, (out / gltf_name).string(),
                                                       request.load.files);
        !s)
      return reportError(kCmd, s);
  }

  nlohmann::ordered_json report;
  report["lightlink"] = {{"version", lightlinkVersion()}, {"commit", lightlinkCommit()}};
  report["scene"] = args.scene_path;
  report["preset"] = bake_options->preset;
  report["warnings"] = findings.warnings;
  report["notes"] = findings.notes;
  report["lighting"] = {{"no_light", findings.no_light}, {"all_black", findings.all_black}};
  report["load"] = resident->loadReport();
  report["artifact"] = artifact_note;
  report["cache_key"] = key_hex;
  report["backend"] = {{"requested", args.backend}, {"used", result->backend}, {"note", backend_note}};
  report["isa"] = {{"cpu", isaName(cpuIsa())}, {"used", isaName(activeIsa())}};
  report["precompute"] = resident->precomputeReport();
  report["relight"] = result->report();
  report["effects_plan"] = result->plan.toJson();
  report["half_clamped_values"] = {{"lightmap", lm_stats.clamped}, {"grid", grid_clamped}};
  report["half_underflowed_values"] = {{"lightmap", lm_stats.underflowed}, {"grid", grid_underflowed}};
  report["encoding"] = {{"name", output::encodingName(*encoding)},
                        {"lightmap_bands", output::lightmapBands(*encoding, result->bands)},
                        {"grid_bands", p.has_grid ? output::gridBands(*encoding, result->bands) : 0},
                        {"exr_layout", output::kExrLayout},
                        {"precision", exr.half ? "half" : "float"},
                        {"write_seconds", write_s}};
  std::vector<std::string> outputs = lm->files;
  outputs.insert(outputs.end(), {"lightmap.png", "report.json"});
  if (p.has_grid) {
    outputs.insert(outputs.end(), grid_files.files.begin(), grid_files.files.end());
    outputs.insert(outputs.end(), {"grid.json", "grid.raw"});
  }
  if (atlas.generated) outputs.push_back(gltf_name);
  report["outputs"] = outputs;
  // Static meshes whose indirect light is not in the lightmap: from the irradiance volume,
  // or none at all (receive_gi "off": the engine shades them without baked indirect light).
  nlohmann::ordered_json from_volume = nlohmann::ordered_json::array(), no_gi = nlohmann::ordered_json::array();
  for (const std::uint32_t i : atlas.probe_lit) {  // marked, or too small for the lightmap
    const auto& m = scene.meshes[i];
    (m.receive_gi == scene::ReceiveGi::kOff ? no_gi : from_volume).push_back(m.name);
  }
  report["receive_gi"] = {{"volume", std::move(from_volume)}, {"off", std::move(no_gi)}};
  if (Status s = output::writeReportJson(report, (out / "report.json").string()); !s) return reportError(kCmd, s);

  if (!args.quiet) {
    std::string text = result->plan.toText();
    for (const std::string& note : findings.notes) text += fmt::format("note         {}\n", note);
    text += fmt::format("artifact     {}\n", artifact_note);
    text += fmt::format("backend      {}\n", backend_note);
    text += fmt::format("relight      {:.2f} ms ({} backend, {} kernel), bounces {} ({})\n",
                        result->totalSeconds() * 1e3, result->backend, result->kernel, result->bounce_log.size(),
                        result->bounce_stop);
    text += fmt::format("wrote        {}: ", out.string());
    for (std::size_t i = 0; i < outputs.size(); ++i) text += (i ? ", " : "") + outputs[i];
    text += "\n";
    std::fwrite(text.data(), 1, text.size(), stdout);
  }
  return bakeExitCode(findings, *fail_on);
}

}  // namespace lightlink::cli
