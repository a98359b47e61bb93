#include "core/charts/flatten.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include "core/charts/pack.h"

namespace lightlink::charts {
namespace {

bool contains(const std::vector<std::uint32_t>& sorted, std::uint32_t id) {
  return std::binary_search(sorted.begin(), sorted.end(), id);
}

std::uint32_t localIndex(const std::vector<std::uint32_t>& sorted, std::uint32_t id) {
  return static_cast<std::uint32_t>(std::lower_bound(sorted.begin(), sorted.end(), id) - sorted.begin());
}

// Splits a face set into edge-connected pieces (each sorted ascending), in order of their
// lowest face.
std::vector<std::vector<std::uint32_t>> components(const PreparedMesh& mesh,
                                                   const std::vector<std::uint32_t>& faces) {
  std::vector<std::vector<std::uint32_t>> out;
  std::vector<char> seen(faces.size(), 0);
  std::vector<std::uint32_t> stack;
  for (std::size_t i = 0; i < faces.size(); ++i) {
    if (seen[i]) continue;
    std::vector<std::uint32_t> piece;
    seen[i] = 1;
    stack.push_back(static_cast<std::uint32_t>(i));
    while (!stack.empty()) {
      const std::uint32_t li = stack.back();
      stack.pop_back();
      const std::uint32_t f = faces[li];
      piece.push_back(f);
      for (int k = 0; k < 3; ++k) {
        const std::int32_t g = mesh.neighbors[3 * f + k];
        if (g < 0 || !contains(faces, static_cast<std::uint32_t>(g))) continue;
        const std::uint32_t lg = localIndex(faces, static_cast<std::uint32_t>(g));
        if (!seen[lg]) {
          seen[lg] = 1;
          stack.push_back(lg);
        }
      }
    }
    std::sort(piece.begin(), piece.end());
    out.push_back(std::move(piece));
  }
  return out;
}

Chart buildChart(const PreparedMesh& mesh, std::vector<std::uint32_t> faces, std::uint32_t mesh_index) {
  Chart c;
  c.mesh = mesh_index;
  c.faces = std::move(faces);
  c.vertices.reserve(c.faces.size() * 3);
  for (std::uint32_t f : c.faces) {
    for (int k = 0; k < 3; ++k) c.vertices.push_back(mesh.corners[3 * f + k]);
    c.area_m2 += mesh.face_areas[f];
  }
  std::sort(c.vertices.begin(), c.vertices.end());
  c.vertices.erase(std::unique(c.vertices.begin(), c.vertices.end()), c.vertices.end());
  c.local_corners.resize(c.faces.size() * 3);
  for (std::size_t i = 0; i < c.faces.size(); ++i)
    for (int k = 0; k < 3; ++k)
      c.local_corners[3 * i + k] = localIndex(c.vertices, mesh.corners[3 * c.faces[i] + k]);
  c.uv.assign(c.vertices.size(), glm::dvec2(0.0));
  return c;
}

glm::dvec3 chartNormal(const PreparedMesh& mesh, const Chart& c) {
  glm::dvec3 n(0.0);
  for (std::uint32_t f : c.faces) n += mesh.face_normals[f] * mesh.face_areas[f];
  const double len = glm::length(n);
  return len > 0.0 ? n / len : glm::dvec3(0.0, 0.0, 1.0);
}

void projectPlanar(const PreparedMesh& mesh, Chart& c, const glm::dvec3& n) {
  // Tangent from the world axis least aligned with n: deterministic and never parallel.
  const glm::dvec3 a = std::abs(n.x) <= std::abs(n.y) && std::abs(n.x) <= std::abs(n.z) ? glm::dvec3(1, 0, 0)
                       : std::abs(n.y) <= std::abs(n.z)                                 ? glm::dvec3(0, 1, 0)
                                                                                         : glm::dvec3(0, 0, 1);
  const glm::dvec3 t = glm::normalize(glm::cross(a, n));
  const glm::dvec3 b = glm::cross(n, t);  // (t, b, n) right-handed: front faces stay counter-clockwise
  for (std::size_t i = 0; i < c.vertices.size(); ++i) {
    const glm::dvec3& p = mesh.positions[c.vertices[i]];
    c.uv[i] = {glm::dot(p, t), glm::dot(p, b)};
  }
}

// LSCM with the two given local vertices pinned at (0,0) and (d,0). Returns false if the
// system could not be factorised (disconnected or degenerate input).
bool solveLscm(const PreparedMesh& mesh, Chart& c, std::uint32_t pin_a, std::uint32_t pin_b) {
  const std::size_t n = c.vertices.size();
  const double d = glm::length(mesh.positions[c.vertices[pin_b]] - mesh.positions[c.vertices[pin_a]]);
  // Unknown numbering: u of vertex i -> 2*free(i), v -> 2*free(i)+1; pins are not unknowns.
  std::vector<std::int32_t> free_index(n, -1);
  std::int32_t next = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (i != pin_a && i != pin_b) free_index[i] = next++;
  const glm::dvec2 pinned[2] = {{0.0, 0.0}, {d, 0.0}};

  const std::size_t rows = 2 * c.faces.size();
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(rows * 6);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(rows));
  for (std::size_t fi = 0; fi < c.faces.size(); ++fi) {
    const std::uint32_t f = c.faces[fi];
    const glm::dvec3 p0 = mesh.positions[mesh.corners[3 * f]];
    const glm::dvec3 e1 = mesh.positions[mesh.corners[3 * f + 1]] - p0;
    const glm::dvec3 e2 = mesh.positions[mesh.corners[3 * f + 2]] - p0;
    // The triangle in its own plane, counter-clockwise: (0,0), (|e1|,0), (x2,y2).
    const double l1 = glm::length(e1);
    const double x2 = glm::dot(e2, e1) / l1;
    const double y2 = glm::length(glm::cross(e1, e2)) / l1;
    const glm::dvec2 q[3] = {{0.0, 0.0}, {l1, 0.0}, {x2, y2}};
    const double area = 0.5 * l1 * y2;
    const double w = 1.0 / (2.0 * std::sqrt(area));
    const auto rx = static_cast<Eigen::Index>(2 * fi), ry = rx + 1;
    for (int j = 0; j < 3; ++j) {
      const glm::dvec2 e = q[(j + 2) % 3] - q[(j + 1) % 3];  // edge opposite corner j
      // residual = sum_j (u_j e_j + v_j rot90(e_j)) / (2A), rot90(x, y) = (-y, x)
      const double cu_x = w * e.x, cv_x = -w * e.y, cu_y = w * e.y, cv_y = w * e.x;
      const std::uint32_t li = c.local_corners[3 * fi + j];
      if (free_index[li] >= 0) {
        const int col = 2 * free_index[li];
        triplets.emplace_back(rx, col, cu_x);
        triplets.emplace_back(rx, col + 1, cv_x);
        triplets.emplace_back(ry, col, cu_y);
        triplets.emplace_back(ry, col + 1, cv_y);
      } else {
        const glm::dvec2 uv = pinned[li == pin_a ? 0 : 1];
        rhs[rx] -= cu_x * uv.x + cv_x * uv.y;
        rhs[ry] -= cu_y * uv.x + cv_y * uv.y;
      }
    }
  }
  Eigen::SparseMatrix<double> a(static_cast<Eigen::Index>(rows), 2 * next);
  a.setFromTriplets(triplets.begin(), triplets.end());
  const Eigen::SparseMatrix<double> at = a.transpose();
  const Eigen::SparseMatrix<double> normal = at * a;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
  if (solver.info() != Eigen::Success) return false;
  const Eigen::VectorXd x = solver.solve(at * rhs);
  if (solver.info() != Eigen::Success || !x.allFinite()) return false;
  for (std::size_t i = 0; i < n; ++i) {
    if (free_index[i] >= 0) {
      c.uv[i] = {x[2 * free_index[i]], x[2 * free_index[i] + 1]};
    } else {
      c.uv[i] = pinned[i == pin_a ? 0 : 1];
    }
  }
  return true;
}

// Two border vertices far apart: the border vertex farthest from the first border vertex,
// then the one farthest from that. Returns false if the chart has no border (closed).
bool choosePins(const PreparedMesh& mesh, const Chart& c, std::uint32_t& pin_a, std::uint32_t& pin_b) {
  std::vector<std::uint32_t> border;
  for (std::size_t fi = 0; fi < c.faces.size(); ++fi) {
    for (int k = 0; k < 3; ++k) {
      const std::int32_t g = mesh.neighbors[3 * c.faces[fi] + k];
      if (g >= 0 && contains(c.faces, static_cast<std::uint32_t>(g))) continue;
      border.push_back(c.local_corners[3 * fi + k]);
      border.push_back(c.local_corners[3 * fi + (k + 1) % 3]);
    }
  }
  if (border.empty()) return false;
  std::sort(border.begin(), border.end());
  border.erase(std::unique(border.begin(), border.end()), border.end());
  auto farthest = [&](std::uint32_t from) {
    const glm::dvec3 p = mesh.positions[c.vertices[from]];
    std::uint32_t best = from;
    double best_d = -1.0;
    for (std::uint32_t v : border) {
      const glm::dvec3 d = mesh.positions[c.vertices[v]] - p;
      const double dd = glm::dot(d, d);
      if (dd > best_d) {
        best_d = dd;
        best = v;
      }
    }
    return best;
  };
  pin_a = farthest(border.front());
  pin_b = farthest(pin_a);
  return pin_a != pin_b;
}

double uvArea(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
  return 0.5 * ((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x));
}

// Scales the chart to its surface area and checks orientation and stretch.
bool normaliseAndCheck(const PreparedMesh& mesh, Chart& c, double max_area_stretch) {
  double uv_area = 0.0;
  for (std::size_t fi = 0; fi < c.faces.size(); ++fi)
    uv_area += uvArea(c.uv[c.local_corners[3 * fi]], c.uv[c.local_corners[3 * fi + 1]],
                      c.uv[c.local_corners[3 * fi + 2]]);
  if (!(uv_area > 0.0) || !std::isfinite(uv_area)) return false;
  const double s = std::sqrt(c.area_m2 / uv_area);
  for (glm::dvec2& q : c.uv) q *= s;
  for (std::size_t fi = 0; fi < c.faces.size(); ++fi) {
    const std::uint32_t f = c.faces[fi];
    const TriangleDistortion d = triangleDistortion(
        mesh.positions[mesh.corners[3 * f]], mesh.positions[mesh.corners[3 * f + 1]],
        mesh.positions[mesh.corners[3 * f + 2]], c.uv[c.local_corners[3 * fi]],
        c.uv[c.local_corners[3 * fi + 1]], c.uv[c.local_corners[3 * fi + 2]], 1.0);
    if (!(d.signed_area_ratio > 0.0) || d.area_stretch > max_area_stretch) return false;
  }
  return true;
}

// Cuts a face set in two across the principal axis of its face centroids, at the area
// median along that axis (ties by face id), so both halves are non-empty.
void splitInTwo(const PreparedMesh& mesh, const std::vector<std::uint32_t>& faces,
                std::vector<std::uint32_t>& lo, std::vector<std::uint32_t>& hi) {
  std::vector<glm::dvec3> centroids(faces.size());
  glm::dvec3 mean(0.0);
  double total = 0.0;
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const std::uint32_t f = faces[i];
    centroids[i] = (mesh.positions[mesh.corners[3 * f]] + mesh.positions[mesh.corners[3 * f + 1]] +
                    mesh.positions[mesh.corners[3 * f + 2]]) / 3.0;
    mean += centroids[i] * mesh.face_areas[f];
    total += mesh.face_areas[f];
  }
  mean /= total;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const glm::dvec3 d = centroids[i] - mean;
    const Eigen::Vector3d v(d.x, d.y, d.z);
    cov += mesh.face_areas[faces[i]] * v * v.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  const Eigen::Vector3d axis = eig.eigenvectors().col(2);  // largest eigenvalue last
  std::vector<std::pair<double, std::uint32_t>> order(faces.size());
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const glm::dvec3 d = centroids[i] - mean;
    order[i] = {d.x * axis.x() + d.y * axis.y() + d.z * axis.z(), faces[i]};
  }
  std::sort(order.begin(), order.end());
  std::size_t cut = 0;
  for (double acc = 0.0; cut + 1 < order.size() && acc < 0.5 * total; ++cut)
    acc += mesh.face_areas[order[cut].second];
  cut = std::clamp<std::size_t>(cut, 1, order.size() - 1);
  lo.clear();
  hi.clear();
  for (std::size_t i = 0; i < order.size(); ++i) (i < cut ? lo : hi).push_back(order[i].second);
  std::sort(lo.begin(), lo.end());
  std::sort(hi.begin(), hi.end());
}

// Separating-axis test on the six edge normals; `eps` turns touching (shared vertex,
// collinear borders) into "not overlapping".
bool trianglesOverlap(const glm::dvec2* a, const glm::dvec2* b, double eps) {
  const glm::dvec2* tris[2] = {a, b};
  for (int t = 0; t < 2; ++t) {
    for (int k = 0; k < 3; ++k) {
      const glm::dvec2 e = tris[t][(k + 1) % 3] - tris[t][k];
      const glm::dvec2 axis(-e.y, e.x);
      double amin = std::numeric_limits<double>::max(), amax = -amin, bmin = amin, bmax = -amin;
      for (int j = 0; j < 3; ++j) {
        const double pa = glm::dot(axis, a[j]), pb = glm::dot(axis, b[j]);
        amin = std::min(amin, pa);
        amax = std::max(amax, pa);
        bmin = std::min(bmin, pb);
        bmax = std::max(bmax, pb);
      }
      const double slack = eps * glm::length(axis);
      if (amax <= bmin + slack || bmax <= amin + slack) return false;
    }
  }
  return true;
}

}  // namespace

TriangleDistortion triangleDistortion(const glm::dvec3& p0, const glm::dvec3& p1, const glm::dvec3& p2,
                                      const glm::dvec2& q0, const glm::dvec2& q1, const glm::dvec2& q2,
                                      double chart_area_ratio) {
  const glm::dvec3 e1 = p1 - p0, e2 = p2 - p0;
  const double l1 = glm::length(e1);
  const double x2 = glm::dot(e2, e1) / l1;
  const double y2 = glm::length(glm::cross(e1, e2)) / l1;
  // J maps the triangle's own plane frame to uv: J [l1 x2; 0 y2] = [q1-q0  q2-q0].
  const glm::dvec2 d1 = q1 - q0, d2 = q2 - q0;
  const double a = d1.x / l1, c = d1.y / l1;
  const double b = (d2.x - a * x2) / y2, d = (d2.y - c * x2) / y2;
  const double det = a * d - b * c;
  // Closed-form singular values of a 2x2 matrix.
  const double e = 0.5 * (a + d), f = 0.5 * (a - d), g = 0.5 * (c + b), h = 0.5 * (c - b);
  const double qq = std::sqrt(e * e + h * h), rr = std::sqrt(f * f + g * g);
  const double s_max = qq + rr, s_min = std::abs(qq - rr);
  TriangleDistortion out;
  out.signed_area_ratio = det / chart_area_ratio;
  out.area_stretch = out.signed_area_ratio > 0.0
                         ? std::max(out.signed_area_ratio, 1.0 / out.signed_area_ratio)
                         : std::numeric_limits<double>::infinity();
  out.angle_distortion = s_min > 0.0 ? s_max / s_min : std::numeric_limits<double>::infinity();
  return out;
}

bool chartSelfOverlaps(const Chart& c) {
  const std::size_t nf = c.faces.size();
  if (nf < 2) return false;
  glm::dvec2 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
  double area = 0.0;
  for (std::size_t fi = 0; fi < nf; ++fi) {
    area += std::abs(uvArea(c.uv[c.local_corners[3 * fi]], c.uv[c.local_corners[3 * fi + 1]],
                            c.uv[c.local_corners[3 * fi + 2]]));
  }
  for (const glm::dvec2& q : c.uv) {
    lo = glm::min(lo, q);
    hi = glm::max(hi, q);
  }
  const glm::dvec2 ext = hi - lo;
  const double extent = std::max(ext.x, ext.y);
  if (!(extent > 0.0)) return true;
  // About two triangles per cell on average, at most 1024 cells per side.
  const double cell = std::max({std::sqrt(2.0 * area / static_cast<double>(nf)), extent / 1024.0, 1e-300});
  const int gx = std::max(1, static_cast<int>(ext.x / cell) + 1), gy = std::max(1, static_cast<int>(ext.y / cell) + 1);
  // Counting sort of (cell, triangle) pairs: flat arrays, no per-cell vectors.
  std::vector<std::uint32_t> start(static_cast<std::size_t>(gx) * gy + 1, 0);
  auto cellRange = [&](std::size_t fi, int& x0, int& y0, int& x1, int& y1) {
    glm::dvec2 a = c.uv[c.local_corners[3 * fi]], b = a;
    for (int k = 1; k < 3; ++k) {
      a = glm::min(a, c.uv[c.local_corners[3 * fi + k]]);
      b = glm::max(b, c.uv[c.local_corners[3 * fi + k]]);
    }
    x0 = std::clamp(static_cast<int>((a.x - lo.x) / cell), 0, gx - 1);
    y0 = std::clamp(static_cast<int>((a.y - lo.y) / cell), 0, gy - 1);
    x1 = std::clamp(static_cast<int>((b.x - lo.x) / cell), 0, gx - 1);
    y1 = std::clamp(static_cast<int>((b.y - lo.y) / cell), 0, gy - 1);
  };
  for (std::size_t fi = 0; fi < nf; ++fi) {
    int x0, y0, x1, y1;
    cellRange(fi, x0, y0, x1, y1);
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) ++start[static_cast<std::size_t>(y) * gx + x + 1];
  }
  for (std::size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
  std::vector<std::uint32_t> items(start.back());
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  for (std::size_t fi = 0; fi < nf; ++fi) {
    int x0, y0, x1, y1;
    cellRange(fi, x0, y0, x1, y1);
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) items[fill[static_cast<std::size_t>(y) * gx + x]++] = static_cast<std::uint32_t>(fi);
  }
  const double eps = 1e-9 * extent;
  for (std::size_t cell_id = 0; cell_id + 1 < start.size(); ++cell_id) {
    for (std::uint32_t i = start[cell_id]; i < start[cell_id + 1]; ++i) {
      for (std::uint32_t j = i + 1; j < start[cell_id + 1]; ++j) {
        const std::uint32_t fa = items[i], fb = items[j];
        int shared = 0;
        for (int ka = 0; ka < 3; ++ka)
          for (int kb = 0; kb < 3; ++kb)
            shared += c.local_corners[3 * fa + ka] == c.local_corners[3 * fb + kb];
        if (shared >= 2) continue;  // edge neighbours: only a flip makes them overlap
        const glm::dvec2 ta[3] = {c.uv[c.local_corners[3 * fa]], c.uv[c.local_corners[3 * fa + 1]],
                                  c.uv[c.local_corners[3 * fa + 2]]};
        const glm::dvec2 tb[3] = {c.uv[c.local_corners[3 * fb]], c.uv[c.local_corners[3 * fb + 1]],
                                  c.uv[c.local_corners[3 * fb + 2]]};
        if (trianglesOverlap(ta, tb, eps)) return true;
      }
    }
  }
  return false;
}

void flattenChart(const PreparedMesh& mesh, std::vector<std::uint32_t> faces, std::uint32_t mesh_index,
                  const FlattenOptions& options, std::vector<Chart>& out, FlattenStats& stats) {
  const double cos_planar = std::cos(options.planar_deg * std::numbers::pi / 180.0);
  std::sort(faces.begin(), faces.end());
  std::vector<std::vector<std::uint32_t>> work = components(mesh, faces);
  std::reverse(work.begin(), work.end());  // LIFO: pieces come out in face order
  std::vector<std::uint32_t> lo, hi;
  while (!work.empty()) {
    Chart c = buildChart(mesh, std::move(work.back()), mesh_index);
    work.pop_back();
    const glm::dvec3 n = chartNormal(mesh, c);
    double min_cos = 1.0;
    for (std::uint32_t f : c.faces) min_cos = std::min(min_cos, glm::dot(mesh.face_normals[f], n));
    bool ok;
    if (min_cos >= cos_planar || c.faces.size() == 1) {
      c.planar = true;
      projectPlanar(mesh, c, n);
      ok = true;
    } else {
      std::uint32_t pa = 0, pb = 0;
      ok = choosePins(mesh, c, pa, pb) && solveLscm(mesh, c, pa, pb);
    }
    ok = ok && normaliseAndCheck(mesh, c, options.max_area_stretch) && !chartSelfOverlaps(c);
    if (ok && c.faces.size() >= 8 && options.min_box_fill > 0.0) {
      // Long curved or ragged charts waste their bounding box in the atlas.
      alignToMinimalBox(c);
      glm::dvec2 ext(0.0);
      for (const glm::dvec2& q : c.uv) ext = glm::max(ext, q);
      ok = c.area_m2 >= options.min_box_fill * ext.x * ext.y;
    }
    if (ok) {
      ++(c.planar ? stats.planar : stats.lscm);
      out.push_back(std::move(c));
      continue;
    }
    ++stats.splits;
    splitInTwo(mesh, c.faces, lo, hi);
    auto pieces_hi = components(mesh, hi);
    auto pieces_lo = components(mesh, lo);
    for (auto it = pieces_hi.rbegin(); it != pieces_hi.rend(); ++it) work.push_back(std::move(*it));
    for (auto it = pieces_lo.rbegin(); it != pieces_lo.rend(); ++it) work.push_back(std::move(*it));
  }
}

}  // namespace lightlink::charts
