// make_cornell_box: writes the bundled demo scene, clients/demo/cornell_box.gltf.
//
// Geometry is the classic Cornell box as measured at Cornell (the published data, in
// millimetres, converted to metres): 0.556 x 0.549 x 0.559 m room with an open front
// (z = 0), a short and a tall block. Albedos are the measured reflectances commonly
// used for the box (white 0.725/0.71/0.68, red 0.63/0.065/0.05, green 0.14/0.45/0.091).
// Lights: the ceiling quad emits radiance (17, 12, 4) (emissiveFactor * strength 17) and
// a warm point light of 0.5 cd hangs near the ceiling. A small icosphere on the short
// block is flagged dynamic (extras.lightlink.static = false) so the demo shows the
// static/dynamic split. Everything is written into one self-contained .gltf (base64
// buffer) so the demo needs no other file. The output is deterministic; a test checks the
// committed file still matches this program.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

namespace {

using Json = nlohmann::ordered_json;

struct Part {
  std::string name;
  int material;
  bool is_static = true;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<std::uint16_t> indices;
};

std::string base64(const std::vector<std::uint8_t>& bytes) {
  static const char* kTable = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    std::uint32_t n = std::uint32_t(bytes[i]) << 16;
    if (i + 1 < bytes.size()) n |= std::uint32_t(bytes[i + 1]) << 8;
    if (i + 2 < bytes.size()) n |= bytes[i + 2];
    out += kTable[(n >> 18) & 63];
    out += kTable[(n >> 12) & 63];
    out += i + 1 < bytes.size() ? kTable[(n >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? kTable[n & 63] : '=';
  }
  return out;
}

// Adds a planar quad (corners in order around the rim, millimetres) with flat normals,
// wound so that its normal points towards `towards` (metres).
void addQuad(Part& part, std::array<glm::vec3, 4> mm, glm::vec3 towards) {
  std::array<glm::vec3, 4> p;
  for (int i = 0; i < 4; ++i) p[i] = mm[i] * 0.001f;
  glm::vec3 n = glm::normalize(glm::cross(p[1] - p[0], p[2] - p[0]));
  glm::vec3 centre = 0.25f * (p[0] + p[1] + p[2] + p[3]);
  if (glm::dot(n, towards - centre) < 0.0f) {
    std::swap(p[1], p[3]);
    n = -n;
  }
  auto base = static_cast<std::uint16_t>(part.positions.size());
  for (const auto& q : p) {
    part.positions.push_back(q);
    part.normals.push_back(n);
  }
  for (int i : {0, 1, 2, 0, 2, 3}) part.indices.push_back(static_cast<std::uint16_t>(base + i));
}

// A block given by its top quad (mm) and height; side normals point away from its axis.
void addBlock(Part& part, std::array<glm::vec3, 4> top) {
  glm::vec3 axis = 0.25f * (top[0] + top[1] + top[2] + top[3]) * 0.001f;
  addQuad(part, top, axis + glm::vec3(0, 1, 0));
  for (int i = 0; i < 4; ++i) {
    glm::vec3 a = top[i], b = top[(i + 1) % 4];
    glm::vec3 a0(a.x, 0, a.z), b0(b.x, 0, b.z);
    glm::vec3 mid = 0.5f * (a + b) * 0.001f;
    glm::vec3 away = mid + (glm::vec3(mid.x, 0, mid.z) - glm::vec3(axis.x, 0, axis.z));
    addQuad(part, {a0, a, b, b0}, away);
  }
}

Part icosphere(const std::string& name, int material, glm::vec3 centre, float radius) {
  const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
  std::vector<glm::vec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                              {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                              {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<int, 3>> f = {
      {0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
      {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
      {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (auto& p : v) p = glm::normalize(p);
  // One subdivision: 80 triangles, enough to read as a sphere in the renders.
  std::vector<std::array<int, 3>> g;
  auto mid = [&](int a, int b) {
    v.push_back(glm::normalize(v[a] + v[b]));
    return static_cast<int>(v.size() - 1);
  };
  for (auto [a, b, c] : f) {
    int ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
    g.push_back({a, ab, ca});
    g.push_back({b, bc, ab});
    g.push_back({c, ca, bc});
    g.push_back({ab, bc, ca});
  }
  Part part{name, material, false, {}, {}, {}};
  for (const auto& p : v) {
    part.positions.push_back(centre + radius * p);
    part.normals.push_back(p);
  }
  for (const auto& tri : g)
    for (int i : tri) part.indices.push_back(static_cast<std::uint16_t>(i));
  return part;
}

template <typename T>
void append(std::vector<std::uint8_t>& bytes, const std::vector<T>& values) {
  const auto* p = reinterpret_cast<const std::uint8_t*>(values.data());
  bytes.insert(bytes.end(), p, p + values.size() * sizeof(T));
  while (bytes.size() % 4 != 0) bytes.push_back(0);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: make_cornell_box OUT.gltf\n";
    return 2;
  }
  enum { kWhite, kRed, kGreen, kLight };
  const glm::vec3 room(0.278f, 0.274f, 0.280f);  // inside the room, metres

  Part walls{"WhiteWalls", kWhite, true, {}, {}, {}};
  addQuad(walls, {glm::vec3(552.8f, 0, 0), {0, 0, 0}, {0, 0, 559.2f}, {549.6f, 0, 559.2f}}, room);
  addQuad(walls, {glm::vec3(556, 548.8f, 0), {556, 548.8f, 559.2f}, {0, 548.8f, 559.2f}, {0, 548.8f, 0}}, room);
  addQuad(walls, {glm::vec3(549.6f, 0, 559.2f), {0, 0, 559.2f}, {0, 548.8f, 559.2f}, {556, 548.8f, 559.2f}}, room);
  Part red{"RedWall", kRed, true, {}, {}, {}};
  addQuad(red, {glm::vec3(552.8f, 0, 0), {549.6f, 0, 559.2f}, {556, 548.8f, 559.2f}, {556, 548.8f, 0}}, room);
  Part green{"GreenWall", kGreen, true, {}, {}, {}};
  addQuad(green, {glm::vec3(0, 0, 559.2f), {0, 0, 0}, {0, 548.8f, 0}, {0, 548.8f, 559.2f}}, room);
  Part blocks{"Blocks", kWhite, true, {}, {}, {}};
  addBlock(blocks, {glm::vec3(130, 165, 65), {82, 165, 225}, {240, 165, 272}, {290, 165, 114}});
  addBlock(blocks, {glm::vec3(423, 330, 247), {265, 330, 296}, {314, 330, 456}, {472, 330, 406}});
  // The emitter hangs 0.5 mm below the ceiling so the two never share a plane.
  Part light{"CeilingLight", kLight, true, {}, {}, {}};
  addQuad(light, {glm::vec3(343, 548.3f, 227), {343, 548.3f, 332}, {213, 548.3f, 332}, {213, 548.3f, 227}},
          glm::vec3(0.278f, 0.0f, 0.280f));
  Part probe = icosphere("DynamicProbe", kWhite, glm::vec3(0.186f, 0.225f, 0.169f), 0.05f);

  std::vector<Part> parts = {walls, red, green, blocks, light, probe};

  Json gltf;
  gltf["asset"] = {{"version", "2.0"}, {"generator", "lightlink make_cornell_box"}};
  gltf["extensionsUsed"] = {"KHR_lights_punctual", "KHR_materials_emissive_strength"};
  auto material = [](const char* name, std::array<double, 3> albedo) {
    return Json{{"name", name},
                {"pbrMetallicRoughness",
                 {{"baseColorFactor", {albedo[0], albedo[1], albedo[2], 1.0}},
                  {"metallicFactor", 0.0},
                  {"roughnessFactor", 1.0}}}};
  };
  gltf["materials"] = Json::array({material("White", {0.725, 0.71, 0.68}),
                                   material("Red", {0.63, 0.065, 0.05}),
                                   material("Green", {0.14, 0.45, 0.091}),
                                   material("Light", {0.78, 0.78, 0.78})});
  gltf["materials"][kLight]["emissiveFactor"] = {1.0, 12.0 / 17.0, 4.0 / 17.0};
  gltf["materials"][kLight]["extensions"] = {
      {"KHR_materials_emissive_strength", {{"emissiveStrength", 17.0}}}};

  std::vector<std::uint8_t> bytes;
  Json views = Json::array(), accessors = Json::array(), meshes = Json::array(),
       nodes = Json::array();
  auto addView = [&](std::size_t offset, std::size_t length, int target) {
    views.push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", length}, {"target", target}});
    return static_cast<int>(views.size() - 1);
  };
  for (const auto& part : parts) {
    glm::vec3 lo(1e9f), hi(-1e9f);
    for (const auto& p : part.positions) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    std::size_t pos_at = bytes.size();
    append(bytes, part.positions);
    std::size_t nrm_at = bytes.size();
    append(bytes, part.normals);
    std::size_t idx_at = bytes.size();
    append(bytes, part.indices);
    const auto count = part.positions.size();
    int pv = addView(pos_at, count * 12, 34962);
    int nv = addView(nrm_at, count * 12, 34962);
    int iv = addView(idx_at, part.indices.size() * 2, 34963);
    int pa = static_cast<int>(accessors.size());
    accessors.push_back({{"bufferView", pv}, {"componentType", 5126}, {"count", count},
                         {"type", "VEC3"}, {"min", {lo.x, lo.y, lo.z}}, {"max", {hi.x, hi.y, hi.z}}});
    accessors.push_back({{"bufferView", nv}, {"componentType", 5126}, {"count", count}, {"type", "VEC3"}});
    accessors.push_back({{"bufferView", iv}, {"componentType", 5123},
                         {"count", part.indices.size()}, {"type", "SCALAR"}});
    Json primitive;
    primitive["attributes"] = {{"POSITION", pa}, {"NORMAL", pa + 1}};
    primitive["indices"] = pa + 2;
    primitive["material"] = part.material;
    Json mesh;
    mesh["name"] = part.name;
    mesh["primitives"] = Json::array({primitive});
    meshes.push_back(mesh);
    Json node = {{"name", part.name}, {"mesh", meshes.size() - 1}};
    if (!part.is_static) node["extras"] = {{"lightlink", {{"static", false}}}};
    nodes.push_back(node);
  }
  // The point light: glTF lights shine along the node's -Z; a point light has no
  // direction, so only the translation matters.
  Json light_node;
  light_node["name"] = "PointLight";
  light_node["translation"] = {0.40, 0.45, 0.40};
  light_node["extensions"]["KHR_lights_punctual"]["light"] = 0;
  nodes.push_back(light_node);
  Json bulb;
  bulb["name"] = "WarmBulb";
  bulb["type"] = "point";
  bulb["color"] = {1.0, 0.85, 0.7};
  bulb["intensity"] = 0.5;
  gltf["extensions"]["KHR_lights_punctual"]["lights"] = Json::array({bulb});
  Json scene_nodes = Json::array();
  for (std::size_t i = 0; i < nodes.size(); ++i) scene_nodes.push_back(i);
  gltf["scene"] = 0;
  Json scene;
  scene["name"] = "CornellBox";
  scene["nodes"] = scene_nodes;
  gltf["scenes"] = Json::array({scene});
  gltf["nodes"] = nodes;
  gltf["meshes"] = meshes;
  gltf["accessors"] = accessors;
  gltf["bufferViews"] = views;
  Json buffer;
  buffer["byteLength"] = bytes.size();
  buffer["uri"] = "data:application/octet-stream;base64," + base64(bytes);
  gltf["buffers"] = Json::array({buffer});

  std::ofstream out(argv[1], std::ios::binary | std::ios::trunc);
  out << gltf.dump(1) << "\n";
  if (!out) {
    std::cerr << "make_cornell_box: cannot write " << argv[1] << "\n";
    return 1;
  }
  return 0;
}
