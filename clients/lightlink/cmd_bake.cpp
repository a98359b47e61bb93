// `lightlink bake`: the CI job. Scene -> (unwrap) -> precompute (or a matching cached
// artifact) -> relight with the scene's lights (+ a light-set file) -> EXR lightmap and
// grid in the chosen encoding (l0, l1, l2) and the grid's three.js form, PNG preview, the
// glTF with TEXCOORD_1 that points at all of them, and one JSON report; with --scenario, the
// lighting of each scenario in its own folder. Several scenes (or --batch): a batch, one
// folder each under the output directory, one artifact cache for all, going on past a scene
// that fails, with one summary (JSON and JUnit XML, batch_summary.h).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <new>

#include <fmt/format.h>

#include "clients/lightlink/bake_findings.h"
#include "clients/lightlink/batch_summary.h"
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
nlohmann::ordered_json sourceJson(const BakeArgs& args, const std::string& scene_path,
                                  const relight::LightSet& lights) {
  std::error_code ec;
  fs::path scene = fs::absolute(scene_path, ec);
  if (ec) scene = scene_path;
  nlohmann::ordered_json options = nlohmann::ordered_json::object();
  for (const auto& [name, value] : args.options) options[name] = value;
  nlohmann::ordered_json nodes = nlohmann::ordered_json::object();
  for (const auto& e : lights.lights())
    if (e.light.gltf_node >= 0) nodes[e.id] = e.light.gltf_node;
  return {{"scene", scene.lexically_normal().string()}, {"options", std::move(options)}, {"light_set", "lights.json"},
          {"light_nodes", std::move(nodes)}};
}

// One scene's bake into `out`, its artifact cached in `cache_dir`; what happened goes into
// `outcome` (the batch summary) as well as stderr. Returns the scene's exit code.
int bakeScene(const BakeArgs& args, const std::string& scene_path, const fs::path& out, const fs::path& cache_dir,
              SceneOutcome& outcome) {
  constexpr const char* kCmd = "bake";
  // An error is printed and recorded; the batch goes on with the next scene.
  auto fail = [&](const Status& s) {
    outcome.message = s.message();
    outcome.exit_code = reportError(kCmd, s);
    return outcome.exit_code;
  };
  auto bake_options = bake::buildBakeOptions(args.options, "medium");
  if (!bake_options) return fail(bake_options.status());
  const relight::RelightOptions relight_options = bake_options->relight;
  auto backend_choice = gpu::parseBackendChoice(args.backend, "--backend");
  if (!backend_choice) return fail(backend_choice.status());

  auto fail_on = parseFailOn(args.fail_on);
  if (!fail_on) return fail(fail_on.status());
  auto encoding = output::parseEncoding(args.encoding);
  if (!encoding) return fail(encoding.status());

  if (Status s = makeDirectory(out); !s) return fail(s);
  ProgressBar bar(!args.quiet);

  // Load the scene, then reuse a matching artifact or precompute and save one.
  precompute::ResidentRequest request;
  request.scene_path = scene_path;
  request.load.files = sceneFileAccess(args.allow_outside_scene);
  request.options = bake_options->precompute;
  request.cache_dir = cache_dir.string();
  request.use_cache = !args.no_cache;
  auto resident = precompute::ResidentScene::open(request, &bar);
  if (!resident) return fail(resident.status());
  const scene::Scene& scene = resident->scene();
  const precompute::Precomputation& p = resident->precomputation();
  const charts::LightmapAtlas& atlas = resident->atlas();
  const std::string key_hex = resident->cacheKeyHex();
  const std::string& artifact_note = resident->note();
  outcome.artifact = artifact_note;
  outcome.cache_key = key_hex;

  auto lights = relight::LightSet::fromSceneLights(scene.lights);
  if (!args.lights_path.empty()) {
    if (Status s = lights.applyFile(args.lights_path); !s) return fail(s);
  }
  // --scenario NAME=FILE: each a light-set file applied over the same base (the scene's
  // lights and --lights), checked before the precompute's result is used for anything.
  std::vector<std::pair<std::string, ScenarioFile>> scenarios;
  for (const std::string& spec : args.scenarios) {
    auto sc = parseScenarioOption(spec, lights, scene.materials.size());
    if (!sc) return fail(sc.status());
    for (const auto& [name, f] : scenarios)
      if (name == sc->first) return fail(invalidInput("--scenario {}: named twice", name));
    scenarios.push_back(std::move(sc).value());
  }
  // cpu, gpu or auto: the note says which ran and, for a fallback, why.
  std::string backend_note;
  auto backend = gpu::makeBackend(*backend_choice, scene, resident->accel(), p, resident->lightmapLinks(),
                                  resident->gridLinks(), &backend_note);
  if (!backend) return fail(backend.status());
  bar.begin("relight", 0);
  Expected<relight::RelightResult> result = relight::RelightResult{};
  const Status relit = (*backend)->relightInto(lights, relight_options, *result);
  bar.end();
  if (!relit) return fail(relit);
  BakeFindings findings = collectFindings(scene, resident->precomputeReport(), *result);

  output::ExrOptions exr;
  exr.half = !args.float_exr;
  exr.scene_hash = key_hex;
  exr.encoding = *encoding;
  const auto t_write = std::chrono::steady_clock::now();
  auto written = writeLightingFiles(*result, p, out, exr);
  if (!written) return fail(written.status());
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
    if (!st) return fail(Status(st.code(), fmt::format("scenario \"{}\": {}", name, st.message())));
    const fs::path dir = out / "scenarios" / name;
    if (Status s = makeDirectory(dir); !s) return fail(s);
    auto sf = writeLightingFiles(sr, p, dir, exr);
    if (!sf) return fail(sf.status());
    // The scenario's whole light set, so a daemon can take the scenario over (the gateway's
    // live mode, docs/web.md) without the file the bake was given.
    if (Status s = file.lights.save((dir / "lights.json").string()); !s) return fail(s);
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
    if (Status s = writeScenarioManifest(scenario_reports, out / "scenarios.json"); !s) return fail(s);
  }
  // After the progress bar's last line, so no redraw hides them; with -q too.
  printWarnings(findings, stderr);

  std::vector<std::string> outputs = written->outputs;
  // The light set this bake relit with, whole (the scene's lights with --lights applied).
  if (Status s = lights.save((out / "lights.json").string()); !s) return fail(s);
  outputs.push_back("lights.json");
  outputs.push_back("report.json");
  // The lightmapped scene, always (a kept TEXCOORD_1 too), pointing at the files above:
  // MOZ_lightmap binds the plain irradiance map only where this bake wrote one.
  const output::LightingFiles files =
      output::LightingFiles::fromWritten(written->outputs, std::string(output::encodingName(*encoding)));
  charts::GltfLighting gltf_lighting;
  gltf_lighting.irradiance_uri = files.irradiance;
  gltf_lighting.description = output::describeLighting(*result, p.has_grid ? &p.grid : nullptr, files);
  const std::string gltf_name = fs::path(scene_path).stem().string() + "_lm" +
                                (fs::path(scene_path).extension() == ".glb" ? ".glb" : ".gltf");
  if (Status s = charts::writeGltfWithLightmapUv(scene_path, scene, atlas, (out / gltf_name).string(),
                                                 request.load.files, gltf_lighting);
      !s)
    return fail(s);
  outputs.push_back(gltf_name);

  nlohmann::ordered_json report;
  report["lightlink"] = {{"version", lightlinkVersion()}, {"commit", lightlinkCommit()}};
  report["scene"] = scene_path;
  report["preset"] = bake_options->preset;
  report["warnings"] = findings.warnings;
  report["notes"] = findings.notes;
  report["lighting"] = {{"no_light", findings.no_light}, {"all_black", findings.all_black}};
  report["load"] = resident->loadReport();
  report["artifact"] = artifact_note;
  report["cache_key"] = key_hex;
  report["source"] = sourceJson(args, scene_path, lights);
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
  if (Status s = output::writeReportJson(report, (out / "report.json").string()); !s) return fail(s);

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
  outcome.outputs_written = true;
  outcome.warnings = findings.warnings.size();
  outcome.exit_code = bakeExitCode(findings, *fail_on);
  if (outcome.exit_code == kExitDark)
    outcome.message = findings.no_light ? "--fail-on: no light reaches the scene" : "--fail-on: the lightmap is all black";
  else if (outcome.exit_code == kExitWarnings)
    outcome.message = fmt::format("--fail-on warning: {} warnings (report.json)", findings.warnings.size());
  return outcome.exit_code;
}


// Output folder names of a batch: each scene's file stem, made unique with its extension and
// then a counter, in the order given (so a rerun writes the same folders).
std::vector<std::string> batchFolders(const std::vector<std::string>& scenes) {
  std::vector<std::string> folders;
  auto taken = [&](const std::string& f) {
    return f == "cache" || std::find(folders.begin(), folders.end(), f) != folders.end();
  };
  for (const std::string& scene : scenes) {
    const fs::path p(scene);
    std::string f = p.stem().string();
    if (f.empty() || f == "." || f == "..") f = "scene";
    if (taken(f) && p.has_extension()) f += "_" + p.extension().string().substr(1);
    const std::string base = f;
    for (int k = 2; taken(f); ++k) f = fmt::format("{}_{}", base, k);
    folders.push_back(f);
  }
  return folders;
}

}  // namespace

int runBake(const BakeArgs& args) {
  constexpr const char* kCmd = "bake";
  if (args.scene_paths.empty()) return reportError(kCmd, invalidInput("no scene given"));
  const fs::path out(args.output_dir);
  const fs::path cache_dir = args.cache_dir.empty() ? out / "cache" : fs::path(args.cache_dir);
  if (args.scene_paths.size() == 1 && !args.batch) {
    SceneOutcome outcome;
    return bakeScene(args, args.scene_paths[0], out, cache_dir, outcome);
  }
  // A batch: the options are checked once, up front (a typo fails the batch, not each scene).
  if (auto o = bake::buildBakeOptions(args.options, "medium"); !o) return reportError(kCmd, o.status());
  if (auto b = gpu::parseBackendChoice(args.backend, "--backend"); !b) return reportError(kCmd, b.status());
  if (auto f = parseFailOn(args.fail_on); !f) return reportError(kCmd, f.status());
  if (auto e = output::parseEncoding(args.encoding); !e) return reportError(kCmd, e.status());
  if (Status s = makeDirectory(out); !s) return reportError(kCmd, s);
  const auto batch_start = std::chrono::steady_clock::now();
  const std::vector<std::string> folders = batchFolders(args.scene_paths);
  std::vector<SceneOutcome> outcomes;
  int first_failure = kExitOk;
  for (std::size_t i = 0; i < args.scene_paths.size(); ++i) {
    SceneOutcome o;
    o.scene = args.scene_paths[i];
    o.folder = folders[i];
    if (!args.quiet) std::fprintf(stdout, "== [%zu/%zu] %s -> %s/\n", i + 1, args.scene_paths.size(), o.scene.c_str(),
                                  (out / o.folder).string().c_str());
    std::fflush(stdout);
    const auto start = std::chrono::steady_clock::now();
    // One scene running out of memory (or any other escape) stops that scene, not the batch.
    try {
      bakeScene(args, o.scene, out / o.folder, cache_dir, o);
    } catch (const std::bad_alloc&) {
      o.message = "out of memory";
      o.exit_code = reportError(kCmd, resourceExhausted("{}: out of memory", o.scene));
    } catch (const std::exception& e) {
      o.message = e.what();
      o.exit_code = reportError(kCmd, internalError("{}: {}", o.scene, e.what()));
    }
    o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (o.exit_code != kExitOk && first_failure == kExitOk) first_failure = o.exit_code;
    outcomes.push_back(std::move(o));
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - batch_start).count();
  if (Status s = writeBatchSummary(outcomes, seconds, out.string()); !s) return reportError(kCmd, s);
  std::size_t failed = 0;
  for (const SceneOutcome& o : outcomes) failed += o.exit_code != kExitOk;
  std::string text = fmt::format("batch        {} scenes: {} ok, {} failed in {:.1f} s; summary in {}\n",
                                 outcomes.size(), outcomes.size() - failed, failed, seconds,
                                 (out / "summary.json").string());
  for (const SceneOutcome& o : outcomes)
    if (o.exit_code != kExitOk)
      text += fmt::format("failed       {} (exit {}): {}\n", o.scene, o.exit_code, o.message);
  if (failed) std::fwrite(text.data(), 1, text.size(), stderr);
  else if (!args.quiet) std::fwrite(text.data(), 1, text.size(), stdout);
  // The first failed scene's code: a CI job branches on it as on a single bake's.
  return first_failure;
}

}  // namespace lightlink::cli
