#include "core/relight/seam_stitch.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>
#include <unordered_map>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <tbb/parallel_for.h>

namespace lightlink::relight {

struct SeamStitch::Solver {
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
};

SeamStitch::SeamStitch() = default;
SeamStitch::SeamStitch(SeamStitch&&) noexcept = default;
SeamStitch& SeamStitch::operator=(SeamStitch&&) noexcept = default;
SeamStitch::~SeamStitch() = default;

namespace {

// Vertices of different indices at one position are one point of the surface (the unwrap
// splits seam vertices): edges are matched by their endpoints' positions.
using Key = std::tuple<float, float, float>;
Key key(const glm::vec3& p) { return {p.x, p.y, p.z}; }

struct Side {
  std::uint32_t tri;
  glm::vec2 uv_a, uv_b;  // uv1 at the edge's endpoints, in the edge's canonical order
};

}  // namespace

SeamStitch SeamStitch::build(const scene::Scene& scene, int width, int height) {
  SeamStitch s;
  if (width < 1 || height < 1) return s;
  const glm::vec2 size{float(width), float(height)};
  std::map<std::uint32_t, std::uint32_t> variable;  // texel -> variable, ordered for determinism
  struct Row {
    std::vector<std::pair<std::uint32_t, float>> taps;  // texel, weight
  };
  std::vector<Row> rows;
  auto taps = [&](glm::vec2 uv, float sign, Row& row) {
    const glm::vec2 f = uv * size - 0.5f;
    const float fx = std::clamp(f.x, -1.0f, float(width)), fy = std::clamp(f.y, -1.0f, float(height));
    const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
    const float ax = fx - float(x0), ay = fy - float(y0);
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) {
        const float w = (dx ? ax : 1 - ax) * (dy ? ay : 1 - ay);
        if (w <= 0.0f) continue;
        const int x = std::clamp(x0 + dx, 0, width - 1), y = std::clamp(y0 + dy, 0, height - 1);
        row.taps.emplace_back(std::uint32_t(y) * std::uint32_t(width) + std::uint32_t(x), sign * w);
      }
  };
  for (const auto& mesh : scene.meshes) {
    if (!mesh.is_static || !mesh.hasLightmapUv() || mesh.probe_lit) continue;
    std::map<std::pair<Key, Key>, std::vector<Side>> edges;
    const std::size_t nt = mesh.triangleCount();
    for (std::size_t t = 0; t < nt; ++t)
      for (int e = 0; e < 3; ++e) {
        const std::uint32_t i = mesh.indices[3 * t + e], j = mesh.indices[3 * t + (e + 1) % 3];
        Key a = key(mesh.positions[i]), b = key(mesh.positions[j]);
        glm::vec2 ua = mesh.uv1[i], ub = mesh.uv1[j];
        if (b < a) std::swap(a, b), std::swap(ua, ub);
        if (a == b) continue;
        edges[{a, b}].push_back({std::uint32_t(t), ua, ub});
      }
    auto normal = [&](std::uint32_t t) {
      const glm::vec3 p0 = mesh.positions[mesh.indices[3 * t]], p1 = mesh.positions[mesh.indices[3 * t + 1]],
                      p2 = mesh.positions[mesh.indices[3 * t + 2]];
      const glm::vec3 n = glm::cross(p1 - p0, p2 - p0);
      const float len = glm::length(n);
      return len > 0.0f ? n / len : glm::vec3(0.0f);
    };
    for (const auto& [ends, sides] : edges) {
      if (sides.size() != 2) continue;  // a border, or a non-manifold edge: nothing to match
      const Side& A = sides[0];
      const Side& B = sides[1];
      const float tol = 0.25f / std::max(size.x, size.y);  // a quarter texel
      if (glm::all(glm::lessThan(glm::abs(A.uv_a - B.uv_a), glm::vec2(tol))) &&
          glm::all(glm::lessThan(glm::abs(A.uv_b - B.uv_b), glm::vec2(tol))))
        continue;  // the same UVs on both sides: no seam
      if (glm::dot(normal(A.tri), normal(B.tri)) < kSmoothSeamCos) continue;  // a crease
      const float len_texels =
          std::max(glm::length((A.uv_b - A.uv_a) * size), glm::length((B.uv_b - B.uv_a) * size));
      const int samples = std::max(2, int(std::ceil(2.0f * len_texels)));
      for (int k = 0; k < samples; ++k) {
        const float t = (float(k) + 0.5f) / float(samples);
        Row row;
        taps(A.uv_a + t * (A.uv_b - A.uv_a), 1.0f, row);
        taps(B.uv_a + t * (B.uv_b - B.uv_a), -1.0f, row);
        rows.push_back(std::move(row));
      }
      ++s.edges_;
    }
  }
  if (rows.empty()) return s;
  for (const Row& r : rows)
    for (const auto& [texel, w] : r.taps) variable.emplace(texel, 0);
  std::uint32_t next = 0;
  for (auto& [texel, v] : variable) {
    v = next++;
    s.texel_.push_back(texel);
  }
  s.row_begin_.push_back(0);
  std::vector<Eigen::Triplet<double>> triplets;
  for (const Row& r : rows) {
    for (const auto& [texel, w] : r.taps) {
      s.col_.push_back(variable[texel]);
      s.weight_.push_back(w);
    }
    s.row_begin_.push_back(std::uint32_t(s.col_.size()));
    for (const auto& [ti, wi] : r.taps)
      for (const auto& [tj, wj] : r.taps)
        triplets.emplace_back(int(variable[ti]), int(variable[tj]), kSeamWeight * double(wi) * double(wj));
  }
  const int n = int(s.texel_.size());
  for (int i = 0; i < n; ++i) triplets.emplace_back(i, i, 1.0);
  Eigen::SparseMatrix<double> m(n, n);
  m.setFromTriplets(triplets.begin(), triplets.end());
  s.solver_ = std::make_unique<Solver>();
  s.solver_->ldlt.compute(m);
  if (s.solver_->ldlt.info() != Eigen::Success) {  // cannot happen for an SPD matrix; never stitch garbage
    s.texel_.clear();
    s.solver_.reset();
  }
  return s;
}

void SeamStitch::apply(float* data, std::size_t stride, SeamStats* stats, std::size_t measure) const {
  if (stats) *stats = {};
  if (empty()) return;
  const std::size_t n = texel_.size(), rows = row_begin_.size() - 1;
  auto jump = [&](const Eigen::VectorXd& x) {
    double diff = 0.0, level = 0.0;
    for (std::size_t r = 0; r < rows; ++r) {
      double d = 0.0, a = 0.0;
      for (std::uint32_t k = row_begin_[r]; k < row_begin_[r + 1]; ++k) {
        d += weight_[k] * x[col_[k]];
        a += std::abs(weight_[k]) * x[col_[k]];
      }
      diff += std::abs(d);
      level += std::abs(a) * 0.5;
    }
    return level > 0.0 ? diff / level : 0.0;
  };
  Eigen::MatrixXd rhs(n, stride);
  for (std::size_t v = 0; v < n; ++v)
    for (std::size_t c = 0; c < stride; ++c) rhs(Eigen::Index(v), Eigen::Index(c)) = data[texel_[v] * stride + c];
  if (stats) {
    stats->edges = edges_, stats->samples = rows, stats->texels = n;
    stats->jump_before = jump(rhs.col(Eigen::Index(measure)));
  }
  // Channels are independent solves against one factorisation: in parallel, each column
  // written by one task, so the result does not depend on the thread count.
  Eigen::MatrixXd x(n, stride);
  tbb::parallel_for(std::size_t(0), stride, [&](std::size_t c) {
    x.col(Eigen::Index(c)) = solver_->ldlt.solve(rhs.col(Eigen::Index(c)));
  });
  for (std::size_t v = 0; v < n; ++v)
    for (std::size_t c = 0; c < stride; ++c) data[texel_[v] * stride + c] = float(x(Eigen::Index(v), Eigen::Index(c)));
  if (stats) stats->jump_after = jump(x.col(Eigen::Index(measure)));
}

}  // namespace lightlink::relight
