// Non-finite values that JSON text cannot carry (it has no NaN, and nlohmann rejects
// overflowing numbers) can still reach the ingest steps from an in-memory tinygltf
// model; these tests run the steps on such models and check each one names the object.
#include <limits>

#include <gtest/gtest.h>

#include "core/scene/gltf_context.h"
#include "core/scene/gltf_lights.h"
#include "core/scene/gltf_materials.h"
#include "core/scene/gltf_nodes.h"

namespace lightlink::scene::gltf {
namespace {

const double kNan = std::numeric_limits<double>::quiet_NaN();

struct Fixture {
  tinygltf::Model model;
  Scene scene;
  LoadOptions options;
  Context ctx() { return Context{"mem.gltf", model, scene, options}; }
};

void expectInvalid(const Status& status, std::initializer_list<std::string> parts) {
  ASSERT_FALSE(status.isOk());
  EXPECT_EQ(status.code(), Code::kInvalidInput) << status.toString();
  for (const std::string& part : parts) {
    EXPECT_NE(status.message().find(part), std::string::npos)
        << "missing '" << part << "' in: " << status.message();
  }
}

TEST(GltfInternal, NanNodeRotationIsRejected) {
  Fixture f;
  f.model.nodes.resize(1);
  f.model.nodes[0].name = "Spin";
  f.model.nodes[0].rotation = {0, kNan, 0, 1};
  f.model.scenes.resize(1);
  f.model.scenes[0].nodes = {0};
  Expected<std::vector<PlacedNode>> nodes = placeNodes(f.ctx());
  ASSERT_FALSE(nodes.hasValue());
  expectInvalid(nodes.status(), {"mem.gltf", "node 0 'Spin'", "rotation[1] is not finite"});
}

TEST(GltfInternal, NanMatrixIsRejected) {
  Fixture f;
  f.model.nodes.resize(1);
  f.model.nodes[0].matrix = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, kNan, 0, 0, 1};
  Expected<std::vector<PlacedNode>> nodes = placeNodes(f.ctx());  // no scenes: roots
  ASSERT_FALSE(nodes.hasValue());
  expectInvalid(nodes.status(), {"node 0", "matrix[12] is not finite"});
}

TEST(GltfInternal, NanLightParametersAreRejected) {
  for (const char* field : {"intensity", "range", "color[2]", "spot"}) {
    Fixture f;
    f.model.lights.resize(1);
    tinygltf::Light& l = f.model.lights[0];
    l.name = "Bulb";
    l.type = std::string(field) == "spot" ? "spot" : "point";
    l.color = {1, 1, 1};
    if (std::string(field) == "intensity") l.intensity = kNan;
    if (std::string(field) == "range") l.range = kNan;
    if (std::string(field) == "color[2]") l.color[2] = kNan;
    if (std::string(field) == "spot") l.spot.outerConeAngle = kNan;
    expectInvalid(loadLights(f.ctx(), {}), {"light 0 'Bulb'", field});
  }
}

TEST(GltfInternal, NanMaterialFactorsAreRejected) {
  for (const char* field : {"baseColorFactor[3]", "emissiveFactor[0]", "metallicFactor", "roughnessFactor"}) {
    Fixture f;
    f.model.materials.resize(1);
    tinygltf::Material& m = f.model.materials[0];
    m.name = "Paint";
    m.emissiveFactor = {0, 0, 0};
    const std::string which = field;
    if (which == "baseColorFactor[3]") m.pbrMetallicRoughness.baseColorFactor[3] = kNan;
    if (which == "emissiveFactor[0]") m.emissiveFactor[0] = kNan;
    if (which == "metallicFactor") m.pbrMetallicRoughness.metallicFactor = kNan;
    if (which == "roughnessFactor") m.pbrMetallicRoughness.roughnessFactor = kNan;
    expectInvalid(loadMaterials(f.ctx()), {"material 0 'Paint'", field});
  }
}

}  // namespace
}  // namespace lightlink::scene::gltf
