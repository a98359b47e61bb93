#include "core/charts/segment.h"

#include <cmath>
#include <functional>
#include <numbers>
#include <queue>

namespace lightlink::charts {
namespace {

struct Candidate {
  double cost;
  std::uint32_t face;
  // Min-heap by cost, ties to the lower face index so the growth order is reproducible.
  bool operator>(const Candidate& o) const { return cost != o.cost ? cost > o.cost : face > o.face; }
};

constexpr std::uint32_t kUnassigned = 0xffffffffu;

// Region growing stops at the cone limit face by face, which leaves ragged borders
// (one-face spikes and notches) on irregular meshes; those waste atlas space around every
// chart. A face with two of its three neighbours in another chart B moves to B if it is
// within B's cone and not across a hard edge from them. It then has at most one neighbour
// left in its old chart, so no chart is ever cut in two. A few passes, in face order;
// charts emptied this way are dropped and the rest renumbered in order of first face.
void smoothBorders(const PreparedMesh& mesh, const SegmentOptions& options, Segmentation& seg) {
  const double deg = std::numbers::pi / 180.0;
  const double cos_cone = std::cos(options.normal_cone_deg * deg);
  const double cos_hard = std::cos(options.hard_edge_deg * deg);
  const std::size_t faces = mesh.faceCount();
  std::vector<glm::dvec3> normal_sum(seg.chart_count, glm::dvec3(0.0));
  for (std::size_t f = 0; f < faces; ++f) normal_sum[seg.face_chart[f]] += mesh.face_normals[f] * mesh.face_areas[f];
  for (int pass = 0; pass < 3; ++pass) {
    bool changed = false;
    for (std::size_t f = 0; f < faces; ++f) {
      const std::uint32_t a = seg.face_chart[f];
      std::uint32_t other[3];
      for (int k = 0; k < 3; ++k) {
        const std::int32_t g = mesh.neighbors[3 * f + k];
        other[k] = g < 0 ? kUnassigned : seg.face_chart[static_cast<std::size_t>(g)];
      }
      std::uint32_t b = kUnassigned;
      for (int k = 0; k < 3 && b == kUnassigned; ++k)
        if (other[k] != kUnassigned && other[k] != a && (other[k] == other[(k + 1) % 3] || other[k] == other[(k + 2) % 3]))
          b = other[k];
      if (b == kUnassigned) continue;
      bool ok = glm::dot(mesh.face_normals[f], glm::normalize(normal_sum[b])) >= cos_cone;
      for (int k = 0; k < 3 && ok; ++k)
        if (other[k] == b)
          ok = glm::dot(mesh.face_normals[f], mesh.face_normals[static_cast<std::size_t>(mesh.neighbors[3 * f + k])]) >= cos_hard;
      if (!ok) continue;
      normal_sum[a] -= mesh.face_normals[f] * mesh.face_areas[f];
      normal_sum[b] += mesh.face_normals[f] * mesh.face_areas[f];
      seg.face_chart[f] = b;
      changed = true;
    }
    if (!changed) break;
  }
  std::vector<std::uint32_t> renumber(seg.chart_count, kUnassigned);
  std::uint32_t next = 0;
  for (std::size_t f = 0; f < faces; ++f) {
    std::uint32_t& r = renumber[seg.face_chart[f]];
    if (r == kUnassigned) r = next++;
    seg.face_chart[f] = r;
  }
  seg.chart_count = next;
}

}  // namespace

Segmentation segmentCharts(const PreparedMesh& mesh, const SegmentOptions& options) {
  const std::size_t faces = mesh.faceCount();
  const double deg = std::numbers::pi / 180.0;
  const double cos_cone = std::cos(options.normal_cone_deg * deg);
  const double cos_hard = std::cos(options.hard_edge_deg * deg);

  std::vector<glm::dvec3> centroids(faces);
  for (std::size_t f = 0; f < faces; ++f) {
    centroids[f] = (mesh.positions[mesh.corners[3 * f]] + mesh.positions[mesh.corners[3 * f + 1]] +
                    mesh.positions[mesh.corners[3 * f + 2]]) / 3.0;
  }

  Segmentation seg;
  seg.face_chart.assign(faces, kUnassigned);
  std::vector<Candidate> heap_storage;
  std::priority_queue<Candidate, std::vector<Candidate>, std::greater<>> heap(std::greater<>{},
                                                                              std::move(heap_storage));
  for (std::size_t seed = 0; seed < faces; ++seed) {
    if (seg.face_chart[seed] != kUnassigned) continue;
    const std::uint32_t chart = seg.chart_count++;
    glm::dvec3 normal_sum(0.0);
    double area = 0.0;
    const glm::dvec3 seed_c = centroids[seed];
    glm::dvec3 chart_n = mesh.face_normals[seed];

    auto cost = [&](std::uint32_t f) {
      const double planarity = 1.0 - glm::dot(mesh.face_normals[f], chart_n);
      const double radius = std::sqrt(area / std::numbers::pi);
      const double compact = radius > 0.0 ? glm::length(centroids[f] - seed_c) / radius : 0.0;
      return planarity + options.compactness_weight * compact;
    };
    auto add = [&](std::uint32_t f) {
      seg.face_chart[f] = chart;
      normal_sum += mesh.face_normals[f] * mesh.face_areas[f];
      area += mesh.face_areas[f];
      const double len = glm::length(normal_sum);
      if (len > 0.0) chart_n = normal_sum / len;
      for (int k = 0; k < 3; ++k) {
        const std::int32_t g = mesh.neighbors[3 * f + k];
        if (g < 0 || seg.face_chart[static_cast<std::size_t>(g)] != kUnassigned) continue;
        const auto gu = static_cast<std::uint32_t>(g);
        if (glm::dot(mesh.face_normals[f], mesh.face_normals[gu]) < cos_hard) continue;  // hard edge
        heap.push({cost(gu), gu});
      }
    };

    add(static_cast<std::uint32_t>(seed));
    while (!heap.empty()) {
      const Candidate c = heap.top();
      heap.pop();
      if (seg.face_chart[c.face] != kUnassigned) continue;
      // The cone is tested against the chart normal as it is now, not when f was queued.
      if (glm::dot(mesh.face_normals[c.face], chart_n) < cos_cone) continue;
      add(c.face);
    }
  }
  smoothBorders(mesh, options, seg);
  return seg;
}

}  // namespace lightlink::charts
