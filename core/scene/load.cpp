#include "core/scene/load.h"

#include <algorithm>
#include <cstdint>
#include <cctype>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string_view>

#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "core/scene/gltf_context.h"
#include "core/scene/gltf_diagnose.h"
#include "core/scene/gltf_lights.h"
#include "core/scene/gltf_materials.h"
#include "core/scene/gltf_nodes.h"
#include "core/scene/gltf_primitive.h"
#include "core/scene/gltf_structure.h"
#include "core/scene/lighting_images.h"
#include "core/scene/scene_files_unread.h"
#include "core/scene/mesh_ops.h"

namespace lightlink::scene {
namespace {

// Triangles smaller than (kDegenerateEdgeFraction * scene scale)^2 carry no light and
// break normals and barycentric sampling downstream; they are dropped, not fatal.
constexpr double kDegenerateEdgeFraction = 1e-7;

// Binary (.glb) by the "glTF" magic or the extension, JSON (.gltf) by the extension or a
// leading '{'; anything else (an .obj, an .fbx) is named as unsupported rather than
// reported as malformed JSON.
Expected<bool> isBinaryGltf(const std::string& path, const std::string& bytes) {
  const std::size_t got = std::min<std::size_t>(bytes.size(), 64);
  if (got >= 4 && std::string_view(bytes.data(), 4) == "glTF") return true;
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".glb") return true;
  if (ext == ".gltf") return false;
  for (std::size_t i = 0; i < got; ++i) {
    if (bytes[i] == '{') return false;
    if (!std::isspace(static_cast<unsigned char>(bytes[i]))) break;
  }
  return unsupported("{}: unknown scene format '{}': lightlink reads {}", path,
                     ext.empty() ? std::string("(no extension)") : ext, acceptedSceneExtensions());
}

// tinygltf converts extras and extensions recursively, and so does the failure diagnosis:
// JSON nested tens of thousands deep (a few hundred KB of '[') overflows the stack before
// either can report anything (found by tests/fuzz; regression deep_extras.gltf). No glTF
// needs more than a few dozen levels, so deeper nesting is refused before parsing.
constexpr int kMaxJsonDepth = 256;

// The JSON text of the file: all of a .gltf, the first (JSON) chunk of a .glb as far as the
// file holds it. Empty when there is nothing to scan; tinygltf then names the problem.
std::string_view jsonText(const std::string& bytes, bool binary) {
  if (!binary) return bytes;
  // GLB: magic, version, length (12 bytes), then chunk 0: length, type "JSON", data.
  constexpr std::size_t kHead = 20;
  if (bytes.size() < kHead) return {};
  const auto* head = reinterpret_cast<const unsigned char*>(bytes.data());
  const std::uint32_t json_bytes = std::uint32_t(head[12]) | std::uint32_t(head[13]) << 8 |
                                   std::uint32_t(head[14]) << 16 | std::uint32_t(head[15]) << 24;
  return std::string_view(bytes).substr(kHead, std::min<std::size_t>(json_bytes, bytes.size() - kHead));
}

Status checkJsonNesting(const std::string& path, std::string_view text) {
  int depth = 0;
  bool in_string = false, escaped = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth) {
        return invalidInput("{}: JSON nested deeper than {} levels (at byte {}); glTF never needs that "
                            "much, and parsing it would exhaust the stack", path, kMaxJsonDepth, i);
      }
    } else if (c == ']' || c == '}') {
      depth = std::max(0, depth - 1);
    }
  }
  return Status::ok();
}

void addTinygltfWarnings(const std::string& path, const std::string& warn, Scene& scene) {
  std::istringstream lines(warn);
  std::string line;
  while (std::getline(lines, line)) {
    if (!line.empty()) {
      scene.warnings.push_back(fmt::format("{}: tinygltf: {}", path, gltf::shortenTinygltfMessage(line)));
    }
  }
}

// The external files of images that are not decoded (all of them without load_textures),
// unless a decoded image or a buffer names the same file.
std::vector<std::filesystem::path> unreadImageFiles(const SceneFiles& files, const nlohmann::json& gltf,
                                                    const gltf::ImageDecodeState& images) {
  std::vector<std::filesystem::path> unread, read;
  for (const char* list : {"buffers", "images"}) {
    const auto it = gltf.is_object() ? gltf.find(list) : gltf.end();
    if (!gltf.is_object() || it == gltf.end() || !it->is_array()) continue;
    for (std::size_t i = 0; i < it->size(); ++i) {
      const nlohmann::json& entry = (*it)[i];
      if (!entry.is_object() || !entry.contains("uri") || !entry["uri"].is_string()) continue;
      const std::string& uri = entry["uri"].get_ref<const std::string&>();
      if (uri.empty() || uri.rfind("data:", 0) == 0) continue;
      Expected<std::filesystem::path> p = files.resolveUri(uri, list);
      if (!p) continue;
      const bool decoded = std::string_view(list) == "buffers" ||
                           (images.decode && i < images.wanted.size() && images.wanted[i]);
      (decoded ? read : unread).push_back(std::move(p).value());
    }
  }
  unread.erase(std::remove_if(unread.begin(), unread.end(),
                              [&](const std::filesystem::path& p) {
                                return std::find(read.begin(), read.end(), p) != read.end();
                              }),
               unread.end());
  return unread;
}

Status loadModel(const SceneFiles& files, std::vector<std::filesystem::path> unread_files, const std::string& bytes,
                 bool binary, gltf::ImageDecodeState& images, tinygltf::Model& model, Scene& scene) {
  const std::string& path = files.scenePath();
  if (bytes.size() > std::numeric_limits<unsigned int>::max())
    return invalidInput("{}: {} bytes is larger than tinygltf can parse", path, bytes.size());
  tinygltf::TinyGLTF loader;
  const UnreadFiles unread{&files, std::move(unread_files)};
  installSkippingUnread(unread, loader);
  images.model = &model;
  loader.SetImageLoader(&gltf::decodeImage, &images);
  std::string err, warn;
  // From memory with the canonical folder as base: relative URIs resolve there, and every
  // file read goes through `files` (tinygltf's own file callbacks are never used).
  const auto size = static_cast<unsigned int>(bytes.size());
  const std::string base = files.folder().string();
  const bool ok =
      binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                           size, base)
             : loader.LoadASCIIFromString(&model, &err, &warn, bytes.data(), size, base);
  if (!ok) {
    if (!images.fatal.empty()) return invalidInput("{}: {}", path, images.fatal);
    if (!images.over_budget.empty()) return resourceExhausted("{}: {}", path, images.over_budget);
    if (std::optional<Status> why = gltf::diagnoseLoadFailure(files, bytes, binary, err)) return *why;
    const bool json_error = err.find("parse_error") != std::string::npos ||
                            err.find("JSON") != std::string::npos;
    return invalidInput("{}: {}{}", path, json_error ? "malformed JSON: " : "",
                        gltf::shortenTinygltfMessage(err.empty() ? "tinygltf failed without a message" : err));
  }
  addTinygltfWarnings(path, warn, scene);
  for (const std::string& problem : images.problems) {
    scene.warnings.push_back(fmt::format("{}: {}", path, gltf::shortenTinygltfMessage(problem)));
  }
  return Status::ok();
}

// Triangles the node graph instances, from accessor counts alone: a small file that places
// one mesh thousands of times is refused before it is flattened into gigabytes.
std::uint64_t instancedTriangles(const tinygltf::Model& model, const std::vector<gltf::PlacedNode>& nodes) {
  std::uint64_t total = 0;
  for (const gltf::PlacedNode& placed : nodes) {
    const int mesh = model.nodes[static_cast<std::size_t>(placed.node)].mesh;
    if (mesh < 0 || static_cast<std::size_t>(mesh) >= model.meshes.size()) continue;
    for (const tinygltf::Primitive& prim : model.meshes[static_cast<std::size_t>(mesh)].primitives) {
      int accessor = prim.indices;
      if (accessor < 0) {
        const auto it = prim.attributes.find("POSITION");
        accessor = it == prim.attributes.end() ? -1 : it->second;
      }
      if (accessor < 0 || static_cast<std::size_t>(accessor) >= model.accessors.size()) continue;
      const std::uint64_t count = model.accessors[static_cast<std::size_t>(accessor)].count;
      const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
      if (mode == TINYGLTF_MODE_TRIANGLES) total += count / 3;
      else if ((mode == TINYGLTF_MODE_TRIANGLE_STRIP || mode == TINYGLTF_MODE_TRIANGLE_FAN) && count >= 3)
        total += count - 2;
    }
  }
  return total;
}

Status buildGeometry(const gltf::Context& ctx, const std::vector<gltf::PlacedNode>& nodes) {
  Scene& scene = ctx.scene;
  for (const gltf::PlacedNode& placed : nodes) {
    const int mesh = ctx.model.nodes[static_cast<std::size_t>(placed.node)].mesh;
    if (mesh < 0) continue;
    const auto& primitives = ctx.model.meshes[static_cast<std::size_t>(mesh)].primitives;
    for (std::size_t p = 0; p < primitives.size(); ++p) {
      Expected<MeshInstance> instance = gltf::buildInstance(ctx, placed, mesh, static_cast<int>(p));
      if (!instance) return instance.status();
      scene.stats.triangles_in += instance->triangleCount();
      scene.stats.vertices += instance->positions.size();
      scene.meshes.push_back(std::move(*instance));
    }
  }

  Aabb all;
  for (const MeshInstance& m : scene.meshes) {
    for (std::uint32_t i : m.indices) all.grow(m.positions[i]);
  }
  const double edge = kDegenerateEdgeFraction * static_cast<double>(all.diagonal());
  const double min_area_m2 = std::max(edge * edge, std::numeric_limits<double>::min());

  std::map<int, std::size_t> dropped_per_mesh;
  for (MeshInstance& m : scene.meshes) {
    const std::size_t dropped = dropDegenerateTriangles(m, min_area_m2);
    if (dropped > 0) dropped_per_mesh[m.gltf_mesh] += dropped;
    scene.stats.degenerate_dropped += dropped;
  }
  for (const auto& [mesh, dropped] : dropped_per_mesh) {
    ctx.warn(gltf::describeMesh(ctx.model, mesh),
             fmt::format("{} degenerate triangles dropped (zero area below {:.3g} m^2 or a "
                         "repeated index)", dropped, min_area_m2));
  }
  const auto empty = std::remove_if(scene.meshes.begin(), scene.meshes.end(),
                                    [](const MeshInstance& m) { return m.indices.empty(); });
  scene.stats.instances_without_triangles = static_cast<std::size_t>(scene.meshes.end() - empty);
  scene.meshes.erase(empty, scene.meshes.end());
  scene.stats.normals_generated = static_cast<std::size_t>(std::count_if(
      scene.meshes.begin(), scene.meshes.end(), [](const MeshInstance& m) { return m.normals_generated; }));

  if (scene.meshes.empty()) {
    return ctx.invalid("scene", fmt::format("has no triangles ({} read, {} degenerate)",
                                            scene.stats.triangles_in, scene.stats.degenerate_dropped));
  }
  scene.bounds = Aabb{};
  for (const MeshInstance& m : scene.meshes) {
    for (std::uint32_t i : m.indices) scene.bounds.grow(m.positions[i]);
  }
  scene.scale = scene.bounds.diagonal();
  return Status::ok();
}

}  // namespace

Expected<Scene> loadGltf(const std::string& path, const LoadOptions& options) {
  Expected<SceneFiles> files = SceneFiles::forScene(path, options.files);
  if (!files) return files.status();
  Expected<std::string> bytes = files->readScene();
  if (!bytes) return bytes.status();
  Expected<bool> binary = isBinaryGltf(path, *bytes);
  if (!binary) return binary.status();

  const std::string_view json = jsonText(*bytes, *binary);
  if (Status s = checkJsonNesting(path, json); !s) return s;
  // Before tinygltf touches any external file: name the entry whose URI leaves the folder.
  // Then which images lighting reads: only those are read and decoded. The parsed JSON is
  // released before tinygltf builds its own model.
  gltf::ImageDecodeState images;
  images.decode = options.load_textures;
  images.max_image_pixels = options.max_image_pixels;
  images.max_image_bytes = options.max_image_bytes;
  LightingImages lighting;
  std::vector<std::filesystem::path> unread;
  {
    const nlohmann::json parsed = nlohmann::json::parse(json, nullptr, /*allow_exceptions=*/false);
    if (Status s = files->checkUris(parsed); !s) return s;
    lighting = lightingImages(parsed);
    images.wanted = lighting.images;
    images.alpha = lighting.alpha;
    unread = unreadImageFiles(*files, parsed, images);
  }

  Scene scene;
  scene.source_path = path;
  tinygltf::Model model;
  if (Status s = loadModel(*files, std::move(unread), *bytes, *binary, images, model, scene); !s) return s;
  scene.stats.images_decoded = images.decoded;
  scene.stats.image_bytes = images.decoded_bytes;
  for (std::size_t i = 0; i < model.images.size(); ++i)
    if (!options.load_textures || !lighting.image(static_cast<int>(i))) ++scene.stats.images_skipped;

  const gltf::Context ctx{path, model, scene, options, std::move(lighting)};
  if (Status s = gltf::validateExtensions(ctx); !s) return s;
  if (Status s = gltf::validateBufferViews(ctx); !s) return s;
  Expected<std::vector<gltf::PlacedNode>> nodes = gltf::placeNodes(ctx);
  if (!nodes) return nodes.status();
  if (options.max_triangles != 0) {
    if (const std::uint64_t n = instancedTriangles(model, *nodes); n > options.max_triangles)
      return resourceExhausted("{}: the node graph instances {} triangles, above the limit of {} (max_triangles)",
                               path, n, options.max_triangles);
  }
  if (Status s = gltf::loadTextures(ctx, images); !s) return s;
  if (Status s = gltf::loadMaterials(ctx); !s) return s;
  if (Status s = buildGeometry(ctx, *nodes); !s) return s;
  if (Status s = gltf::loadLights(ctx, *nodes); !s) return s;
  return scene;
}

}  // namespace lightlink::scene
