// suggest_lights: writes a light-set file (docs/lightset.md) for a level that has no lights,
// as a level designer's first pass would: a sun and sky when much of the playable space sees
// the sky, and point lights at the most open spots of the covered space. Used to author the
// light sets of the shared game levels (tests/levels/lights/*.json); deterministic.
//
//   suggest_lights SCENE OUT.json [--points N] [--grid N]
//
// Candidates are the points of a grid over the scene's bounds. A candidate is playable
// space when at least 95 % of 96 directions hit something or the sky and no ray hits a back
// face first (it is not inside a wall or below the terrain); its clearance is the distance
// to the nearest hit; it is covered when no upward ray escapes. Point lights go to covered
// candidates by farthest-point sampling weighted by clearance, each as bright as gives
// ~200 lux at its clearance distance (units: the scene's, as if metres).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/rt/accel.h"
#include "core/scene/load.h"

using namespace lightlink;

namespace {

struct Candidate {
  glm::vec3 p;
  float clearance;
  float sky_up;  // fraction of upper-hemisphere rays that escape
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: suggest_lights SCENE OUT.json [--points N] [--grid N]\n");
    return 1;
  }
  int points = 6, grid = 24;
  for (int i = 3; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--points")) points = std::clamp(std::atoi(argv[i + 1]), 1, 64);
    else if (!std::strcmp(argv[i], "--grid")) grid = std::clamp(std::atoi(argv[i + 1]), 4, 128);
  }
  auto scene = scene::loadScene(argv[1]);
  if (!scene) {
    std::fprintf(stderr, "%s\n", scene.status().toString().c_str());
    return 2;
  }
  auto accel = rt::Accel::build(*scene);
  if (!accel) {
    std::fprintf(stderr, "%s\n", accel.status().toString().c_str());
    return 2;
  }
  const glm::vec3 lo = scene->bounds.min, hi = scene->bounds.max, ext = hi - lo;
  const float step = std::max({ext.x, ext.y, ext.z}) / float(grid);
  const glm::ivec3 dims = glm::max(glm::ivec3(glm::ceil(ext / step)), glm::ivec3(1));
  // Fibonacci sphere: even, deterministic directions.
  constexpr int kDirs = 96;
  std::vector<glm::vec3> dirs;
  for (int i = 0; i < kDirs; ++i) {
    const float z = 1.0f - (2.0f * float(i) + 1.0f) / float(kDirs);
    const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
    const float phi = 2.39996323f * float(i);
    dirs.emplace_back(r * std::cos(phi), z, r * std::sin(phi));  // y up
  }
  std::vector<Candidate> playable;
  std::size_t up_total = 0, up_open = 0;
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const glm::vec3 p = lo + (glm::vec3(x, y, z) + 0.5f) * step;
        int back = 0, up = 0, up_escape = 0;
        float nearest = std::numeric_limits<float>::max();
        for (const glm::vec3& d : dirs) {
          const rt::Hit h = accel->intersect({p, 0.0f, d});
          if (d.y > 0.2f) ++up;
          if (!h.hit()) {
            if (d.y > 0.2f) ++up_escape;
            continue;
          }
          nearest = std::min(nearest, h.t);
          back += h.backFacing(d);
        }
        if (back > kDirs / 20) continue;  // inside a wall or under the ground
        if (nearest == std::numeric_limits<float>::max()) continue;  // floating outside the level
        // Not playable when most of the lower hemisphere escapes too (above the level).
        int down_escape = 0, down = 0;
        for (const glm::vec3& d : dirs)
          if (d.y < -0.2f) {
            ++down;
            down_escape += !accel->intersect({p, 0.0f, d}).hit();
          }
        if (down_escape * 2 > down) continue;
        playable.push_back({p, nearest, float(up_escape) / float(std::max(up, 1))});
        up_total += up;
        up_open += up_escape;
      }
  if (playable.empty()) {
    std::fprintf(stderr, "no playable space found in %s\n", argv[1]);
    return 2;
  }
  const double sky_share = double(up_open) / double(std::max<std::size_t>(up_total, 1));
  const bool open = sky_share > 0.15;
  nlohmann::ordered_json lights = nlohmann::ordered_json::array();
  if (open)
    lights.push_back({{"id", "sun"}, {"type", "directional"}, {"direction", {-0.35, -1.0, -0.25}},
                      {"intensity", 1000.0}, {"color", {1.0, 0.95, 0.88}}});
  // Farthest-point sampling over covered candidates, scored by distance to the chosen
  // lights times clearance (open spots first, spread out).
  std::vector<Candidate> covered;
  for (const Candidate& c : playable)
    if (c.sky_up == 0.0f) covered.push_back(c);
  std::vector<glm::vec3> chosen;
  std::vector<float> chosen_clearance;
  const int wanted = open ? std::max(1, points / 2) : points;
  for (int k = 0; k < wanted && !covered.empty(); ++k) {
    std::size_t best = 0;
    float best_score = -1.0f;
    for (std::size_t i = 0; i < covered.size(); ++i) {
      float d = std::numeric_limits<float>::max();
      for (const glm::vec3& q : chosen) d = std::min(d, glm::length(covered[i].p - q));
      if (d < step) continue;  // a chosen spot, or next to one
      const float score = covered[i].clearance * (chosen.empty() ? 1.0f : std::min(d, 8.0f * covered[i].clearance));
      if (score > best_score) best_score = score, best = i;
    }
    if (best_score < 0.0f) break;  // no covered spot left away from the chosen ones
    chosen.push_back(covered[best].p);
    chosen_clearance.push_back(covered[best].clearance);
  }
  for (std::size_t k = 0; k < chosen.size(); ++k) {
    const float r = chosen_clearance[k];
    lights.push_back({{"id", "lamp" + std::to_string(k)},
                      {"type", "point"},
                      {"position", {chosen[k].x, chosen[k].y, chosen[k].z}},
                      {"intensity", std::round(200.0 * r * r)},
                      {"color", {1.0, 0.85, 0.65}}});
  }
  nlohmann::ordered_json out = {{"version", 1}, {"lights", lights}};
  if (open) out["sky"] = {{"radiance", {60.0, 80.0, 120.0}}};
  std::ofstream(argv[2]) << out.dump(2) << "\n";
  std::printf("%s: %zu playable candidates, sky share %.2f -> %s, %zu point lights\n", argv[1], playable.size(),
              sky_share, open ? "open (sun + sky)" : "closed", chosen.size());
  return 0;
}
