#include "bench/common/bench_common.h"

#include <algorithm>
#include <cstring>

#include <glm/geometric.hpp>

namespace lightlink::bench {

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

bool parsePrecomputeFlag(const std::string& flag, const char* value, precompute::PrecomputeOptions& options) {
  if (flag == "--surfels") options.surfels = static_cast<std::uint32_t>(std::stoul(value));
  else if (flag == "--links") options.links = std::stoi(value);
  else if (flag == "--bands") options.bands = std::stoi(value);
  else if (flag == "--rays") options.rays = std::stoi(value);
  else if (flag == "--resolution") options.lightmap_resolution = std::stoi(value);
  else if (flag == "--hierarchy") {
    const auto builder = enumValue(hierarchy::kBuilderNames, value);
    if (!builder) return false;
    options.builder = *builder;
  }
  else return false;
  return true;
}

relight::LightSet lightsOrSun(const scene::Scene& scene) {
  relight::LightSet lights = relight::LightSet::fromSceneLights(scene.lights);
  if (lights.lights().empty()) {
    relight::LightEntry sun;
    sun.id = "sun";
    sun.light.kind = scene::Light::Kind::kDirectional;
    sun.light.direction = glm::normalize(glm::vec3(-0.3f, -1.0f, -0.2f));
    sun.light.intensity = 10.0f;  // lux
    // A fresh set with one valid directional light: add() cannot fail.
    (void)lights.add(sun);
  }
  return lights;
}

}  // namespace lightlink::bench
