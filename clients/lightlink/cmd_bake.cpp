// `lightlink bake`: the CI job. Scene -> (unwrap) -> precompute (or a matching cached
// artifact) -> relight with the scene's lights (+ a light-set file) -> EXR lightmap and
// grid in the chosen encoding (l0, l1, l2) and the grid's three.js form, PNG preview, the
// glTF with TEXCOORD_1 that points at all of them, and one JSON report; with --scenario, the
// lighting of each scenario in its own folder.
#include <algorithm>
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
#include "core/lights/scenarios.h"
#include "core/bake/bake_options.h"
#include "core/charts/gltf_writer.h"
#include "core/output/grid_threejs.h"
#include "core/output/lighting_description.h"
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

// What writeLightingFiles wrote, and what the half writers clamped or lost.
struct WrittenFiles {
  std::vector<std::string> outputs;
  std::size_t lightmap_clamped = 0, lightmap_underflowed = 0, grid_clamped = 0, grid_underflowed = 0;
};

// The lighting of one relight into `dir`: lightmap (+ finer direct), preview, grid files.
Expected<WrittenFiles> writeLightingFiles(const relight::RelightResult& result, const precompute::Precomputation& p,
                                          const fs::path& dir, const output::ExrOptions& exr) {
  WrittenFiles f;
  const caches::LightmapCaches* direct_texels = p.hasDirectLayer() ? &p.direct_texels : nullptr;
  auto lm = output::writeLightmapExrs(result, p.lightmap, dir.string(), exr, direct_texels);
  if (!lm) return lm.status();
  f.outputs = lm->files;
  f.lightmap_clamped = lm->stats.clamped;
  f.lightmap_underflowed = lm->stats.underflowed;
  if (Status s = output::writeIrradiancePng(result, p.lightmap, (dir / "lightmap.png").string(), {}, direct_texels); !s)
    return s;
  f.outputs.push_back("lightmap.png");
  if (p.has_grid) {
    auto g = output::writeGridExrs(result, p.grid, dir.string(), exr);
    if (!g) return g.status();
    f.grid_clamped = g->stats.clamped;
    f.grid_underflowed = g->stats.underflowed;
    f.outputs.insert(f.outputs.end(), g->files.begin(), g->files.end());
    if (Status s = output::writeGridJson(result, p.grid, (dir / "grid.json").string(), exr.encoding); !s) return s;
    if (Status s = output::writeGridRaw(result, p.grid, (dir / "grid.raw").string(), exr.encoding); !s) return s;
    if (Status s = output::writeThreeJsGrid(result, p.grid, (dir / "grid_threejs.json").string(), "grid_threejs.bin");
        !s)
      return s;
    f.outputs.insert(f.outputs.end(), {"grid.json", "grid.raw", "grid_threejs.json", "grid_threejs.bin"});
  }
  return f;
}

void addWriterWarnings(const WrittenFiles& f, const std::string& prefix, std::vector<std::string>& warnings) {
  if (f.lightmap_clamped + f.grid_clamped > 0)
    warnings.push_back(fmt::format("{}EXR outputs: {} values beyond the half range were clamped "
                                   "(use --float)", prefix, f.lightmap_clamped + f.grid_clamped));
  if (f.lightmap_underflowed + f.grid_underflowed > 0)
    warnings.push_back(fmt::format("{}EXR outputs: {} non-zero values below the smallest normal "
                                   "half lost precision (use --float)",
                                   prefix, f.lightmap_underflowed + f.grid_underflowed));
}

struct ScenarioFile {
  std::string path;
  relight::LightSet lights;
};

// "NAME=FILE": the base light set with FILE applied, its name checked as a folder name.
Expected<std::pair<std::string, ScenarioFile>> parseScenarioOption(const std::string& spec,
                                                                   const relight::LightSet& base,
                                                                   std::size_t material_count) {
  const auto eq = spec.find('=');
  if (eq == std::string::npos || eq + 1 == spec.size())
    return invalidInput("--scenario {}: expected NAME=LIGHTS.json", spec);
  const std::string name = spec.substr(0, eq);
  if (Status s = lights::validateScenarioName(name, "--scenario"); !s) return s;
  ScenarioFile f{spec.substr(eq + 1), base};
  if (Status s = f.lights.applyFile(f.path); !s)
    return Status(s.code(), fmt::format("--scenario {}: {}", name, s.message()));
  if (Status s = f.lights.checkMaterials(material_count); !s)
    return Status(s.code(), fmt::format("--scenario {}: {}", name, s.message()));
  return std::pair{name, std::move(f)};
}

// scenarios.json: the scenarios a bake wrote and how an engine blends them.
Status writeScenarioManifest(const nlohmann::ordered_json& reports, const fs::path& path) {
  nlohmann::ordered_json m;
  m["format"] = "lightlink.scenarios";
  m["version"] = 1;
  m["blend"] = "linear: the lighting of weights w_k is sum_k w_k * lighting_k, per SH coefficient, texel and "
               "grid point (docs/outputs.md \"Lighting scenarios\")";
  nlohmann::ordered_json list = nlohmann::ordered_json::array();
  for (const auto& r : reports)
    list.push_back({{"name", r["name"]}, {"folder", r["folder"]}, {"lights", r["lights"]}, {"light_set", r["light_set"]},
                    {"outputs", r["outputs"]}});
  m["scenarios"] = std::move(list);
  return output::writeReportJson(m, path.string());
}

// What reopens this bake's precompute (and so its lightmap atlas) elsewhere: the scene's
// absolute path and the bake options as given (OpenScene takes the same names), the light
// set, and which glTF node holds each light id (for viewers that move lights).
nlohmann::ordered_json sourceJson(const BakeArgs& args, const relight::LightSet& lights) {
  std::error_code ec;
  fs::path scene = fs::absolute(args.scene_path, ec);
  if (ec) scene = args.scene_path;
  nlohmann::ordered_json options = nlohmann::ordered_json::object();
  for (const auto& [name, value] : args.options) options[name] = value;
  nlohmann::ordered_json nodes = nlohmann::ordered_json::object();
  for (const auto& e : lights.lights())
    if (e.light.gltf_node >= 0) nodes[e.id] = e.light.gltf_node;
  return {{"scene", scene.lexically_normal().string()}, {"options", std::move(options)}, {"light_set", "lights.json"},
          {"light_nodes", std::move(nodes)}};
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
  auto encoding = output::parseEncoding(args.encoding);
  if (!encoding) return reportError(kCmd, encoding.status());

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
  // --scenario NAME=FILE: each a light-set file applied over the same base (the scene's
  // lights and --lights), checked before the precompute's result is used for anything.
  std::vector<std::pair<std::string, ScenarioFile>> scenarios;
  for (const std::string& spec : args.scenarios) {
    auto sc = parseScenarioOption(spec, lights, scene.materials.size());
    if (!sc) return reportError(kCmd, sc.status());
    for (const auto& [name, f] : scenarios)
      if (name == sc->first) return reportError(kCmd, invalidInput("--scenario {}: named twice", name));
    scenarios.push_back(std::move(sc).value());
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

  output::ExrOptions exr;
  exr.half = !args.float_exr;
  exr.scene_hash = key_hex;
  exr.encoding = *encoding;
  const auto t_write = std::chrono::steady_clock::now();
  auto written = writeLightingFiles(*result, p, out, exr);
  if (!written) return reportError(kCmd, written.status());
  addWriterWarnings(*written, "", findings.warnings);
  const double write_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_write).count();

  // Lighting scenarios: one relight each over the same precomputation, written under
  // scenarios/<name>/ (docs/outputs.md "Lighting scenarios").
  nlohmann::ordered_json scenario_reports = nlohmann::ordered_json::array();
  for (const auto& [name, file] : scenarios) {
    bar.begin("scenario " + name, 0);
    relight::RelightResult sr;
    const Status st = (*backend)->relightInto(file.lights, relight_options, sr);
    bar.end();
    if (!st) return reportError(kCmd, Status(st.code(), fmt::format("scenario \"{}\": {}", name, st.message())));
    const fs::path dir = out / "scenarios" / name;
    if (Status s = makeDirectory(dir); !s) return reportError(kCmd, s);
    auto sf = writeLightingFiles(sr, p, dir, exr);
    if (!sf) return reportError(kCmd, sf.status());
    // The scenario's whole light set, so a daemon can take the scenario over (the gateway's
    // live mode, docs/web.md) without the file the bake was given.
    if (Status s = file.lights.save((dir / "lights.json").string()); !s) return reportError(kCmd, s);
    sf->outputs.push_back("lights.json");
    addWriterWarnings(*sf, "scenario " + name + ": ", findings.warnings);
    const BakeFindings sfind = collectFindings(scene, resident->precomputeReport(), sr);
    for (const std::string& w : sfind.warnings) findings.warnings.push_back("scenario " + name + ": " + w);
    scenario_reports.push_back({{"name", name},
                                {"lights", file.path},
                                {"light_set", "scenarios/" + name + "/lights.json"},
                                {"folder", "scenarios/" + name},
                                {"relight_ms", sr.totalSeconds() * 1e3},
                                {"lighting", {{"no_light", sfind.no_light}, {"all_black", sfind.all_black}}},
                                {"outputs", sf->outputs},
                                {"relight", sr.report()}});
  }
  if (!scenarios.empty()) {
    if (Status s = writeScenarioManifest(scenario_reports, out / "scenarios.json"); !s) return reportError(kCmd, s);
  }
  // After the progress bar's last line, so no redraw hides them; with -q too.
  printWarnings(findings, stderr);

  std::vector<std::string> outputs = written->outputs;
  // The light set this bake relit with, whole (the scene's lights with --lights applied).
  if (Status s = lights.save((out / "lights.json").string()); !s) return reportError(kCmd, s);
  outputs.push_back("lights.json");
  outputs.push_back("report.json");
  // The lightmapped scene, always (a kept TEXCOORD_1 too), pointing at the files above:
  // MOZ_lightmap binds the plain irradiance map only where this bake wrote one.
  const output::LightingFiles files =
      output::LightingFiles::fromWritten(written->outputs, std::string(output::encodingName(*encoding)));
  charts::GltfLighting gltf_lighting;
  gltf_lighting.irradiance_uri = files.irradiance;
  gltf_lighting.description = output::describeLighting(*result, p.has_grid ? &p.grid : nullptr, files);
  const std::string gltf_name = fs::path(args.scene_path).stem().string() + "_lm" +
                                (fs::path(args.scene_path).extension() == ".glb" ? ".glb" : ".gltf");
  if (Status s = charts::writeGltfWithLightmapUv(args.scene_path, scene, atlas, (out / gltf_name).string(),
                                                 request.load.files, gltf_lighting);
      !s)
    return reportError(kCmd, s);
  outputs.push_back(gltf_name);

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
  report["source"] = sourceJson(args, lights);
  report["backend"] = {{"requested", args.backend}, {"used", result->backend}, {"note", backend_note}};
  report["isa"] = {{"cpu", isaName(cpuIsa())}, {"used", isaName(activeIsa())}};
  report["precompute"] = resident->precomputeReport();
  report["relight"] = result->report();
  report["effects_plan"] = result->plan.toJson();
  report["half_clamped_values"] = {{"lightmap", written->lightmap_clamped}, {"grid", written->grid_clamped}};
  report["half_underflowed_values"] = {{"lightmap", written->lightmap_underflowed}, {"grid", written->grid_underflowed}};
  report["encoding"] = {{"name", output::encodingName(*encoding)},
                        {"lightmap_bands", output::lightmapBands(*encoding, result->bands)},
                        {"grid_bands", p.has_grid ? output::gridBands(*encoding, result->bands) : 0},
                        {"exr_layout", output::kExrLayout},
                        {"precision", exr.half ? "half" : "float"},
                        {"write_seconds", write_s}};
  if (!scenarios.empty()) outputs.push_back("scenarios.json");
  if (!scenarios.empty()) report["scenarios"] = scenario_reports;
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
    for (const auto& sr : scenario_reports)
      text += fmt::format("scenario     {}: relight {:.2f} ms, wrote {}/\n", sr["name"].get<std::string>(),
                          sr["relight_ms"].get<double>(), sr["folder"].get<std::string>());
    std::fwrite(text.data(), 1, text.size(), stdout);
  }
  return bakeExitCode(findings, *fail_on);
}

}  // namespace lightlink::cli
