#include "core/scene/assimp_load.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include <assimp/Importer.hpp>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include "core/scene/assimp_io.h"
#include "core/scene/image_decode.h"
#include "core/scene/mesh_ops.h"
#include "core/scene/obj_diagnose.h"

namespace lightlink::scene {
namespace {
namespace fs = std::filesystem;

// As in the glTF path: triangles below (1e-7 * scene scale)^2 carry no light.
constexpr double kDegenerateEdgeFraction = 1e-7;
// Polygons above kSmallPolygon corners count corners^2 towards kMaxPolygonWork, about 2 s of
// assimp's triangulation on the 2-core VM (one face of 30,000 corners takes 1.7 s).
constexpr unsigned kSmallPolygon = 16;
constexpr std::uint64_t kMaxPolygonWork = std::uint64_t(1) << 30;

std::string lowerExtension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

glm::dmat4 toGlm(const aiMatrix4x4& a) {
  glm::dmat4 m(1.0);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m[c][r] = a[static_cast<unsigned>(r)][static_cast<unsigned>(c)];
  return m;
}

bool finite(const aiVector3D& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

struct PlacedMesh {
  unsigned mesh = 0;
  int node = 0;           // pre-order index of the node
  std::string node_path;  // "Box/side": node names below the root, joined by '/'
  glm::dmat4 world{1.0};
};

// Every (node, mesh) pair in pre-order, with the world transform (in metres) and the path.
std::vector<PlacedMesh> placeMeshes(const aiScene& ai, double metres_per_unit) {
  std::vector<PlacedMesh> placed;
  struct Item {
    const aiNode* node;
    glm::dmat4 parent;
    std::string parent_path;
  };
  const glm::dmat4 to_metres(glm::dvec4(metres_per_unit, 0, 0, 0), glm::dvec4(0, metres_per_unit, 0, 0),
                             glm::dvec4(0, 0, metres_per_unit, 0), glm::dvec4(0, 0, 0, 1));
  std::vector<Item> stack{{ai.mRootNode, to_metres, std::string()}};
  int ordinal = 0;
  while (!stack.empty()) {
    Item item = std::move(stack.back());
    stack.pop_back();
    if (item.node == nullptr) continue;
    const glm::dmat4 world = item.parent * toGlm(item.node->mTransformation);
    const bool root = item.node == ai.mRootNode;
    const std::string name = item.node->mName.C_Str();
    const std::string path = root ? std::string() : item.parent_path.empty() ? name : item.parent_path + "/" + name;
    const int index = ordinal++;
    for (unsigned i = 0; i < item.node->mNumMeshes; ++i) placed.push_back({item.node->mMeshes[i], index, path, world});
    for (unsigned c = item.node->mNumChildren; c-- > 0;) stack.push_back({item.node->mChildren[c], world, path});
  }
  return placed;
}

class Loader {
 public:
  Loader(const std::string& path, const SceneFiles& files, const LoadOptions& options, bool obj, Scene& scene)
      : path_(path), files_(files), options_(options), obj_(obj), scene_(scene) {
    budget_.max_image_pixels = options.max_image_pixels;
    budget_.max_image_bytes = options.max_image_bytes;
  }

  Status run(const std::string& bytes);

 private:
  std::string describeObject(const PlacedMesh& p, const aiMesh& mesh) const {
    const char* kind = obj_ ? "object" : "node";
    std::string label =
        p.node_path.empty() ? fmt::format("{} (root)", kind) : fmt::format("{} '{}'", kind, p.node_path);
    const std::string mesh_name = mesh.mName.C_Str();
    const std::string leaf = p.node_path.substr(p.node_path.rfind('/') + 1);
    if (!mesh_name.empty() && mesh_name != leaf) label += fmt::format(" mesh '{}'", mesh_name);
    return label;
  }
  void warn(std::string_view object, std::string_view what) {
    scene_.warnings.push_back(fmt::format("{}: {}: {}", path_, object, what));
  }
  Status invalid(std::string_view object, std::string_view what) const {
    return {Code::kInvalidInput, fmt::format("{}: {}: {}", path_, object, what)};
  }

  Status readFile(const std::string& bytes);
  Status validateRaw(const std::vector<PlacedMesh>& placed);
  Status loadMaterials();
  Expected<TextureRef> loadTexture(const aiMaterial& material, const std::string& object, aiTextureType type,
                                   const char* key);
  Status buildGeometry(const std::vector<PlacedMesh>& placed);
  void dropUnusedDefaultMaterial();

  const std::string& path_;
  const SceneFiles& files_;
  const LoadOptions& options_;
  const bool obj_;
  Scene& scene_;
  Assimp::Importer importer_;
  ConfinedIOSystem* io_ = nullptr;  // owned by importer_
  const aiScene* ai_ = nullptr;
  double metres_per_unit_ = 1.0;    // FBX UnitScaleFactor / 100; OBJ: 1
  std::string text_;                // the OBJ text, for diagnoses
  ImageBudget budget_;
  std::map<std::string, int> textures_by_name_;
};

Status Loader::readFile(const std::string& bytes) {
  io_ = new ConfinedIOSystem(files_, obj_ ? "mtllib" : "file");
  importer_.SetIOHandler(io_);
  const char* hint = obj_ ? "obj" : "fbx";
  if (obj_) {
    if (std::optional<std::string> where = diagnoseObj(bytes, /*vertices=*/false))
      return invalidInput("{}: {}", path_, *where);
  }
  // Read without post-processing first: the data is validated and the triangle budget
  // checked before triangulation and vertex joining (which would hide a NaN) run.
  ai_ = importer_.ReadFileFromMemory(bytes.data(), bytes.size(), 0, hint);
  if (!io_->refused().empty()) return invalidInput("{}", io_->refused());
  if (ai_ == nullptr) {
    const std::string why = importer_.GetErrorString();
    if (obj_) {
      if (std::optional<std::string> where = diagnoseObj(bytes)) return invalidInput("{}: {}", path_, *where);
    }
    return invalidInput("{}: cannot be read as {} ({})", path_, obj_ ? "OBJ" : "FBX",
                        why.empty() ? "assimp gave no reason" : why);
  }
  for (const std::string& name : io_->missing()) {
    warn(obj_ ? fmt::format("mtllib '{}'", name) : fmt::format("file '{}'", name),
         "not found beside the scene; its materials fall back to assimp's default (grey 0.6)");
  }
  return Status::ok();
}

Status Loader::validateRaw(const std::vector<PlacedMesh>& placed) {
  std::vector<const PlacedMesh*> first_use(ai_->mNumMeshes, nullptr);
  std::uint64_t triangles = 0;
  for (const PlacedMesh& p : placed) {
    if (p.mesh >= ai_->mNumMeshes || ai_->mMeshes[p.mesh] == nullptr)
      return invalidInput("{}: node '{}' names mesh {}, but the file has {}", path_, p.node_path, p.mesh,
                          ai_->mNumMeshes);
    if (first_use[p.mesh] == nullptr) first_use[p.mesh] = &p;
    const aiMesh& mesh = *ai_->mMeshes[p.mesh];
    for (unsigned f = 0; f < mesh.mNumFaces; ++f)
      if (mesh.mFaces[f].mNumIndices >= 3) triangles += mesh.mFaces[f].mNumIndices - 2;
  }
  if (options_.max_triangles != 0 && triangles > options_.max_triangles)
    return resourceExhausted("{}: the node graph instances {} triangles, above the limit of {} (max_triangles)", path_,
                             triangles, options_.max_triangles);
  // assimp triangulates a polygon in time quadratic in its corners: one face of 300,000
  // corners (a 1 MB file) would take minutes. Big polygons are bounded together.
  std::uint64_t polygon_work = 0;
  const PlacedMesh* biggest_at = nullptr;
  unsigned biggest = 0, biggest_face = 0;
  for (unsigned i = 0; i < ai_->mNumMeshes; ++i) {
    if (first_use[i] == nullptr) continue;
    const aiMesh& mesh = *ai_->mMeshes[i];
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const unsigned corners = mesh.mFaces[f].mNumIndices;
      if (corners <= kSmallPolygon) continue;
      polygon_work += std::uint64_t(corners) * corners;
      if (corners > biggest) {
        biggest = corners;
        biggest_face = f;
        biggest_at = first_use[i];
      }
    }
  }
  if (polygon_work > kMaxPolygonWork) {
    const aiMesh& mesh = *ai_->mMeshes[biggest_at->mesh];
    return {Code::kResourceExhausted,
            fmt::format("{}: {}: face {} has {} corners; the polygons of more than {} corners add up to {} corners "
                        "squared, above the {} lightlink triangulates (split the large polygons into smaller ones)",
                        path_, describeObject(*biggest_at, mesh), biggest_face, biggest, kSmallPolygon, polygon_work,
                        kMaxPolygonWork)};
  }
  for (unsigned i = 0; i < ai_->mNumMeshes; ++i) {
    if (first_use[i] == nullptr) continue;
    const aiMesh& mesh = *ai_->mMeshes[i];
    const std::string object = describeObject(*first_use[i], mesh);
    for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
      if (!finite(mesh.mVertices[v])) {
        std::string where;
        if (obj_) {
          if (std::optional<std::string> line = diagnoseObj(text_)) where = " (" + *line + ")";
        }
        return invalid(object, fmt::format("position of vertex {} is not finite ({}, {}, {}){}", v, mesh.mVertices[v].x,
                                           mesh.mVertices[v].y, mesh.mVertices[v].z, where));
      }
      if (mesh.mTextureCoords[0] != nullptr && !finite(mesh.mTextureCoords[0][v]))
        return invalid(object, fmt::format("texture coordinate of vertex {} is not finite", v));
    }
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      for (unsigned k = 0; k < face.mNumIndices; ++k) {
        if (face.mIndices[k] >= mesh.mNumVertices)
          return invalid(object, fmt::format("face {} corner {} names vertex {}, but the mesh has {}", f, k,
                                             face.mIndices[k], mesh.mNumVertices));
      }
    }
  }
  return Status::ok();
}

Expected<TextureRef> Loader::loadTexture(const aiMaterial& material, const std::string& object, aiTextureType type,
                                         const char* key) {
  TextureRef ref;
  aiString raw;
  if (material.GetTextureCount(type) == 0 || material.GetTexture(type, 0, &raw) != AI_SUCCESS || raw.length == 0)
    return ref;
  const std::string field = fmt::format("{} '{}'", key, raw.C_Str());
  const aiTexture* embedded = ai_->GetEmbeddedTexture(raw.C_Str());
  const std::string name = embedded != nullptr ? std::string(raw.C_Str()) : io_->normalise(raw.C_Str());
  if (const auto it = textures_by_name_.find(name); it != textures_by_name_.end()) {
    ref.texture = it->second;
    return ref;
  }
  Texture texture;
  texture.name = name;
  const std::string what = fmt::format("{}: {}", object, field);
  if (embedded != nullptr) {
    if (options_.load_textures) {
      std::string problem;
      if (embedded->mHeight == 0) {
        const std::string_view bytes(reinterpret_cast<const char*>(embedded->pcData), embedded->mWidth);
        if (Status s = decodeImageRgba8(bytes, fmt::format("{}: {}", path_, what), budget_, texture, problem); !s)
          return s;
      } else {
        texture.width = static_cast<int>(embedded->mWidth);
        texture.height = static_cast<int>(embedded->mHeight);
        texture.rgba8.resize(std::size_t(embedded->mWidth) * embedded->mHeight * 4);
        for (std::size_t p = 0; p < std::size_t(embedded->mWidth) * embedded->mHeight; ++p) {
          const aiTexel& t = embedded->pcData[p];
          texture.rgba8[p * 4 + 0] = t.r;
          texture.rgba8[p * 4 + 1] = t.g;
          texture.rgba8[p * 4 + 2] = t.b;
          texture.rgba8[p * 4 + 3] = t.a;
        }
      }
      if (!problem.empty()) {
        warn(what, fmt::format("embedded image {}; the factor alone applies", problem));
        return ref;
      }
    }
  } else {
    // The folder rule is checked even when nothing is decoded (the writer copies the file).
    Expected<fs::path> resolved = files_.resolveName(name, key);
    if (!resolved) return invalidInput("{} ({})", resolved.status().message(), object);
    if (options_.load_textures) {
      Expected<std::string> bytes = files_.readName(name, key);
      if (!bytes) {
        if (bytes.status().code() != Code::kNotFound)
          return Status(bytes.status().code(), fmt::format("{} ({})", bytes.status().message(), object));
        warn(what, "not found; the factor alone applies");
        return ref;
      }
      std::string problem;
      if (Status s = decodeImageRgba8(*bytes, fmt::format("{}: {}", path_, what), budget_, texture, problem); !s)
        return s;
      if (!problem.empty()) {
        warn(what, fmt::format("{}; the factor alone applies", problem));
        return ref;
      }
    } else {
      std::error_code ec;
      if (!fs::is_regular_file(*resolved, ec)) {
        warn(what, "not found; the factor alone applies");
        return ref;
      }
    }
  }
  ref.texture = static_cast<int>(scene_.textures.size());
  textures_by_name_[name] = ref.texture;
  scene_.textures.push_back(std::move(texture));
  return ref;
}

Status Loader::loadMaterials() {
  scene_.materials.resize(ai_->mNumMaterials);
  for (unsigned i = 0; i < ai_->mNumMaterials; ++i) {
    const aiMaterial& am = *ai_->mMaterials[i];
    Material& m = scene_.materials[i];
    aiString name;
    if (am.Get(AI_MATKEY_NAME, name) == AI_SUCCESS) m.name = name.C_Str();
    const std::string object =
        m.name.empty() ? fmt::format("material {}", i) : fmt::format("material '{}'", m.name);
    m.metallic = 0.0f;  // OBJ/FBX materials are diffuse surfaces, not glTF's metal default
    m.roughness = 1.0f;
    const char* kd = obj_ ? "Kd" : "diffuse colour";
    const char* ke = obj_ ? "Ke" : "emissive colour";
    const char* d = obj_ ? "d (opacity)" : "opacity";
    aiColor3D diffuse(1.0f, 1.0f, 1.0f);
    if (am.Get(AI_MATKEY_COLOR_DIFFUSE, diffuse) == AI_SUCCESS) {
      for (int c = 0; c < 3; ++c) {
        if (!std::isfinite(diffuse[c]) || diffuse[c] < 0.0f)
          return invalid(object, fmt::format("{} component {} = {} is not a finite non-negative number", kd, c,
                                             diffuse[c]));
      }
    }
    float opacity = 1.0f;
    if (am.Get(AI_MATKEY_OPACITY, opacity) == AI_SUCCESS) {
      if (!std::isfinite(opacity))
        return invalid(object, fmt::format("{} = {} is not a finite number", d, opacity));
      if (opacity < 0.0f || opacity > 1.0f) {
        warn(object, fmt::format("{} = {} is outside [0, 1]; clamped", d, opacity));
        opacity = std::clamp(opacity, 0.0f, 1.0f);
      }
    }
    m.base_color_factor = glm::vec4(diffuse.r, diffuse.g, diffuse.b, opacity);
    aiColor3D emissive(0.0f, 0.0f, 0.0f);
    if (am.Get(AI_MATKEY_COLOR_EMISSIVE, emissive) == AI_SUCCESS) {
      for (int c = 0; c < 3; ++c) {
        if (!std::isfinite(emissive[c]) || emissive[c] < 0.0f)
          return invalid(object, fmt::format("{} component {} = {} is not a finite non-negative number", ke, c,
                                             emissive[c]));
      }
      // glTF keeps emissiveFactor in [0, 1] and the rest in KHR_materials_emissive_strength.
      const float peak = std::max({emissive.r, emissive.g, emissive.b});
      m.emissive_strength = std::max(1.0f, peak);
      m.emissive_factor = glm::vec3(emissive.r, emissive.g, emissive.b) / m.emissive_strength;
    }
    Expected<TextureRef> base = loadTexture(am, object, aiTextureType_DIFFUSE, obj_ ? "map_Kd" : "diffuse texture");
    if (!base) return base.status();
    if (!base->valid()) {
      base = loadTexture(am, object, aiTextureType_BASE_COLOR, "base colour texture");
      if (!base) return base.status();
    }
    m.base_color_texture = *base;
    Expected<TextureRef> glow = loadTexture(am, object, aiTextureType_EMISSIVE, obj_ ? "map_Ke" : "emissive texture");
    if (!glow) return glow.status();
    m.emissive_texture = *glow;
  }
  return Status::ok();
}

Status Loader::buildGeometry(const std::vector<PlacedMesh>& placed) {
  std::size_t skipped_primitives = 0;
  for (const PlacedMesh& p : placed) {
    const aiMesh& mesh = *ai_->mMeshes[p.mesh];
    if ((mesh.mPrimitiveTypes & (aiPrimitiveType_TRIANGLE | aiPrimitiveType_POLYGON)) == 0) {
      skipped_primitives += mesh.mNumFaces;
      continue;
    }
    MeshInstance out;
    out.name = p.node_path.empty() ? std::string(mesh.mName.C_Str()) : p.node_path;
    if (const std::string leaf = p.node_path.substr(p.node_path.rfind('/') + 1);
        mesh.mName.length > 0 && mesh.mName.C_Str() != leaf && !p.node_path.empty())
      out.name += std::string("/") + mesh.mName.C_Str();
    out.gltf_node = p.node;
    out.gltf_mesh = static_cast<int>(p.mesh);
    out.gltf_primitive = 0;
    out.material = mesh.mMaterialIndex < scene_.materials.size() ? static_cast<int>(mesh.mMaterialIndex) : -1;
    out.is_static = true;
    out.world_from_mesh = glm::mat4(p.world);
    const glm::dmat3 linear(p.world);
    const bool mirrored = glm::determinant(linear) < 0.0;
    const std::size_t n = mesh.mNumVertices;
    out.positions.resize(n);
    for (std::size_t v = 0; v < n; ++v) {
      const aiVector3D& a = mesh.mVertices[v];
      out.positions[v] = glm::vec3(p.world * glm::dvec4(a.x, a.y, a.z, 1.0));
    }
    if (mesh.mTextureCoords[0] != nullptr) {
      out.uv0.resize(n);
      for (std::size_t v = 0; v < n; ++v)
        out.uv0[v] = glm::vec2(mesh.mTextureCoords[0][v].x, mesh.mTextureCoords[0][v].y);
    }
    out.indices.reserve(std::size_t(mesh.mNumFaces) * 3);
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      if (face.mNumIndices != 3) {
        ++skipped_primitives;
        continue;
      }
      out.indices.push_back(face.mIndices[0]);
      out.indices.push_back(face.mIndices[mirrored ? 2 : 1]);
      out.indices.push_back(face.mIndices[mirrored ? 1 : 2]);
    }
    if (mesh.mNormals != nullptr) {
      out.normals.resize(n);
      for (std::size_t v = 0; v < n; ++v) out.normals[v] = glm::vec3(mesh.mNormals[v].x, mesh.mNormals[v].y, mesh.mNormals[v].z);
    }
    if (const std::size_t replaced = worldNormalsOrGenerated(linear, out); replaced > 0)
      warn(describeObject(p, mesh),
           fmt::format("{} zero-length or non-finite normals replaced by generated ones", replaced));
    scene_.stats.triangles_in += out.triangleCount();
    scene_.stats.vertices += out.positions.size();
    scene_.meshes.push_back(std::move(out));
  }
  if (skipped_primitives > 0)
    warn("scene", fmt::format("{} line and point elements ignored (only faces are lit)", skipped_primitives));

  Aabb all;
  for (const MeshInstance& m : scene_.meshes)
    for (std::uint32_t i : m.indices) all.grow(m.positions[i]);
  const double edge = kDegenerateEdgeFraction * static_cast<double>(all.diagonal());
  const double min_area_m2 = std::max(edge * edge, std::numeric_limits<double>::min());
  std::map<std::string, std::size_t> dropped_per_object;
  for (MeshInstance& m : scene_.meshes) {
    const std::size_t dropped = dropDegenerateTriangles(m, min_area_m2);
    if (dropped > 0) dropped_per_object[m.name] += dropped;
    scene_.stats.degenerate_dropped += dropped;
  }
  for (const auto& [object, dropped] : dropped_per_object) {
    warn(fmt::format("{} '{}'", obj_ ? "object" : "node", object),
         fmt::format("{} degenerate triangles dropped (zero area below {:.3g} m^2 or a repeated index)", dropped,
                     min_area_m2));
  }
  const auto empty = std::remove_if(scene_.meshes.begin(), scene_.meshes.end(),
                                    [](const MeshInstance& m) { return m.indices.empty(); });
  scene_.stats.instances_without_triangles = static_cast<std::size_t>(scene_.meshes.end() - empty);
  scene_.meshes.erase(empty, scene_.meshes.end());
  scene_.stats.normals_generated = static_cast<std::size_t>(std::count_if(
      scene_.meshes.begin(), scene_.meshes.end(), [](const MeshInstance& m) { return m.normals_generated; }));
  if (scene_.meshes.empty()) {
    return invalid("scene", fmt::format("has no triangles ({} read, {} degenerate)", scene_.stats.triangles_in,
                                        scene_.stats.degenerate_dropped));
  }
  scene_.bounds = Aabb{};
  for (const MeshInstance& m : scene_.meshes)
    for (std::uint32_t i : m.indices) scene_.bounds.grow(m.positions[i]);
  scene_.scale = scene_.bounds.diagonal();
  return Status::ok();
}

// assimp's OBJ reader adds "DefaultMaterial" for faces without `usemtl`; when every face has
// one, it is not the file's and would only inflate the material count.
void Loader::dropUnusedDefaultMaterial() {
  for (std::size_t i = 0; i < scene_.materials.size(); ++i) {
    if (scene_.materials[i].name != AI_DEFAULT_MATERIAL_NAME) continue;
    const int index = static_cast<int>(i);
    const auto uses = [&](const MeshInstance& m) { return m.material == index; };
    if (std::any_of(scene_.meshes.begin(), scene_.meshes.end(), uses)) return;
    scene_.materials.erase(scene_.materials.begin() + index);
    for (MeshInstance& m : scene_.meshes)
      if (m.material > index) --m.material;
    return;
  }
}

// FBX states its unit as UnitScaleFactor, centimetres per unit (1 for Maya's cm, 100 for
// Blender's metres); lightlink works in metres. assimp leaves coordinates in file units.
double fbxMetresPerUnit(const aiScene& ai) {
  if (ai.mMetaData == nullptr) return 1.0;
  double cm = 0.0;
  float cm_float = 0.0f;
  if (!ai.mMetaData->Get("UnitScaleFactor", cm)) {
    if (!ai.mMetaData->Get("UnitScaleFactor", cm_float)) return 1.0;
    cm = cm_float;
  }
  return std::isfinite(cm) && cm > 0.0 ? cm / 100.0 : 1.0;
}

Status Loader::run(const std::string& bytes) {
  if (obj_) text_ = bytes;
  if (Status s = readFile(bytes); !s) return s;
  if (ai_->mRootNode == nullptr) return invalid("scene", "has no root node");
  if (!obj_) metres_per_unit_ = fbxMetresPerUnit(*ai_);
  if (Status s = validateRaw(placeMeshes(*ai_, metres_per_unit_)); !s) return s;
  ai_ = importer_.ApplyPostProcessing(aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_SortByPType |
                                      aiProcess_FlipUVs);
  if (ai_ == nullptr) return invalidInput("{}: assimp post-processing failed: {}", path_, importer_.GetErrorString());
  if (Status s = loadMaterials(); !s) return s;
  if (Status s = buildGeometry(placeMeshes(*ai_, metres_per_unit_)); !s) return s;
  dropUnusedDefaultMaterial();
  if (ai_->mNumLights > 0)
    warn("scene", fmt::format("{} lights in the file are not read (give lights in a light set)", ai_->mNumLights));
  return Status::ok();
}

}  // namespace

Expected<Scene> loadWithAssimp(const std::string& path, const LoadOptions& options) {
  const std::string ext = lowerExtension(path);
  if (ext != ".obj" && ext != ".fbx")
    return unsupported("{}: the assimp importer reads .obj and .fbx files only", path);
  Expected<SceneFiles> files = SceneFiles::forScene(path, options.files);
  if (!files) return files.status();
  Expected<std::string> bytes = files->readScene();
  if (!bytes) return bytes.status();
  if (bytes->empty()) return invalidInput("{}: the file is empty", path);
  Scene scene;
  scene.source_path = path;
  Loader loader(path, *files, options, ext == ".obj", scene);
  if (Status s = loader.run(*bytes); !s) return s;
  return scene;
}

}  // namespace lightlink::scene
