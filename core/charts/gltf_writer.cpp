#include "core/charts/gltf_writer.h"

#include "core/charts/gltf_append.h"

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>

#include <tiny_gltf.h>

#include "core/charts/gltf_scene_writer.h"
#include "core/scene/load.h"

namespace lightlink::charts {
namespace {

namespace fs = std::filesystem;

// Images are neither decoded nor re-encoded: the loader keeps the uri (or bufferView)...
bool skipImageLoad(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int,
                   void*) {
  return true;
}

struct ImageCopy {
  const scene::SceneFiles* from;
  fs::path to_dir;  // canonical
  const tinygltf::Image* bake_image;  // the bound irradiance map: written by the bake, never copied
  Status status;
};

// Where an image uri lands next to the output: only inside the output's folder (a uri
// with `..` or an absolute path, possible when reading outside was allowed, is refused
// rather than written wherever it points).
Expected<fs::path> copyTarget(const fs::path& to_dir, const std::string& uri) {
  const std::string name = scene::SceneFiles::decodeUri(uri);
  // Links resolved, dangling ones too: writing through one must not land outside either.
  const Expected<fs::path> resolved = scene::resolvePath(to_dir / fs::path(name).relative_path());
  const fs::path to = resolved ? *resolved : fs::path();
  const fs::path rel = to.lexically_relative(to_dir);
  if (!resolved || name.empty() || name.front() == '/' || rel.empty() || *rel.begin() == "..")
    return invalidInput("glTF writer: image uri '{}' would be copied outside the output's folder", uri.substr(0, 120));
  return to;
}

// ...and the writer keeps the uri, copying the file next to the output if needed.
// Returning false tells tinygltf to write the original uri unchanged.
bool copyImageFile(const std::string*, const std::string*, const tinygltf::Image* image, bool, std::string*,
                   void* user) {
  auto* ctx = static_cast<ImageCopy*>(user);
  if (image == ctx->bake_image) return false;
  if (!ctx->status || image->uri.empty() || image->uri.rfind("data:", 0) == 0 || ctx->from->folder() == ctx->to_dir)
    return false;
  Expected<fs::path> from = ctx->from->resolveUri(image->uri, "image uri");
  if (!from) {
    ctx->status = from.status();
    return false;
  }
  std::error_code ec;
  if (!fs::exists(*from, ec)) return false;  // the loader warned about the missing image already
  Expected<fs::path> to = copyTarget(ctx->to_dir, image->uri);
  if (!to) {
    ctx->status = to.status();
    return false;
  }
  std::error_code same_ec;  // `to` may not exist yet: that is not an error
  if (fs::equivalent(*from, *to, same_ec)) return false;
  Expected<std::string> bytes = scene::readRegularFile(*from, fmt::format("glTF writer: image '{}'", image->uri));
  if (!bytes) {
    ctx->status = bytes.status();
    return false;
  }
  fs::create_directories(to->parent_path(), ec);
  std::ofstream out(*to, std::ios::binary | std::ios::trunc);
  out.write(bytes->data(), static_cast<std::streamsize>(bytes->size()));
  if (ec || !out.flush()) ctx->status = ioError("glTF writer: could not copy image '{}' to {}", image->uri, to->string());
  return false;
}

int componentBytes(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    case TINYGLTF_COMPONENT_TYPE_DOUBLE: return 8;
    default: return 0;
  }
}

class ModelEditor : public GltfAppender {
 public:
  explicit ModelEditor(tinygltf::Model& model) : GltfAppender(model) {}

  // All buffers into buffer 0, each old one starting 16-byte aligned.
  void mergeBuffers() {
    std::vector<unsigned char> merged;
    std::vector<std::size_t> offset(model_.buffers.size());
    for (std::size_t b = 0; b < model_.buffers.size(); ++b) {
      merged.resize((merged.size() + 15) / 16 * 16, 0);
      offset[b] = merged.size();
      merged.insert(merged.end(), model_.buffers[b].data.begin(), model_.buffers[b].data.end());
    }
    for (tinygltf::BufferView& bv : model_.bufferViews) {
      bv.byteOffset += offset[static_cast<std::size_t>(bv.buffer)];
      bv.buffer = 0;
    }
    tinygltf::Buffer one;
    if (!model_.buffers.empty()) {
      one.name = model_.buffers[0].name;
      one.extras = model_.buffers[0].extras;
    }
    one.data = std::move(merged);
    model_.buffers.assign(1, std::move(one));
  }

  // New accessor with the elements of `src` listed in `source_vertex`, bytes as stored.
  Expected<int> gather(int src, const std::vector<std::uint32_t>& source_vertex, const std::string& what) {
    const tinygltf::Accessor& a = model_.accessors[static_cast<std::size_t>(src)];
    if (a.sparse.isSparse) return unsupported("glTF writer: sparse accessor {} ({}) cannot be re-indexed", src, what);
    const int elem = componentBytes(a.componentType) * tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(a.type));
    if (elem <= 0) return invalidInput("glTF writer: accessor {} ({}) has an unknown element type", src, what);
    std::vector<unsigned char> out(source_vertex.size() * static_cast<std::size_t>(elem), 0);
    if (a.bufferView >= 0) {
      const tinygltf::BufferView& bv = model_.bufferViews[static_cast<std::size_t>(a.bufferView)];
      const std::size_t stride = bv.byteStride > 0 ? bv.byteStride : static_cast<std::size_t>(elem);
      const std::vector<unsigned char>& data = model_.buffers[0].data;
      for (std::size_t i = 0; i < source_vertex.size(); ++i) {
        const std::size_t v = source_vertex[i];
        const std::size_t at = bv.byteOffset + a.byteOffset + v * stride;
        if (v >= a.count || at + static_cast<std::size_t>(elem) > data.size())
          return invalidInput("glTF writer: accessor {} ({}) has no element {}", src, what, v);
        std::memcpy(&out[i * static_cast<std::size_t>(elem)], &data[at], static_cast<std::size_t>(elem));
      }
    }
    tinygltf::Accessor na = a;
    na.bufferView = addView(out.data(), out.size(), TINYGLTF_TARGET_ARRAY_BUFFER);
    na.byteOffset = 0;
    na.count = source_vertex.size();
    if (a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT && !a.minValues.empty()) {
      // Dropped degenerate faces may drop extremes: recompute the bounds glTF asks for.
      const int nc = tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(a.type));
      na.minValues.assign(static_cast<std::size_t>(nc), std::numeric_limits<double>::max());
      na.maxValues.assign(static_cast<std::size_t>(nc), std::numeric_limits<double>::lowest());
      for (std::size_t i = 0; i < source_vertex.size(); ++i) {
        for (int c = 0; c < nc; ++c) {
          float f;
          std::memcpy(&f, &out[i * static_cast<std::size_t>(elem) + 4 * static_cast<std::size_t>(c)], 4);
          na.minValues[static_cast<std::size_t>(c)] = std::min(na.minValues[static_cast<std::size_t>(c)], double(f));
          na.maxValues[static_cast<std::size_t>(c)] = std::max(na.maxValues[static_cast<std::size_t>(c)], double(f));
        }
      }
      if (source_vertex.empty()) na.minValues.clear(), na.maxValues.clear();
    }
    return push(std::move(na));
  }

};

// A material whose textures sample TEXCOORD_1 would sample the lightmap uv once it is
// replaced; such primitives get a copy of the material reading the old set under its new
// name TEXCOORD_<set> instead. Returns the material to use.
int remapMaterialTexCoord1(tinygltf::Model& model, int material, int set, std::map<std::pair<int, int>, int>& copies) {
  if (material < 0 || static_cast<std::size_t>(material) >= model.materials.size()) return material;
  const tinygltf::Material& m = model.materials[static_cast<std::size_t>(material)];
  const bool uses1 = (m.pbrMetallicRoughness.baseColorTexture.index >= 0 && m.pbrMetallicRoughness.baseColorTexture.texCoord == 1) ||
                     (m.pbrMetallicRoughness.metallicRoughnessTexture.index >= 0 &&
                      m.pbrMetallicRoughness.metallicRoughnessTexture.texCoord == 1) ||
                     (m.normalTexture.index >= 0 && m.normalTexture.texCoord == 1) ||
                     (m.occlusionTexture.index >= 0 && m.occlusionTexture.texCoord == 1) ||
                     (m.emissiveTexture.index >= 0 && m.emissiveTexture.texCoord == 1);
  if (!uses1) return material;
  auto [it, inserted] = copies.try_emplace({material, set}, static_cast<int>(model.materials.size()));
  if (inserted) {
    tinygltf::Material copy = m;
    auto remap = [set](int& tc) {
      if (tc == 1) tc = set;
    };
    remap(copy.pbrMetallicRoughness.baseColorTexture.texCoord);
    remap(copy.pbrMetallicRoughness.metallicRoughnessTexture.texCoord);
    remap(copy.normalTexture.texCoord);
    remap(copy.occlusionTexture.texCoord);
    remap(copy.emissiveTexture.texCoord);
    model.materials.push_back(std::move(copy));
  }
  return it->second;
}

bool endsWith(const std::string& s, const std::string& suffix) {
  if (s.size() < suffix.size()) return false;
  return std::equal(suffix.rbegin(), suffix.rend(), s.rbegin(),
                    [](char a, char b) { return std::tolower(static_cast<unsigned char>(a)) == b; });
}

}  // namespace

bool isLightmapped(const scene::Scene& scene, const LightmapAtlas& atlas, std::size_t m) {
  const scene::MeshInstance& inst = scene.meshes[m];
  return inst.is_static && !inst.uv1.empty() &&
         std::find(atlas.probe_lit.begin(), atlas.probe_lit.end(), static_cast<std::uint32_t>(m)) == atlas.probe_lit.end();
}

Status writeGltfWithLightmapUv(const std::string& in_path, const scene::Scene& scene, const LightmapAtlas& atlas,
                               const std::string& out_path, const scene::FileAccess& access,
                               const GltfLighting& lighting) {
  const bool out_glb = endsWith(out_path, ".glb");
  if (!out_glb && !endsWith(out_path, ".gltf"))
    return invalidInput("glTF writer: output '{}' must end in .gltf or .glb", out_path);
  std::error_code ec;
  if (fs::weakly_canonical(in_path, ec) == fs::weakly_canonical(out_path, ec))
    return invalidInput("glTF writer: output '{}' would overwrite the input", out_path);
  if (atlas.meshes.size() != scene.meshes.size())
    return internalError("glTF writer: atlas has {} meshes, scene {}", atlas.meshes.size(), scene.meshes.size());
  // An OBJ or FBX has no glTF to edit: the lightmapped scene is written from the Scene.
  if (scene::isAssimpScenePath(in_path)) {
    std::vector<bool> lightmapped(scene.meshes.size());
    for (std::size_t m = 0; m < scene.meshes.size(); ++m) lightmapped[m] = isLightmapped(scene, atlas, m);
    return writeGltfFromScene(in_path, scene, out_path, access, lighting, lightmapped);
  }

  Expected<scene::SceneFiles> files = scene::SceneFiles::forScene(in_path, access);
  if (!files) return files.status();
  Expected<std::string> bytes = files->readScene();
  if (!bytes) return bytes.status();
  if (bytes->size() > std::numeric_limits<unsigned int>::max())
    return invalidInput("glTF writer: '{}' is too large", in_path);
  tinygltf::TinyGLTF io;
  files->install(io);
  io.SetImageLoader(&skipImageLoad, nullptr);
  tinygltf::Model model;
  std::string err, warn;
  const auto size = static_cast<unsigned int>(bytes->size());
  const bool ok = bytes->compare(0, 4, "glTF") == 0
                      ? io.LoadBinaryFromMemory(&model, &err, &warn,
                                                reinterpret_cast<const unsigned char*>(bytes->data()), size,
                                                files->folder().string())
                      : io.LoadASCIIFromString(&model, &err, &warn, bytes->data(), size, files->folder().string());
  if (!ok) return ioError("glTF writer: cannot read '{}': {}", in_path, err);

  ModelEditor edit(model);
  edit.mergeBuffers();

  // Instances to rewrite, grouped by glTF mesh; within a mesh by node, so the lowest node
  // keeps the original mesh object and later nodes get copies.
  std::map<int, std::map<int, std::vector<std::size_t>>> by_mesh;  // mesh -> node -> instances
  std::map<std::pair<int, int>, int> material_copies;               // (material, set) -> copy
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    if (atlas.meshes[m].source_vertex.empty()) continue;
    const scene::MeshInstance& inst = scene.meshes[m];
    if (inst.gltf_mesh < 0 || inst.gltf_node < 0 || static_cast<std::size_t>(inst.gltf_mesh) >= model.meshes.size() ||
        static_cast<std::size_t>(inst.gltf_node) >= model.nodes.size() ||
        model.nodes[static_cast<std::size_t>(inst.gltf_node)].mesh != inst.gltf_mesh ||
        static_cast<std::size_t>(inst.gltf_primitive) >=
            model.meshes[static_cast<std::size_t>(inst.gltf_mesh)].primitives.size())
      return invalidInput("glTF writer: mesh '{}' (node {}, mesh {}, primitive {}) does not match '{}'", inst.name,
                          inst.gltf_node, inst.gltf_mesh, inst.gltf_primitive, in_path);
    by_mesh[inst.gltf_mesh][inst.gltf_node].push_back(m);
  }
  for (auto& [mesh_index, nodes] : by_mesh) {
    const tinygltf::Mesh original = model.meshes[static_cast<std::size_t>(mesh_index)];
    // Nodes that keep the mesh as it is (dynamic ones): then every static node gets a copy.
    bool first = true;
    for (std::size_t n = 0; n < model.nodes.size() && first; ++n)
      if (model.nodes[n].mesh == mesh_index && !nodes.count(static_cast<int>(n))) first = false;
    for (auto& [node_index, instances] : nodes) {
      int target = mesh_index;
      if (!first) {
        model.meshes.push_back(original);
        target = static_cast<int>(model.meshes.size() - 1);
        model.nodes[static_cast<std::size_t>(node_index)].mesh = target;
      }
      first = false;
      for (std::size_t m : instances) {
        const scene::MeshInstance& inst = scene.meshes[m];
        const std::vector<std::uint32_t>& src = atlas.meshes[m].source_vertex;
        tinygltf::Primitive prim = original.primitives[static_cast<std::size_t>(inst.gltf_primitive)];
        if (inst.positions.size() != src.size() || inst.uv1.size() != src.size())
          return internalError("glTF writer: mesh '{}' has {} vertices, {} uv1, {} source entries", inst.name,
                               inst.positions.size(), inst.uv1.size(), src.size());
        std::map<std::string, int> attributes;
        int old_uv1_set = -1;  // where a replaced TEXCOORD_1 moves to
        for (const auto& [name, accessor] : prim.attributes) {
          std::string out_name = name;
          if (name == "TEXCOORD_1") {
            old_uv1_set = 2;
            while (prim.attributes.count("TEXCOORD_" + std::to_string(old_uv1_set))) ++old_uv1_set;
            out_name = "TEXCOORD_" + std::to_string(old_uv1_set);
          }
          Expected<int> a = edit.gather(accessor, src, inst.name + " " + name);
          if (!a) return a.status();
          attributes[out_name] = *a;
        }
        attributes["TEXCOORD_1"] = edit.addVec2(inst.uv1);
        if (old_uv1_set >= 0) prim.material = remapMaterialTexCoord1(model, prim.material, old_uv1_set, material_copies);
        for (std::map<std::string, int>& target_attrs : prim.targets) {
          for (auto& [name, accessor] : target_attrs) {
            Expected<int> a = edit.gather(accessor, src, inst.name + " morph " + name);
            if (!a) return a.status();
            accessor = *a;
          }
        }
        prim.attributes = std::move(attributes);
        // The scene swapped two corners under mirroring transforms to keep world-space
        // winding; the file stores the mesh-space winding.
        std::vector<std::uint32_t> indices = inst.indices;
        if (glm::determinant(glm::dmat3(glm::dmat4(inst.world_from_mesh))) < 0.0)
          for (std::size_t t = 0; t + 2 < indices.size(); t += 3) std::swap(indices[t + 1], indices[t + 2]);
        prim.indices = edit.addIndices(indices, src.size());
        prim.mode = TINYGLTF_MODE_TRIANGLES;
        model.meshes[static_cast<std::size_t>(target)].primitives[static_cast<std::size_t>(inst.gltf_primitive)] =
            std::move(prim);
      }
    }
  }

  // glTF's TEXCOORD sets start at 0: where the source had none, the lightmap uv (written
  // here, or a kept TEXCOORD_1 the source gave without a set 0) is set 0 too.
  for (tinygltf::Mesh& mesh : model.meshes)
    for (tinygltf::Primitive& prim : mesh.primitives)
      if (const auto uv1 = prim.attributes.find("TEXCOORD_1"); uv1 != prim.attributes.end() && !prim.attributes.count("TEXCOORD_0"))
        prim.attributes["TEXCOORD_0"] = uv1->second;

  // Lightmapped primitives where they now live (a static instance may have moved to a copy).
  int bake_image = -1;
  if (!lighting.empty()) {
    std::vector<std::pair<int, int>> lightmapped;
    for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
      const scene::MeshInstance& inst = scene.meshes[m];
      if (!isLightmapped(scene, atlas, m) || inst.gltf_node < 0 ||
          static_cast<std::size_t>(inst.gltf_node) >= model.nodes.size())
        continue;
      lightmapped.emplace_back(model.nodes[static_cast<std::size_t>(inst.gltf_node)].mesh, inst.gltf_primitive);
    }
    Expected<int> bound = addGltfLighting(model, lightmapped, lighting);
    if (!bound) return bound.status();
    bake_image = *bound;
  }

  const fs::path out_fs(out_path);
  if (!model.buffers.empty()) model.buffers[0].uri = out_glb ? "" : out_fs.stem().string() + ".bin";
  Expected<fs::path> out_dir = scene::resolvePath(fs::absolute(out_fs).parent_path());
  if (!out_dir) return out_dir.status();
  ImageCopy images{&*files, *out_dir, bake_image >= 0 ? &model.images[static_cast<std::size_t>(bake_image)] : nullptr,
                   Status::ok()};
  tinygltf::TinyGLTF writer;  // default file callbacks: it writes the output, which the reader may not
  writer.SetImageWriter(&copyImageFile, &images);
  if (!writer.WriteGltfSceneToFile(&model, out_path, /*embedImages=*/false, /*embedBuffers=*/false,
                                   /*prettyPrint=*/true, /*writeBinary=*/out_glb))
    return ioError("glTF writer: cannot write '{}'", out_path);
  if (!images.status) return images.status;
  return Status::ok();
}

}  // namespace lightlink::charts
