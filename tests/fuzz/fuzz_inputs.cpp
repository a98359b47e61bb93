#include "tests/fuzz/fuzz_inputs.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <unordered_set>

#include <tbb/global_control.h>

#include "clients/viewer/baked_lighting.h"
#include "core/artifact/artifact.h"
#include "core/output/output.h"
#include "core/relight/light_set.h"
#include "core/relight/relight.h"
#include "core/rt/accel.h"
#include "core/scene/load.h"
#include "tests/common/scene_builders.h"

namespace lightlink::fuzz {
namespace {

namespace fs = std::filesystem;

// One private directory per process, so relative URIs in a fuzzed glTF resolve next to the
// input only and parallel fuzzers (-jobs) do not overwrite each other's files.
class Scratch {
 public:
  Scratch() {
    dir_ = fs::temp_directory_path() / fmt::format("lightlink-fuzz-{}", ::getpid());
    fs::create_directories(dir_);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string write(const char* name, std::span<const std::uint8_t> bytes) const {
    const fs::path path = dir_ / name;
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    if (!out) {
      std::fprintf(stderr, "fuzz: cannot write %s\n", path.c_str());
      std::abort();  // an environment problem, not a finding: stop loudly
    }
    return path.string();
  }

 private:
  fs::path dir_;
};

const Scratch& scratch() {
  static const Scratch s;
  return s;
}

// What a relight of a fuzzed artifact needs besides the artifact: the scene it was computed
// from (with the lightmap UVs precompute gave it) and its ray-tracing structure. Built once.
struct RelightContext {
  // One thread: a relight is bit-identical for any thread count, and a single thread keeps
  // ASan fast and a crash's stack readable.
  tbb::global_control threads{tbb::global_control::max_allowed_parallelism, 1};
  scene::Scene scene;
  std::optional<rt::Accel> accel;
  relight::LightSet lights;
};

const RelightContext& relightContext() {
  static const std::unique_ptr<RelightContext> ctx = [] {
    auto c = std::make_unique<RelightContext>();
    c->scene = fuzzScene();
    auto unwrap = precompute::unwrapFor(c->scene, fuzzOptions());
    auto accel = unwrap ? rt::Accel::build(c->scene) : Expected<rt::Accel>(unwrap.status());
    if (!accel) {
      std::fprintf(stderr, "fuzz: the fuzz scene does not build: %s\n", accel.status().message().c_str());
      std::abort();
    }
    c->accel.emplace(std::move(accel).value());
    c->lights = relight::LightSet::fromSceneLights(c->scene.lights);
    return c;
  }();
  return *ctx;
}

// The fuzz scene baked in memory, for relights with fuzzed light sets.
struct BakeContext {
  tbb::global_control threads{tbb::global_control::max_allowed_parallelism, 1};
  scene::Scene scene;
  precompute::Precomputation p;
  std::optional<rt::Accel> accel;
  std::optional<relight::Relighter> relighter;
  relight::LightSet lights;
};

BakeContext& bakeContext() {
  static const std::unique_ptr<BakeContext> ctx = [] {
    auto c = std::make_unique<BakeContext>();
    c->scene = fuzzScene();
    auto p = precompute::run(c->scene, fuzzOptions());
    auto accel = p ? rt::Accel::build(c->scene) : Expected<rt::Accel>(p.status());
    if (!accel) {
      std::fprintf(stderr, "fuzz: the fuzz scene does not bake: %s\n", accel.status().message().c_str());
      std::abort();
    }
    c->p = std::move(p).value();
    c->accel.emplace(std::move(accel).value());
    auto relighter = relight::Relighter::create(c->scene, *c->accel, c->p);
    if (!relighter) {
      std::fprintf(stderr, "fuzz: no relighter for the fuzz scene: %s\n", relighter.status().message().c_str());
      std::abort();
    }
    c->relighter.emplace(std::move(relighter).value());
    c->lights = relight::LightSet::fromSceneLights(c->scene.lights);
    return c;
  }();
  return *ctx;
}

Status relightOnce(const precompute::LoadedPrecomputation& loaded) {
  const RelightContext& ctx = relightContext();
  auto relighter = relight::Relighter::create(ctx.scene, *ctx.accel, loaded.p, loaded.lightmap_links,
                                              loaded.grid_links);
  if (!relighter) return relighter.status();
  relight::RelightOptions options;
  options.max_bounces = 1;
  options.emitter_samples = 1;
  for (relight::LinkForm form : {relight::LinkForm::kProjected, relight::LinkForm::kRuntime}) {
    options.link_form = form;
    auto result = relighter->relight(ctx.lights, options);
    if (!result) return result.status();
  }
  return Status::ok();
}

// Everything a reader of an artifact can ask of it, through the artifact API alone.
Status openAndWalk(const std::string& path) {
  // Header + table only, then each section verified and read on demand, as a fast reopen
  // does.
  auto lazy = artifact::Artifact::open(path, {.verify_payloads = false});
  if (lazy) {
    for (const artifact::SectionEntry& e : lazy->sections()) {
      const std::string name(e.name, strnlen(e.name, sizeof(e.name)));
      (void)lazy->verify(name);
      auto bytes = lazy->bytes(name);
      if (bytes && !bytes->empty()) {
        // Touch both ends of the payload: ASan flags a span that reaches past the mapping.
        volatile std::byte first = bytes->front(), last = bytes->back();
        (void)first;
        (void)last;
      }
    }
  }
  return precompute::open(path).status();
}

}  // namespace

const relight::LightSet& fuzzSceneLights() { return bakeContext().lights; }
std::size_t fuzzSceneMaterialCount() { return bakeContext().scene.materials.size(); }

Status relightFuzzScene(const relight::LightSet& lights) {
  // Mutations often produce a set already relit: relight each distinct set once (a relight
  // is deterministic), which keeps the light-set and request fuzzers' exec/s up.
  static std::unordered_set<std::string> relit;
  std::string key = lights.toJson().dump();
  if (relit.count(key) != 0) return Status::ok();
  // One fuzzer thread: the Relighter's scratch is not shared.
  relight::Relighter& relighter = *bakeContext().relighter;
  relight::RelightOptions options;
  options.max_bounces = 1;
  options.emitter_samples = 1;
  Status s = relighter.relight(lights, options).status();
  if (s) relit.insert(std::move(key));
  return s;
}

LightSetVerdict loadLightSetBytes(std::span<const std::uint8_t> bytes) {
  LightSetVerdict v;
  const std::string path = scratch().write("lights.json", bytes);
  auto set = relight::LightSet::load(path);
  v.load = set.status();
  if (set) {
    auto again = relight::LightSet::fromJson(set->toJson());
    if (!again)
      v.round_trip = internalError("a loaded light set does not load from its own toJson: {}", again.status().message());
    else if (again->toJson() != set->toJson())
      v.round_trip = internalError("a light set's toJson changes across a round trip");
  }
  relight::LightSet merged = fuzzSceneLights();
  v.apply = merged.applyFile(path);
  if (!v.apply && merged.toJson() != fuzzSceneLights().toJson())
    v.round_trip = internalError("a rejected light-set merge changed the set (it must be all or nothing)");
  // A light-set file knows no scene: its emissive overrides are checked against the scene's
  // materials where it meets one (LightSet::checkMaterials, as the daemon and Relighter do).
  if (v.apply) v.apply = merged.checkMaterials(fuzzSceneMaterialCount());
  if (v.apply) {
    v.relit = true;
    v.relight = relightFuzzScene(merged);
  }
  return v;
}

namespace {

// Samples a bake as `render` does, at points chosen to reach every edge case of the lookups.
void sampleLikeRender(const viewer::BakedLighting& b) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  glm::vec3 e;
  if (b.width > 0)
    for (const glm::vec2 uv : {glm::vec2(0.5f), glm::vec2(0.0f), glm::vec2(1.0f), glm::vec2(-7.0f, 3e9f),
                               glm::vec2(1e38f, -1e38f), glm::vec2(nan)})
      (void)b.sampleLightmap(uv, {0.0f, 1.0f, 0.0f}, e);
  if (b.has_grid) {
    const glm::vec3 mid = b.origin + 0.5f * b.spacing_m * glm::vec3(b.dims);
    for (const glm::vec3 p : {mid, b.origin, glm::vec3(-1e38f), glm::vec3(1e38f), glm::vec3(nan)})
      (void)b.sampleGrid(p, {0.0f, 0.0f, 1.0f}, e);
  }
}

}  // namespace

Status readLightmapExrBytes(std::span<const std::uint8_t> bytes) {
  const std::string path = scratch().write("lightmap.exr", bytes);
  viewer::ExrImage img;
  if (Status s = viewer::readLightlinkExr(path, img, std::uint64_t(1) << 16); !s) return s;
  // An irradiance map loads as an L0 bake and is sampled as render samples it.
  if (img.kind == "irradiance") {
    viewer::BakedLighting b;
    if (Status s = viewer::readIrradianceExr(path, b, std::uint64_t(1) << 16); !s) return s;
    sampleLikeRender(b);
  }
  return {};
}

Status readGridRawBytes(std::span<const std::uint8_t> bytes) {
  const std::string path = scratch().write("grid.raw", bytes);
  viewer::BakedLighting b;
  if (Status s = viewer::readGridRaw(path, b); !s) return s;
  sampleLikeRender(b);
  return {};
}

Status loadGltfBytes(std::span<const std::uint8_t> bytes) {
  const std::string path = scratch().write("in.gltf", bytes);
  return scene::loadGltf(path).status();
}

bool fixChecksums(std::vector<std::uint8_t>& bytes) {
  using artifact::FileHeader;
  using artifact::SectionEntry;
  if (bytes.size() < sizeof(FileHeader)) return false;
  FileHeader h;
  std::memcpy(&h, bytes.data(), sizeof(h));
  if (std::memcmp(h.magic, artifact::kMagic, sizeof(artifact::kMagic)) != 0) return false;
  const std::vector<std::uint8_t> before = bytes;
  h.file_bytes = bytes.size();
  const std::size_t table_bytes = std::size_t(h.section_count) * sizeof(SectionEntry);
  if (h.section_count <= 4096 && sizeof(FileHeader) + table_bytes <= bytes.size()) {
    std::uint8_t* table = bytes.data() + sizeof(FileHeader);
    for (std::size_t i = 0; i < h.section_count; ++i) {
      SectionEntry e;
      std::memcpy(&e, table + i * sizeof(e), sizeof(e));
      if (e.offset <= bytes.size() && e.bytes <= bytes.size() - e.offset) {
        e.checksum = artifact::hashBytes(bytes.data() + e.offset, e.bytes);
        std::memcpy(table + i * sizeof(e), &e, sizeof(e));
      }
    }
    h.table_checksum = artifact::hashBytes(table, table_bytes);
  }
  h.header_checksum = artifact::hashBytes(&h, offsetof(FileHeader, header_checksum));
  std::memcpy(bytes.data(), &h, sizeof(h));
  return bytes != before;
}

ArtifactVerdict openArtifactBytes(std::span<const std::uint8_t> bytes) {
  ArtifactVerdict v;
  const std::string path = scratch().write("in.llk", bytes);
  v.raw = openAndWalk(path);
  std::vector<std::uint8_t> fixed(bytes.begin(), bytes.end());
  if (!v.raw && fixChecksums(fixed)) {
    v.fixed = true;
    scratch().write("in.llk", fixed);
    v.after_fix = openAndWalk(path);
  }
  if (v.raw || (v.fixed && v.after_fix)) {
    auto loaded = precompute::open(path);
    if (!loaded) {
      v.relight = loaded.status();  // opened a moment ago: cannot happen, report it
    } else {
      v.relit = true;
      v.relight = relightOnce(*loaded);
    }
  }
  return v;
}

scene::Scene fuzzScene() {
  using testing::addBox;
  using testing::addMaterial;
  using testing::addQuad;
  scene::Scene s;
  s.source_path = "fuzz-scene";
  const int wall = addMaterial(s, glm::vec3(0.7f, 0.6f, 0.5f));
  const int lamp = addMaterial(s, glm::vec3(0.5f), glm::vec3(4.0f));
  addBox(s, glm::vec3(0.0f), glm::vec3(2.0f), /*inward=*/true, wall);
  // An emissive panel under the ceiling, facing down.
  addQuad(s, {0.7f, 1.9f, 0.7f}, {1.3f, 1.9f, 0.7f}, {1.3f, 1.9f, 1.3f}, {0.7f, 1.9f, 1.3f}, lamp);
  // A dynamic block: the artifact then carries grid caches and grid links too.
  const std::size_t first_dynamic = s.meshes.size();
  addBox(s, glm::vec3(0.3f, 0.0f, 0.3f), glm::vec3(0.7f, 0.4f, 0.7f), /*inward=*/false, wall);
  for (std::size_t m = first_dynamic; m < s.meshes.size(); ++m) s.meshes[m].is_static = false;
  scene::Light light;
  light.name = "bulb";
  light.position = glm::vec3(1.0f, 1.2f, 1.0f);
  light.intensity = 5.0f;
  s.lights.push_back(light);
  testing::finishScene(s);
  return s;
}

precompute::PrecomputeOptions fuzzOptions() {
  precompute::PrecomputeOptions o;
  o.surfels = 48;
  o.links = 8;
  o.bands = 2;
  o.rays = 32;
  o.grid = precompute::GridMode::kAuto;
  o.grid_resolution = 3;
  o.target_resolution = 16;
  o.validity_rays = 4;
  return o;
}

Status writeSeedArtifact(const std::string& path) {
  scene::Scene s = fuzzScene();
  const precompute::PrecomputeOptions options = fuzzOptions();
  auto p = precompute::run(s, options);
  if (!p) return p.status();
  return precompute::save(*p, path, artifact::cacheKey({}, options.canonical()));
}

Status writeSeedBakeOutputs(const std::string& dir) {
  scene::Scene s = fuzzScene();
  auto p = precompute::run(s, fuzzOptions());
  if (!p) return p.status();
  auto accel = rt::Accel::build(s);
  if (!accel) return accel.status();
  auto relighter = relight::Relighter::create(s, *accel, *p);
  if (!relighter) return relighter.status();
  auto result = relighter->relight(relight::LightSet::fromSceneLights(s.lights), {});
  if (!result) return result.status();
  const fs::path d(dir);
  // Of each precision: the irradiance map, an SH coefficient and a validity file (the three
  // channel layouts a lightlink EXR has), renamed so both precisions fit one folder.
  for (const bool half : {false, true}) {
    output::ExrOptions options;
    options.half = half;
    const fs::path tmp = d / (half ? "tmp_half" : "tmp_float");
    std::error_code ec;
    fs::create_directories(tmp, ec);
    auto w = output::writeLightmapExrs(*result, p->lightmap, tmp.string(), options,
                                       p->hasDirectLayer() ? &p->direct_texels : nullptr);
    if (!w) return w.status();
    for (const char* f : {"irradiance", "lightmap_L00", "valid"}) {
      fs::rename(tmp / (std::string(f) + ".exr"), d / (std::string(f) + (half ? "_half.exr" : "_float.exr")), ec);
      if (ec) return ioError("cannot move {} into {}: {}", f, dir, ec.message());
    }
    fs::remove_all(tmp, ec);
  }
  return output::writeGridRaw(*result, p->grid, (d / "grid.raw").string());
}

}  // namespace lightlink::fuzz
