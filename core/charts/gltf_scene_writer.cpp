#include "core/charts/gltf_scene_writer.h"

#include "core/charts/gltf_append.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>

#include <tiny_gltf.h>

namespace lightlink::charts {
namespace {

namespace fs = std::filesystem;

bool endsWith(const std::string& s, const char* suffix) {
  const std::size_t n = std::strlen(suffix);
  return s.size() >= n && std::equal(s.end() - static_cast<std::ptrdiff_t>(n), s.end(), suffix, suffix + n,
                                     [](char a, char b) { return std::tolower(static_cast<unsigned char>(a)) == b; });
}

// glTF URIs are percent-encoded; the loader decodes %XX and '+', so anything but the
// unreserved characters and '/' is escaped.
std::string encodeUri(const std::string& name) {
  std::string out;
  for (unsigned char c : name) {
    if (std::isalnum(c) || c == '-' || c == '.' || c == '_' || c == '~' || c == '/') {
      out += static_cast<char>(c);
    } else {
      out += fmt::format("%{:02X}", c);
    }
  }
  return out;
}

// Copies the texture files the materials use next to the output and gives each its glTF
// texture index (-1: left out). Names inside the scene folder keep their relative path;
// a file read from outside it (allowed by FileAccess) lands under its file name.
class TextureCopier {
 public:
  TextureCopier(const scene::SceneFiles& files, fs::path out_dir, tinygltf::Model& model)
      : files_(files), out_dir_(std::move(out_dir)), model_(model) {}

  Expected<int> textureFor(const scene::Scene& scene, const scene::TextureRef& ref) {
    if (!ref.valid() || static_cast<std::size_t>(ref.texture) >= scene.textures.size()) return -1;
    if (const auto it = done_.find(ref.texture); it != done_.end()) return it->second;
    const std::string& name = scene.textures[static_cast<std::size_t>(ref.texture)].name;
    int index = -1;
    if (!name.empty() && name.front() != '*') {  // "*N": an image embedded in the FBX
      Expected<fs::path> from = files_.resolveName(name, "texture");
      if (!from) return from.status();
      std::error_code ec;
      if (fs::is_regular_file(*from, ec)) {
        fs::path rel = fs::path(name).lexically_normal();
        if (rel.is_absolute() || rel.empty() || *rel.begin() == "..") rel = rel.filename();
        const fs::path to = out_dir_ / rel;
        if (!fs::equivalent(*from, to, ec)) {
          Expected<std::string> bytes = scene::readRegularFile(*from, fmt::format("glTF writer: texture '{}'", name));
          if (!bytes) return bytes.status();
          fs::create_directories(to.parent_path(), ec);
          std::ofstream out(to, std::ios::binary | std::ios::trunc);
          out.write(bytes->data(), static_cast<std::streamsize>(bytes->size()));
          if (!out.flush()) return ioError("glTF writer: could not copy texture '{}' to {}", name, to.string());
        }
        tinygltf::Image image;
        image.uri = encodeUri(rel.generic_string());
        model_.images.push_back(std::move(image));
        tinygltf::Texture texture;
        texture.source = static_cast<int>(model_.images.size() - 1);
        model_.textures.push_back(std::move(texture));
        index = static_cast<int>(model_.textures.size() - 1);
      }
    }
    done_[ref.texture] = index;
    return index;
  }

 private:
  const scene::SceneFiles& files_;
  fs::path out_dir_;
  tinygltf::Model& model_;
  std::map<int, int> done_;
};

// Images are written by us (copied above), never by tinygltf.
bool keepImageUri(const std::string*, const std::string*, const tinygltf::Image*, bool, std::string*, void*) {
  return false;
}

}  // namespace

Status writeGltfFromScene(const std::string& in_path, const scene::Scene& scene, const std::string& out_path,
                          const scene::FileAccess& access, const GltfLighting& lighting,
                          const std::vector<bool>& lightmapped) {
  const bool out_glb = endsWith(out_path, ".glb");
  if (!out_glb && !endsWith(out_path, ".gltf"))
    return invalidInput("glTF writer: output '{}' must end in .gltf or .glb", out_path);
  Expected<scene::SceneFiles> files = scene::SceneFiles::forScene(in_path, access);
  if (!files) return files.status();
  const fs::path out_fs(out_path);
  Expected<fs::path> out_dir = scene::resolvePath(fs::absolute(out_fs).parent_path());
  if (!out_dir) return out_dir.status();

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "lightlink (from " + fs::path(in_path).filename().string() + ")";
  GltfAppender build(model);
  TextureCopier textures(*files, *out_dir, model);
  bool emissive_strength_used = false;
  for (const scene::Material& m : scene.materials) {
    tinygltf::Material gm;
    gm.name = m.name;
    gm.pbrMetallicRoughness.baseColorFactor = {m.base_color_factor.x, m.base_color_factor.y, m.base_color_factor.z,
                                               m.base_color_factor.w};
    gm.pbrMetallicRoughness.metallicFactor = m.metallic;
    gm.pbrMetallicRoughness.roughnessFactor = m.roughness;
    gm.doubleSided = m.double_sided;
    Expected<int> base = textures.textureFor(scene, m.base_color_texture);
    if (!base) return base.status();
    gm.pbrMetallicRoughness.baseColorTexture.index = *base;
    gm.emissiveFactor = {m.emissive_factor.x, m.emissive_factor.y, m.emissive_factor.z};
    Expected<int> glow = textures.textureFor(scene, m.emissive_texture);
    if (!glow) return glow.status();
    gm.emissiveTexture.index = *glow;
    if (m.emissive_strength != 1.0f && m.isEmissive()) {
      tinygltf::Value::Object strength;
      strength["emissiveStrength"] = tinygltf::Value(static_cast<double>(m.emissive_strength));
      gm.extensions["KHR_materials_emissive_strength"] = tinygltf::Value(std::move(strength));
      emissive_strength_used = true;
    }
    model.materials.push_back(std::move(gm));
  }
  if (emissive_strength_used) model.extensionsUsed.push_back("KHR_materials_emissive_strength");

  tinygltf::Scene root;
  std::vector<std::pair<int, int>> lit_primitives;
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    const scene::MeshInstance& inst = scene.meshes[m];
    if (inst.positions.empty() || inst.indices.empty()) continue;
    const std::size_t n = inst.positions.size();
    if (inst.normals.size() != n || (!inst.uv0.empty() && inst.uv0.size() != n) ||
        (!inst.uv1.empty() && inst.uv1.size() != n))
      return internalError("glTF writer: mesh '{}' has {} positions, {} normals, {} uv0, {} uv1", inst.name,
                           inst.positions.size(), inst.normals.size(), inst.uv0.size(), inst.uv1.size());
    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    prim.material = inst.material;
    prim.attributes["POSITION"] = build.addVec3(inst.positions, true);
    prim.attributes["NORMAL"] = build.addVec3(inst.normals, false);
    if (!inst.uv0.empty()) prim.attributes["TEXCOORD_0"] = build.addVec2(inst.uv0);
    if (!inst.uv1.empty()) {
      prim.attributes["TEXCOORD_1"] = build.addVec2(inst.uv1);
      // glTF's TEXCOORD sets start at 0: without a uv0 the lightmap uv is set 0 too.
      if (inst.uv0.empty()) prim.attributes["TEXCOORD_0"] = prim.attributes["TEXCOORD_1"];
    }
    prim.indices = build.addIndices(inst.indices, inst.positions.size());
    tinygltf::Mesh mesh;
    mesh.name = inst.name;
    mesh.primitives.push_back(std::move(prim));
    model.meshes.push_back(std::move(mesh));
    if (m < lightmapped.size() && lightmapped[m]) lit_primitives.emplace_back(static_cast<int>(model.meshes.size() - 1), 0);
    tinygltf::Node node;
    node.name = inst.name;
    node.mesh = static_cast<int>(model.meshes.size() - 1);
    if (!inst.is_static) {
      tinygltf::Value::Object flags;
      flags["static"] = tinygltf::Value(false);
      tinygltf::Value::Object extras;
      extras["lightlink"] = tinygltf::Value(std::move(flags));
      node.extras = tinygltf::Value(std::move(extras));
    }
    model.nodes.push_back(std::move(node));
    root.nodes.push_back(static_cast<int>(model.nodes.size() - 1));
  }
  model.scenes.push_back(std::move(root));
  model.defaultScene = 0;
  if (!lighting.empty())
    if (Expected<int> bound = addGltfLighting(model, lit_primitives, lighting); !bound) return bound.status();
  model.buffers[0].uri = out_glb ? "" : out_fs.stem().string() + ".bin";

  tinygltf::TinyGLTF writer;
  writer.SetImageWriter(&keepImageUri, nullptr);
  if (!writer.WriteGltfSceneToFile(&model, out_path, /*embedImages=*/false, /*embedBuffers=*/false,
                                   /*prettyPrint=*/true, /*writeBinary=*/out_glb))
    return ioError("glTF writer: cannot write '{}'", out_path);
  return Status::ok();
}

}  // namespace lightlink::charts
