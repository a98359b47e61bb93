#include "core/surfels/surface.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <tuple>

namespace lightlink::surfels {
namespace {

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Barycentric (u, v) of the in-plane part of the world offset `d` from corner 0.
// Returns false for a degenerate triangle (Gram determinant ~ 0).
bool solveUv(const glm::vec3& e1, const glm::vec3& e2, const glm::vec3& d, glm::vec2& uv) {
  const float a = glm::dot(e1, e1), b = glm::dot(e1, e2), c = glm::dot(e2, e2);
  const float det = a * c - b * b;
  if (!(det > 1e-12f * a * c)) return false;  // sin^2 of the corner angle < 1e-12
  const float r1 = glm::dot(e1, d), r2 = glm::dot(e2, d);
  uv = glm::vec2(c * r1 - b * r2, a * r2 - b * r1) / det;
  return true;
}

glm::vec2 clampUv(glm::vec2 uv) {
  uv = glm::max(uv, glm::vec2(0.0f));
  const float s = uv.x + uv.y;
  return s > 1.0f ? uv / s : uv;
}

}  // namespace

Expected<StaticSurface> buildStaticSurface(const scene::Scene& scene) {
  StaticSurface s;
  std::size_t count = 0;
  for (const scene::MeshInstance& m : scene.meshes)
    if (m.is_static) count += m.triangleCount();
  s.mesh.reserve(count);
  s.triangle.reserve(count);
  s.p0.reserve(count);
  s.e1.reserve(count);
  s.e2.reserve(count);
  s.normal.reserve(count);
  s.area_prefix.reserve(count + 1);
  s.area_prefix.push_back(0.0);
  s.neighbour.assign(count * 3, -1);

  // (corner weld id a, weld id b, surface triangle, corner k opposite the edge)
  struct EdgeRecord {
    std::uint32_t a, b, tri, k;
  };
  std::vector<EdgeRecord> edges;
  std::vector<std::uint32_t> order, weld;

  for (std::size_t mi = 0; mi < scene.meshes.size(); ++mi) {
    const scene::MeshInstance& m = scene.meshes[mi];
    if (!m.is_static) continue;
    const std::size_t nv = m.positions.size();
    for (std::size_t v = 0; v < nv; ++v) {
      if (!finite(m.positions[v]))
        return invalidInput("mesh '{}': vertex {} has a non-finite position", m.name, v);
    }
    if (m.indices.size() % 3 != 0)
      return invalidInput("mesh '{}': index count {} is not a multiple of 3", m.name, m.indices.size());

    // Weld vertices with bit-identical positions so split seams still share edges.
    order.resize(nv);
    for (std::size_t v = 0; v < nv; ++v) order[v] = std::uint32_t(v);
    auto key = [&](std::uint32_t v) {
      const glm::vec3& p = m.positions[v];
      return std::make_tuple(p.x, p.y, p.z);
    };
    std::sort(order.begin(), order.end(), [&](std::uint32_t x, std::uint32_t y) {
      return std::make_tuple(key(x), x) < std::make_tuple(key(y), y);
    });
    weld.resize(nv);
    for (std::size_t r = 0; r < nv; ++r)
      weld[order[r]] = (r > 0 && key(order[r]) == key(order[r - 1])) ? weld[order[r - 1]] : std::uint32_t(r);

    edges.clear();
    for (std::size_t t = 0; t < m.triangleCount(); ++t) {
      const std::uint32_t* idx = &m.indices[3 * t];
      for (int k = 0; k < 3; ++k) {
        if (idx[k] >= nv)
          return invalidInput("mesh '{}': triangle {} uses vertex {} of {}", m.name, t, idx[k], nv);
      }
      const glm::vec3 p0 = m.positions[idx[0]], p1 = m.positions[idx[1]], p2 = m.positions[idx[2]];
      // Area in double so that large world coordinates do not cancel.
      const glm::dvec3 cross = glm::cross(glm::dvec3(p1) - glm::dvec3(p0), glm::dvec3(p2) - glm::dvec3(p0));
      const double len = glm::length(cross);
      const std::uint32_t g = std::uint32_t(s.size());
      s.mesh.push_back(std::uint32_t(mi));
      s.triangle.push_back(std::uint32_t(t));
      s.p0.push_back(p0);
      s.e1.push_back(p1 - p0);
      s.e2.push_back(p2 - p0);
      s.normal.push_back(len > 0.0 ? glm::vec3(cross / len) : glm::vec3(0.0f));
      s.back.push_back(0);
      s.area_prefix.push_back(s.area_prefix.back() + 0.5 * len);
      if (len <= 0.0) continue;  // degenerate: nobody walks into it
      for (std::uint32_t k = 0; k < 3; ++k) {
        std::uint32_t a = weld[idx[(k + 1) % 3]], b = weld[idx[(k + 2) % 3]];
        if (a == b) continue;
        if (a > b) std::swap(a, b);
        edges.push_back({a, b, g, k});
      }
    }
    // Edges shared by exactly two triangles are links; sorting makes the result independent
    // of anything but the input order.
    std::sort(edges.begin(), edges.end(), [](const EdgeRecord& x, const EdgeRecord& y) {
      return std::tie(x.a, x.b, x.tri, x.k) < std::tie(y.a, y.b, y.tri, y.k);
    });
    for (std::size_t i = 0; i < edges.size();) {
      std::size_t j = i;
      while (j < edges.size() && edges[j].a == edges[i].a && edges[j].b == edges[i].b) ++j;
      if (j - i == 2 && edges[i].tri != edges[i + 1].tri) {
        s.neighbour[3 * std::size_t(edges[i].tri) + edges[i].k] = std::int32_t(edges[i + 1].tri);
        s.neighbour[3 * std::size_t(edges[i + 1].tri) + edges[i + 1].k] = std::int32_t(edges[i].tri);
      }
      i = j;
    }
  }
  // The back copies of double-sided triangles, in front order.
  const std::size_t fronts = s.size();
  std::vector<std::int32_t> back_of(fronts, -1);
  for (std::size_t t = 0; t < fronts; ++t) {
    if (!scene.materialOf(scene.meshes[s.mesh[t]]).double_sided) continue;
    back_of[t] = std::int32_t(s.size());
    s.mesh.push_back(s.mesh[t]);
    s.triangle.push_back(s.triangle[t]);
    s.p0.push_back(s.p0[t]);
    s.e1.push_back(s.e1[t]);
    s.e2.push_back(s.e2[t]);
    s.normal.push_back(-s.normal[t]);
    s.back.push_back(1);
    s.area_prefix.push_back(s.area_prefix.back() + (s.area_prefix[t + 1] - s.area_prefix[t]));
  }
  s.neighbour.resize(3 * s.size(), -1);
  for (std::size_t t = 0; t < fronts; ++t) {
    if (back_of[t] < 0) continue;
    for (std::size_t k = 0; k < 3; ++k) {
      const std::int32_t nb = s.neighbour[3 * t + k];  // same mesh, so double-sided too
      s.neighbour[3 * std::size_t(back_of[t]) + k] = nb >= 0 ? back_of[std::size_t(nb)] : -1;
    }
  }
  if (!std::isfinite(s.totalArea())) return invalidInput("static geometry area is not finite");
  return s;
}

glm::vec2 clampedBarycentric(const StaticSurface& surface, std::uint32_t t, const glm::vec3& p) {
  glm::vec2 uv(1.0f / 3.0f);
  if (!solveUv(surface.e1[t], surface.e2[t], p - surface.p0[t], uv)) return glm::vec2(1.0f / 3.0f);
  return clampUv(uv);
}

void moveOnSurface(const StaticSurface& surface, std::uint32_t& t, glm::vec2& uv, glm::vec3 delta_m,
                   float cos_coplanar, int max_crossings) {
  for (int crossing = 0; crossing <= max_crossings; ++crossing) {
    const glm::vec3 n = surface.normal[t];
    const glm::vec3 d = delta_m - n * glm::dot(n, delta_m);  // tangential part only
    glm::vec2 duv;
    if (!solveUv(surface.e1[t], surface.e2[t], d, duv)) return;
    // Coordinates (w, u, v) with w = 1 - u - v move linearly along the path; the first one to
    // hit zero names the edge (opposite that corner) where the path leaves the triangle.
    const std::array<float, 3> c = {1.0f - uv.x - uv.y, uv.x, uv.y};
    const std::array<float, 3> dc = {-duv.x - duv.y, duv.x, duv.y};
    float s_exit = 1.0f;
    int exit_k = -1;
    for (int k = 0; k < 3; ++k) {
      if (dc[k] < 0.0f && c[k] + dc[k] < 0.0f) {
        const float s = std::max(c[k], 0.0f) / -dc[k];
        if (s < s_exit) {
          s_exit = s;
          exit_k = k;
        }
      }
    }
    uv = clampUv(uv + s_exit * duv);
    if (exit_k < 0) return;
    // Snap exactly onto the exit edge.
    if (exit_k == 1) uv.x = 0.0f;
    if (exit_k == 2) uv.y = 0.0f;
    if (exit_k == 0 && uv.x + uv.y > 0.0f) uv /= (uv.x + uv.y);
    const std::int32_t nb = surface.neighbour[3 * std::size_t(t) + std::size_t(exit_k)];
    if (nb < 0 || crossing == max_crossings ||
        glm::dot(surface.normal[std::size_t(nb)], n) < cos_coplanar)
      return;  // a crease, an open border or too many crossings: stop on the edge
    const glm::vec3 p = surface.pointAt(t, uv);
    t = std::uint32_t(nb);
    uv = clampedBarycentric(surface, t, p);
    delta_m = (1.0f - s_exit) * d;
  }
}

}  // namespace lightlink::surfels
