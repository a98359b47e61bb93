#include "tests/fuzz/fuzz_inputs.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>

#include <tbb/global_control.h>

#include "core/artifact/artifact.h"
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
    c->lights = relight::LightSet::fromScene(c->scene);
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

}  // namespace lightlink::fuzz
