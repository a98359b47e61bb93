// The `lightlink` commands that talk to a daemon through lightlink_client: open, set-light,
// watch, pull, lights, uvs (docs/cli.md "Daemon commands", docs/clients.md).
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "clients/client/client.h"
#include "clients/client/result_files.h"
#include "clients/client/session.h"
#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"
#include "core/bake/bake_options.h"
#include "core/output/output.h"

namespace lightlink::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

// Flushed at once: `watch` output is read line by line by scripts while it runs.
void print(const std::string& text) {
  std::fwrite(text.data(), 1, text.size(), stdout);
  std::fflush(stdout);
}

struct Remote {
  client::Client client;
  client::Session session;  // target + scene (scene empty when not needed)
};

Expected<client::Vec3> vec3Of(const std::vector<float>& v, const char* flag) {
  if (v.size() != 3) return invalidInput("{}: expected x,y,z (3 numbers), got {}", flag, v.size());
  return client::Vec3{v[0], v[1], v[2]};
}

// Connects and names the scene: from the session file, overridden by explicit flags.
Expected<Remote> connect(const RemoteArgs& a, bool need_scene) {
  client::Session s;
  if (!a.session.empty() && need_scene) {
    auto loaded = client::loadSession(a.session);
    if (!loaded) return loaded.status();
    s = std::move(loaded).value();
  }
  if (!a.target.empty()) s.target = a.target;
  if (s.target.empty()) s.target = "127.0.0.1:50051";
  if (!a.scene_id.empty()) {
    if (a.scene_token.empty()) return invalidInput("--scene-token: required with --scene");
    s.scene = client::SceneHandle::fromIdToken(a.scene_id, a.scene_token);
  }
  if (need_scene && s.scene.id.empty())
    return invalidInput("no scene: give --session FILE (written by `lightlink open --session`) or --scene and "
                        "--scene-token");
  client::ConnectOptions o;
  o.target = s.target;
  if (!a.token.empty()) return invalidInput("{}", client::tokenInArgvMessage("--token"));
  auto bearer = client::bearerTokenFrom(a.token_file);
  if (!bearer) return bearer.status();
  o.bearer_token = *bearer;
  o.tls_root_cert = a.tls_ca;
  if (a.timeout_ms < 0) return invalidInput("--timeout {} must not be negative", a.timeout_ms);
  o.call_timeout = std::chrono::milliseconds(a.timeout_ms);
  // Waiting for the connection is part of the first call's budget.
  if (a.timeout_ms > 0) o.connect_timeout = std::min(o.connect_timeout, std::chrono::milliseconds(a.timeout_ms));
  auto c = client::Client::connect(o);
  if (!c) return c.status();
  return Remote{std::move(c).value(), std::move(s)};
}

}  // namespace

int runOpen(const OpenArgs& args) {
  constexpr const char* kCmd = "open";
  // The daemon checks the options again; checking them here fails before connecting.
  if (auto checked = bake::buildBakeOptions(args.options, "medium"); !checked)
    return reportError(kCmd, checked.status());
  if (args.upload) {
    // An upload is one file: only a self-contained glTF can travel that way (OBJ's MTL and
    // textures, FBX's external files, would stay behind).
    std::string ext = fs::path(args.scene_path).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".gltf" && ext != ".glb")
      return reportError(kCmd, invalidInput("{}: --upload sends one self-contained .gltf or .glb file; open this "
                                            "scene by path (without --upload) on a daemon that can read it",
                                            args.scene_path));
  }
  auto remote = connect(args.remote, false);
  if (!remote) return reportError(kCmd, remote.status());
  client::OpenOptions o;
  for (const auto& [name, value] : args.options) o.options[name] = value;  // the last one given wins
  if (args.upload) {
    std::FILE* f = std::fopen(args.scene_path.c_str(), "rb");
    if (!f) return reportError(kCmd, notFound("{}: cannot open scene", args.scene_path));
    char buf[1 << 16];
    for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, f)) > 0;) o.gltf_bytes.append(buf, n);
    std::fclose(f);
  } else {
    std::error_code ec;
    const fs::path abs = fs::absolute(args.scene_path, ec);
    o.path = ec ? args.scene_path : abs.string();
  }
  o.name = args.name.empty() ? fs::path(args.scene_path).stem().string() : args.name;
  if (args.backend == "cpu") o.backend = v1::BACKEND_CPU;
  else if (args.backend == "gpu") o.backend = v1::BACKEND_GPU;
  else if (args.backend != "auto")
    return reportError(kCmd, invalidInput("--backend '{}' must be auto, cpu or gpu", args.backend));
  if (!args.lights_path.empty()) {
    std::FILE* f = std::fopen(args.lights_path.c_str(), "rb");
    if (!f) return reportError(kCmd, notFound("{}: cannot open light set", args.lights_path));
    char buf[1 << 16];
    for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, f)) > 0;) o.lightset_json.append(buf, n);
    std::fclose(f);
  }
  // Progress goes to stderr, one line per stage, so stdout stays one JSON document.
  std::string last_stage;
  auto scene = remote->client.openScene(o, [&](const v1::OpenSceneProgress& p) {
    if (p.stage() != last_stage) {
      std::fprintf(stderr, "lightlink open: %s %s\n", p.stage().c_str(), p.message().c_str());
      last_stage = p.stage();
    }
  });
  if (!scene) return reportError(kCmd, scene.status());
  if (!args.remote.session.empty()) {
    client::Session s{remote->session.target, *scene};
    if (Status st = client::saveSession(args.remote.session, s); !st) return reportError(kCmd, st);
  }
  print(client::sceneOpenedJson(scene->info, true) + "\n");
  return kExitOk;
}

int runSetLight(const SetLightArgs& args) {
  constexpr const char* kCmd = "set-light";
  auto remote = connect(args.remote, true);
  if (!remote) return reportError(kCmd, remote.status());
  client::SceneHandle& scene = remote->session.scene;
  client::LightUpdate update;
  const bool per_field = !args.type.empty() || !args.position.empty() || !args.direction.empty() ||
                         !args.color.empty() || args.intensity || args.range || args.inner_cone_angle ||
                         args.outer_cone_angle || !args.baked.empty();
  if (!args.json_path.empty()) {
    if (!args.light_id.empty() || per_field || args.add || args.remove)
      return reportError(kCmd, invalidInput("--json: give either a light-set file or a light id with fields"));
    auto u = client::LightUpdate::fromLightSetFile(args.json_path, scene.ids_known ? &scene.light_ids : nullptr);
    if (!u) return reportError(kCmd, u.status());
    update = std::move(u).value();
  } else {
    if (args.light_id.empty()) return reportError(kCmd, invalidInput("a light id (or --json FILE) is required"));
    if (args.remove) {
      if (per_field || args.add) return reportError(kCmd, invalidInput("--remove takes no other light fields"));
      if (Status s = update.remove(args.light_id); !s) return reportError(kCmd, s);
    } else {
      client::LightFields f;
      f.id = args.light_id;
      if (!args.type.empty()) {
        auto t = client::parseLightType(args.type);
        if (!t) return reportError(kCmd, invalidInput("--type: {}", t.status().message()));
        f.type = *t;
      }
      for (auto [values, dst, flag] : {std::tuple{&args.position, &f.position, "--position"},
                                       std::tuple{&args.direction, &f.direction, "--direction"},
                                       std::tuple{&args.color, &f.color, "--color"}}) {
        if (values->empty()) continue;
        auto v = vec3Of(*values, flag);
        if (!v) return reportError(kCmd, v.status());
        *dst = *v;
      }
      f.intensity = args.intensity;
      f.range = args.range;
      f.inner_cone_angle = args.inner_cone_angle;
      f.outer_cone_angle = args.outer_cone_angle;
      if (args.baked == "true") f.baked = true;
      else if (args.baked == "false") f.baked = false;
      else if (!args.baked.empty())
        return reportError(kCmd, invalidInput("--baked '{}' must be true or false", args.baked));
      if (!per_field && !args.add) return reportError(kCmd, invalidInput("nothing to change: give a field to set"));
      const bool add = args.add || (scene.ids_known && !scene.light_ids.contains(f.id));
      if (Status s = add ? update.add(f) : update.modify(f); !s) return reportError(kCmd, s);
    }
  }
  if (args.wait_ms < 0) return reportError(kCmd, invalidInput("--wait-ms {} must not be negative", args.wait_ms));

  // Latency as a client sees it: from sending the update to holding the new version's
  // lightmap (UpdateLights waits for the relight, then one GetTextures fetches it).
  const auto t0 = Clock::now();
  auto r = remote->client.updateLights(scene, update, args.wait ? std::uint32_t(args.wait_ms) : 0);
  if (!r) return reportError(kCmd, r.status());
  const double ack_ms = msSince(t0);
  nlohmann::ordered_json out;
  out["version"] = r->version;
  std::string text = fmt::format("version {}", r->version);
  if (args.wait) {
    if (!r->relit)
      return reportError(kCmd, ioError("version {} was not relit within --wait-ms {}", r->version, args.wait_ms));
    client::ResultSpec spec;
    spec.grid = false;
    auto t = remote->client.getTextures(scene, 0, spec);
    if (!t) return reportError(kCmd, t.status());
    const double total_ms = msSince(t0);
    if (!t->has_value() || (*t)->info.version < r->version)
      return reportError(kCmd, internalError("GetTextures returned an older version than {}", r->version));
    const client::Textures& tex = **t;
    out["relit"] = true;
    out["result_version"] = tex.info.version;
    out["latency_ms"] = total_ms;
    out["update_ms"] = ack_ms;
    out["fetch_ms"] = total_ms - ack_ms;
    out["relight_ms"] = tex.info.relight_ms;
    out["bytes"] = tex.totalBytes();
    text += fmt::format(": light change to texture {:.1f} ms (update + relight {:.1f} ms, relight {:.1f} ms, fetch "
                        "{:.1f} ms of {} KiB)",
                        total_ms, ack_ms, tex.info.relight_ms, total_ms - ack_ms, tex.totalBytes() / 1024);
  }
  print(args.json ? out.dump() + "\n" : text + "\n");
  // Keep the session's light ids current for the next command.
  if (!args.remote.session.empty() && scene.ids_known)
    if (Status s = client::saveSession(args.remote.session, remote->session); !s) return reportError(kCmd, s);
  return kExitOk;
}

int runScenario(const ScenarioArgs& args) {
  constexpr const char* kCmd = "scenario";
  if (args.action == "set") {
    if (args.names.size() != 1) return reportError(kCmd, invalidInput("set: give exactly one scenario name"));
    const int sources = int(!args.lights_path.empty()) + int(args.from_current) + int(args.remove);
    if (sources != 1) return reportError(kCmd, invalidInput("set: give one of --lights FILE, --from-current, --remove"));
    std::string text;
    if (!args.lights_path.empty()) {
      // Checked here first, so a mistake names the file before anything is sent.
      auto patch = lights::LightSetPatch::load(args.lights_path);
      if (!patch) return reportError(kCmd, patch.status());
      std::ifstream in(args.lights_path, std::ios::binary);
      text.assign(std::istreambuf_iterator<char>(in), {});
    }
    auto remote = connect(args.remote, true);
    if (!remote) return reportError(kCmd, remote.status());
    auto names = args.remove ? remote->client.removeScenario(remote->session.scene, args.names[0])
                             : remote->client.setScenario(remote->session.scene, args.names[0], text);
    if (!names) return reportError(kCmd, names.status());
    std::string line = "scenarios:";
    for (const std::string& n : *names) line += " " + n;
    print(line + "\n");
    return kExitOk;
  }
  if (args.action == "use") {
    if (args.names.empty()) return reportError(kCmd, invalidInput("use: give NAME[=WEIGHT] ..."));
    if (args.wait_ms < 0) return reportError(kCmd, invalidInput("--wait-ms {} must not be negative", args.wait_ms));
    std::vector<lights::ScenarioWeight> weights;
    for (const std::string& spec : args.names) {
      auto w = lights::parseScenarioWeight(spec);
      if (!w) return reportError(kCmd, w.status());
      weights.push_back(*w);
    }
    auto remote = connect(args.remote, true);
    if (!remote) return reportError(kCmd, remote.status());
    auto r = remote->client.useScenarios(remote->session.scene, weights, args.wait ? std::uint32_t(args.wait_ms) : 0);
    if (!r) return reportError(kCmd, r.status());
    if (args.wait && !r->relit)
      return reportError(kCmd, ioError("version {} was not relit within --wait-ms {}", r->version, args.wait_ms));
    print(fmt::format("version {}{}\n", r->version, args.wait ? " (relit)" : ""));
    // The blend renamed the lights: the session forgets the ids it knew.
    if (!args.remote.session.empty())
      if (Status s = client::saveSession(args.remote.session, remote->session); !s) return reportError(kCmd, s);
    return kExitOk;
  }
  return reportError(kCmd, invalidInput("'{}': the actions are set and use", args.action));
}

int runWatch(const WatchArgs& args) {
  constexpr const char* kCmd = "watch";
  if (args.count < 0) return reportError(kCmd, invalidInput("--count {} must not be negative", args.count));
  auto remote = connect(args.remote, true);
  if (!remote) return reportError(kCmd, remote.status());
  auto sub = remote->client.subscribe(remote->session.scene, {}, !args.full);
  if (!sub) return reportError(kCmd, sub.status());
  int seen = 0;
  auto prev = Clock::now();
  for (;;) {
    auto t = (*sub)->next();
    if (!t) return reportError(kCmd, t.status());
    if (*t == nullptr) break;
    const auto now = Clock::now();
    const double interval_ms = std::chrono::duration<double, std::milli>(now - prev).count();
    prev = now;
    const client::ResultInfo& i = (*t)->info;
    const std::size_t tiles = std::size_t(i.tilesX()) * std::size_t(i.tilesY());
    if (args.json) {
      nlohmann::ordered_json j;
      j["version"] = i.version;
      j["delta"] = i.delta;
      j["relight_ms"] = i.relight_ms;
      j["interval_ms"] = interval_ms;
      j["payload_bytes"] = i.payload_bytes;
      j["changed_tiles"] = i.delta ? i.changed_tiles.size() : tiles;
      j["tiles"] = tiles;
      j["skipped_versions"] = i.skipped_versions;
      j["coalesced_updates"] = i.coalesced_updates;
      print(j.dump() + "\n");
    } else {
      print(fmt::format("version {:>6}  relight {:7.2f} ms  since last {:8.1f} ms  {:>9} bytes  {} {}/{} tiles  "
                        "skipped {}  coalesced {}\n",
                        i.version, i.relight_ms, interval_ms, i.payload_bytes, i.delta ? "delta" : "full ",
                        i.delta ? i.changed_tiles.size() : tiles, tiles, i.skipped_versions, i.coalesced_updates));
    }
    if (args.count > 0 && ++seen >= args.count) {
      (*sub)->cancel();
      break;
    }
  }
  return kExitOk;
}

int runClose(const RemoteArgs& args) {
  constexpr const char* kCmd = "close";
  auto remote = connect(args, true);
  if (!remote) return reportError(kCmd, remote.status());
  if (Status s = remote->client.closeScene(remote->session.scene); !s) return reportError(kCmd, s);
  print(fmt::format("closed       {}\n", remote->session.scene.id));
  return kExitOk;
}

int runPull(const PullArgs& args) {
  constexpr const char* kCmd = "pull";
  if (args.bands < 0 || args.bands > 4) return reportError(kCmd, invalidInput("--bands {} is out of range (0..4)", args.bands));
  auto remote = connect(args.remote, true);
  if (!remote) return reportError(kCmd, remote.status());
  client::ResultSpec spec;
  spec.bands = args.bands;
  spec.precision = args.float_exr ? client::Precision::kFloat : client::Precision::kHalf;
  const auto t0 = Clock::now();
  auto tex = remote->client.relight(remote->session.scene, args.version, spec);
  if (!tex) return reportError(kCmd, tex.status());
  const double fetch_ms = msSince(t0);
  const fs::path out(args.output_dir);
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) return reportError(kCmd, ioError("cannot create directory {}: {}", out.string(), ec.message()));
  auto encoding = output::parseEncoding(args.encoding);
  if (!encoding) return reportError(kCmd, encoding.status());
  client::ResultFileOptions file_options;
  file_options.encoding = *encoding;
  file_options.half = !args.float_exr;
  file_options.scene_hash = remote->session.scene.info.cache_key();
  auto files = client::writeResultFiles(*tex, out.string(), file_options);
  if (!files) return reportError(kCmd, files.status());
  const std::vector<std::string>& written = files->files;
  nlohmann::ordered_json info;
  info["scene_id"] = remote->session.scene.id;
  info["version"] = tex->info.version;
  info["backend"] = tex->info.backend;
  info["bands"] = tex->info.bands;
  info["precision"] = args.float_exr ? "float" : "half";
  info["encoding"] = output::encodingName(*encoding);
  info["lightmap"] = {{"width", tex->info.width}, {"height", tex->info.height}};
  info["relight_ms"] = tex->info.relight_ms;
  info["fetch_ms"] = fetch_ms;
  info["payload_bytes"] = tex->info.payload_bytes;
  info["outputs"] = written;
  if (Status s = output::writeReportJson(info, (out / "pull.json").string()); !s) return reportError(kCmd, s);
  if (!args.quiet) {
    std::string text = fmt::format("pulled       version {} ({}x{} texels, {} bands, {} KiB in {:.1f} ms)\nwrote        {}: ",
                                   tex->info.version, tex->info.width, tex->info.height, tex->info.bands,
                                   tex->info.payload_bytes / 1024, fetch_ms, out.string());
    for (const auto& w : written) text += w + ", ";
    text += "pull.json\n";
    print(text);
  }
  return kExitOk;
}

int runLights(const LightsArgs& args) {
  constexpr const char* kCmd = "lights";
  auto remote = connect(args.remote, true);
  if (!remote) return reportError(kCmd, remote.status());
  auto state = remote->client.getLights(remote->session.scene);
  if (!state) return reportError(kCmd, state.status());
  std::string text = state->json;
  if (text.empty() || text.back() != '\n') text += '\n';
  if (args.output_path.empty()) {
    print(text);
    return kExitOk;
  }
  std::ofstream out(args.output_path, std::ios::binary | std::ios::trunc);
  out << text;
  if (!out) return reportError(kCmd, ioError("{}: write failed", args.output_path));
  std::fprintf(stderr, "lightlink lights: version %llu, %zu lights -> %s\n",
               static_cast<unsigned long long>(state->version), state->lights.size(), args.output_path.c_str());
  return kExitOk;
}

int runUvs(const UvsArgs& args) {
  constexpr const char* kCmd = "uvs";
  auto remote = connect(args.remote, true);
  if (!remote) return reportError(kCmd, remote.status());
  auto uvs = remote->client.getLightmapUvs(remote->session.scene, !args.gltf_path.empty());
  if (!uvs) return reportError(kCmd, uvs.status());
  if (!args.gltf_path.empty()) {
    std::ofstream out(args.gltf_path, std::ios::binary | std::ios::trunc);
    out.write(uvs->glb.data(), static_cast<std::streamsize>(uvs->glb.size()));
    if (!out) return reportError(kCmd, ioError("{}: write failed", args.gltf_path));
  }
  std::size_t lit = 0, vertices = 0;
  nlohmann::ordered_json meshes = nlohmann::ordered_json::array();
  for (const auto& m : uvs->meshes) {
    lit += m.lightmapped;
    vertices += m.uv.size() / 2;
    if (args.json_path.empty()) continue;
    nlohmann::ordered_json j;
    j["name"] = m.name;
    j["node"] = m.node;
    j["mesh"] = m.mesh;
    j["primitive"] = m.primitive;
    j["lightmapped"] = m.lightmapped;
    j["source_vertex"] = m.source_vertex;
    j["uv"] = m.uv;
    j["indices"] = m.indices;
    meshes.push_back(std::move(j));
  }
  if (!args.json_path.empty()) {
    nlohmann::ordered_json doc;
    doc["width"] = uvs->width;
    doc["height"] = uvs->height;
    doc["texel_size_m"] = uvs->texel_size_m;
    doc["generated"] = uvs->generated;
    doc["meshes"] = std::move(meshes);
    std::ofstream out(args.json_path, std::ios::binary | std::ios::trunc);
    out << doc.dump() << "\n";
    if (!out) return reportError(kCmd, ioError("{}: write failed", args.json_path));
  }
  print(fmt::format("lightmap     {}x{} texels, {:.4g} m per texel, UVs {}\nmeshes       {} ({} lightmapped, {} "
                    "lightmap vertices)\n",
                    uvs->width, uvs->height, uvs->texel_size_m, uvs->generated ? "generated by the daemon" : "the scene's own",
                    uvs->meshes.size(), lit, vertices));
  if (!args.gltf_path.empty()) print(fmt::format("wrote        {} ({} bytes)\n", args.gltf_path, uvs->glb.size()));
  return kExitOk;
}

}  // namespace lightlink::cli
