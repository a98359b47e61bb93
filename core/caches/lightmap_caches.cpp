#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <tbb/parallel_for.h>

#include "core/caches/caches.h"

namespace lightlink::caches {
namespace {

float cross2(glm::vec2 a, glm::vec2 b) { return a.x * b.y - a.y * b.x; }

// Separating-axis test of a triangle against the unit texel square at `lo`.
bool overlapsSquare(const glm::vec2 t[3], glm::vec2 lo) {
  const glm::vec2 hi = lo + glm::vec2(1.0f);
  const glm::vec2 mn = glm::min(t[0], glm::min(t[1], t[2]));
  const glm::vec2 mx = glm::max(t[0], glm::max(t[1], t[2]));
  if (mx.x <= lo.x || mn.x >= hi.x || mx.y <= lo.y || mn.y >= hi.y) return false;
  const glm::vec2 corners[4] = {lo, {hi.x, lo.y}, hi, {lo.x, hi.y}};
  for (int e = 0; e < 3; ++e) {
    const glm::vec2 a = t[e], b = t[(e + 1) % 3], c = t[(e + 2) % 3];
    const glm::vec2 axis(-(b.y - a.y), b.x - a.x);
    const float side = glm::dot(axis, c - a);
    bool all_outside = true;
    for (const auto& q : corners) {
      if (glm::dot(axis, q - a) * side > 0.0f) {
        all_outside = false;
        break;
      }
    }
    if (all_outside) return false;
  }
  return true;
}

// Closest point of triangle t to p, as barycentrics (Ericson, Real-Time Collision
// Detection 5.1.5, in 2D).
glm::vec3 closestBarycentric(const glm::vec2 t[3], glm::vec2 p) {
  const glm::vec2 ab = t[1] - t[0], ac = t[2] - t[0], ap = p - t[0];
  const float d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const glm::vec2 bp = p - t[1];
  const float d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const float v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const glm::vec2 cp = p - t[2];
  const float d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const float w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const float w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const float denom = 1.0f / (va + vb + vc);
  const float v = vb * denom, w = vc * denom;
  return {1 - v - w, v, w};
}

struct Candidate {
  std::uint32_t texel;
  float score;  // 0 = texel centre inside the triangle, else squared distance (texels)
  std::uint32_t mesh;
  std::uint32_t triangle;
  glm::vec3 bary;
};

void rasterizeTriangle(const glm::vec2 t[3], int w, int h, std::uint32_t mesh, std::uint32_t tri,
                       std::vector<Candidate>& out) {
  const glm::vec2 mn = glm::min(t[0], glm::min(t[1], t[2]));
  const glm::vec2 mx = glm::max(t[0], glm::max(t[1], t[2]));
  const int x0 = std::max(0, static_cast<int>(std::floor(mn.x)));
  const int y0 = std::max(0, static_cast<int>(std::floor(mn.y)));
  const int x1 = std::min(w - 1, static_cast<int>(std::ceil(mx.x)) - 1);
  const int y1 = std::min(h - 1, static_cast<int>(std::ceil(mx.y)) - 1);
  const float area = cross2(t[1] - t[0], t[2] - t[0]);  // signed: mirrored charts work too
  constexpr float kInside = -1e-6f;  // barycentric tolerance: centres on a shared edge count
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const glm::vec2 c(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f);
      const float w0 = cross2(t[1] - c, t[2] - c) / area;
      const float w1 = cross2(t[2] - c, t[0] - c) / area;
      const float w2 = 1.0f - w0 - w1;
      const auto texel = static_cast<std::uint32_t>(y * w + x);
      if (w0 >= kInside && w1 >= kInside && w2 >= kInside) {
        out.push_back({texel, 0.0f, mesh, tri, {w0, w1, w2}});
      } else if (overlapsSquare(t, glm::vec2(x, y))) {
        const glm::vec3 b = closestBarycentric(t, c);
        const glm::vec2 q = b.x * t[0] + b.y * t[1] + b.z * t[2];
        const float d2 = std::max(glm::dot(q - c, q - c), 1e-12f);
        out.push_back({texel, d2, mesh, tri, b});
      }
    }
  }
}


// Footprint search of a texel whose centre fails validity: a kFootprintSamples^2 stratified
// pattern over the texel square, against at most kMaxFootprintTriangles of its triangles.
constexpr int kFootprintSamples = 4;
constexpr int kMaxFootprintTriangles = 16;
// How far (texels) a footprint sample clamped onto a triangle's edge is moved inside it.
constexpr float kEdgeInset = 0.0625f;
// Share of the back faces a texel sees that must lie within a texel for it to count as
// covered by a sheet rather than inside geometry.
constexpr float kSheetShare = 0.75f;
// Back faces of double-sided surfaces nearer than this (texels) count against a cache: the
// ray started on that surface. Below the 1/16-texel edge inset, and below a 2 mm rug's gap
// at 5 cm texels, which is a surface seen from a real distance.
constexpr float kContactTexels = 1.0f / 32.0f;

struct FootprintPoint {
  float d2 = 0.0f;  // squared distance to the texel centre, texels
  std::uint32_t triangle = 0;
  glm::vec3 bary{0.0f};
  glm::vec2 uv{0.0f};  // atlas texels
};

glm::vec3 surfacePoint(const scene::MeshInstance& mesh, std::uint32_t tri, const glm::vec3& b) {
  const std::uint32_t* idx = &mesh.indices[3 * tri];
  return b.x * mesh.positions[idx[0]] + b.y * mesh.positions[idx[1]] + b.z * mesh.positions[idx[2]];
}

// The hemisphere axis is the geometric normal on the side the shading normal faces.
glm::vec3 hemisphereAxis(const scene::MeshInstance& mesh, std::uint32_t tri, const glm::vec3& b) {
  const std::uint32_t* idx = &mesh.indices[3 * tri];
  const glm::vec3 p0 = mesh.positions[idx[0]], p1 = mesh.positions[idx[1]], p2 = mesh.positions[idx[2]];
  glm::vec3 ng = glm::cross(p1 - p0, p2 - p0);
  const glm::vec3 ns = b.x * mesh.normals[idx[0]] + b.y * mesh.normals[idx[1]] + b.z * mesh.normals[idx[2]];
  if (glm::dot(ng, ng) == 0.0f) ng = ns;
  if (glm::dot(ng, ns) < 0.0f) ng = -ng;
  return glm::normalize(ng);
}

}  // namespace

std::size_t LightmapCaches::validCount() const {
  return static_cast<std::size_t>(std::count(valid.begin(), valid.end(), std::uint8_t{1}));
}

Expected<LightmapCaches> placeLightmapCaches(const scene::Scene& scene, const rt::Accel& accel,
                                             const LightmapCacheOptions& options) {
  const int res = options.resolution;
  if (res <= 0 || res > 16384)
    return invalidInput("lightmap resolution {} is out of range (1..16384)", res);
  if (options.pages < 1 || std::int64_t(options.pages) * res > 16384)
    return invalidInput("lightmap pages {} of {} rows are out of range (at most 16384 rows)", options.pages, res);
  const int rows = res * options.pages;
  if (options.validity.rays <= 0 || options.validity.rays > 65536)
    return invalidInput("validity rays {} is out of range (1..65536)", options.validity.rays);
  if (!(options.validity.max_backface_fraction >= 0.0f && options.validity.max_backface_fraction <= 1.0f))
    return invalidInput("max backface fraction {} must be in [0, 1]", options.validity.max_backface_fraction);

  // Rasterise every static, lightmapped mesh into candidates; meshes in parallel, each
  // into its own list, concatenated in mesh order so the result is thread-independent.
  std::vector<std::vector<Candidate>> per_mesh(scene.meshes.size());
  std::vector<std::size_t> degenerate(scene.meshes.size(), 0);
  tbb::parallel_for(std::size_t(0), scene.meshes.size(), [&](std::size_t m) {
    const auto& mesh = scene.meshes[m];
    if (!mesh.is_static || !mesh.hasLightmapUv()) return;
    for (std::size_t tri = 0; tri < mesh.triangleCount(); ++tri) {
      glm::vec2 t[3];
      for (int k = 0; k < 3; ++k) t[k] = mesh.uv1[mesh.indices[3 * tri + k]] * glm::vec2(res, rows);
      if (std::abs(cross2(t[1] - t[0], t[2] - t[0])) < 1e-10f) {
        ++degenerate[m];
        continue;
      }
      rasterizeTriangle(t, res, rows, static_cast<std::uint32_t>(m), static_cast<std::uint32_t>(tri),
                        per_mesh[m]);
    }
  });
  std::vector<Candidate> all;
  LightmapCaches out;
  for (std::size_t m = 0; m < per_mesh.size(); ++m) {
    all.insert(all.end(), per_mesh[m].begin(), per_mesh[m].end());
    out.degenerate_uv_triangles += degenerate[m];
  }
  // Per texel the best candidate wins: centre inside beats grazing, nearer grazing beats
  // farther, then lower (mesh, triangle) — a total order, so the choice is deterministic.
  std::sort(all.begin(), all.end(), [](const Candidate& a, const Candidate& b) {
    if (a.texel != b.texel) return a.texel < b.texel;
    if (a.score != b.score) return a.score < b.score;
    if (a.mesh != b.mesh) return a.mesh < b.mesh;
    return a.triangle < b.triangle;
  });

  out.width = res;
  out.height = rows;
  out.cache_of_texel.assign(static_cast<std::size_t>(res) * rows, -1);
  // Every cache keeps the range of its texel's candidates: the footprint search below needs
  // all triangles of its mesh that overlap the texel, not only the one that won.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> texel_range;
  const glm::vec2 atlas(res, rows);
  for (std::size_t i = 0; i < all.size(); ++i) {
    if (i > 0 && all[i].texel == all[i - 1].texel) {
      texel_range.back().second = static_cast<std::uint32_t>(i + 1);
      continue;
    }
    const Candidate& c = all[i];
    const auto& mesh = scene.meshes[c.mesh];
    out.cache_of_texel[c.texel] = static_cast<std::int32_t>(out.position.size());
    out.position.push_back(surfacePoint(mesh, c.triangle, c.bary));
    out.normal.push_back(hemisphereAxis(mesh, c.triangle, c.bary));
    out.texel.push_back(c.texel);
    out.mesh.push_back(c.mesh);
    out.triangle.push_back(c.triangle);
    texel_range.emplace_back(static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(i + 1));
  }

  const std::size_t n = out.position.size();
  out.valid.assign(n, 1);
  out.pushed.assign(n, 0);
  const float max_back = options.validity.max_backface_fraction;
  const Progress* progress = options.validity.progress;
  // World size of a texel on cache i's triangle.
  const auto texelMetres = [&](std::size_t i) {
    const auto& mesh = scene.meshes[out.mesh[i]];
    const std::uint32_t* idx = &mesh.indices[3 * out.triangle[i]];
    const glm::vec3 p0 = mesh.positions[idx[0]], p1 = mesh.positions[idx[1]], p2 = mesh.positions[idx[2]];
    glm::vec2 t[3];
    for (int k = 0; k < 3; ++k) t[k] = mesh.uv1[idx[k]] * atlas;
    const float texel_area = std::abs(cross2(t[1] - t[0], t[2] - t[0]));
    const float world_area = glm::length(glm::cross(p1 - p0, p2 - p0));
    return std::sqrt(world_area / std::max(texel_area, 1e-12f));
  };
  tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
    if (stopRequested(progress)) return;
    // A double-sided wall's back seen this close means the ray started on the wall: the
    // cache sits on a contact line (the inset footprint samples lie 1/16 texel inside).
    const float texel_m = texelMetres(i);
    const float contact_m = kContactTexels * texel_m;
    // A valid point whose every ray stops within a texel lies in a sealed pocket (a closed
    // void between a level's brushes): no light reaches it and no one sees it, while the rest
    // of its texel may be in the open. A texel with no open valid point is invalid (filled).
    const auto sealed = [&](const BackfaceProbe& probe) { return probe.reach <= texel_m; };
    const BackfaceProbe at_centre = probeBackfaces(scene, accel, out.position[i], out.normal[i], options.validity,
                                                0.0f, contact_m);
    const bool centre_valid = at_centre.fraction <= max_back;
    if (centre_valid && (!sealed(at_centre) || !options.footprint_search)) return;
    if (!options.footprint_search) {
      out.valid[i] = 0;
      return;
    }
    // The centre sees back faces (it lies on an edge, a contact line or under a card) or is
    // sealed in: look for the valid, open point of the texel's own footprint nearest its
    // centre, as Bakery and Unity's progressive lightmapper do per texel. The cache never
    // leaves its texel.
    const std::uint32_t m = out.mesh[i];
    const auto& mesh = scene.meshes[m];
    std::uint32_t tris[kMaxFootprintTriangles];
    int tri_count = 0;
    for (std::uint32_t k = texel_range[i].first; k < texel_range[i].second && tri_count < kMaxFootprintTriangles; ++k)
      if (all[k].mesh == m) tris[tri_count++] = all[k].triangle;
    std::sort(tris, tris + tri_count);
    const std::uint32_t texel = out.texel[i];
    const glm::vec2 lo(float(texel % std::uint32_t(res)), float(texel / std::uint32_t(res)));
    const glm::vec2 centre = lo + glm::vec2(0.5f);
    const auto uvTriangle = [&](std::uint32_t tri, glm::vec2 t[3]) {
      for (int k = 0; k < 3; ++k) t[k] = mesh.uv1[mesh.indices[3 * tri + k]] * atlas;
    };
    FootprintPoint pts[kFootprintSamples * kFootprintSamples];
    int count = 0;
    for (int sy = 0; sy < kFootprintSamples; ++sy) {
      for (int sx = 0; sx < kFootprintSamples; ++sx) {
        const glm::vec2 s = lo + (glm::vec2(sx, sy) + 0.5f) / float(kFootprintSamples);
        // The sample itself where a triangle covers it, else the nearest point of the
        // nearest triangle, if that still lies in the texel (a grazed texel).
        FootprintPoint best{};
        float best_d2 = std::numeric_limits<float>::infinity();
        for (int k = 0; k < tri_count; ++k) {
          glm::vec2 t[3];
          uvTriangle(tris[k], t);
          glm::vec3 b = closestBarycentric(t, s);
          glm::vec2 q = b.x * t[0] + b.y * t[1] + b.z * t[2];
          const float d2 = glm::dot(q - s, q - s);
          if (d2 > 0.0f) {
            // Clamped onto an edge, which at a contact is the contact line itself, where
            // half the rays start inside the other surface: step kEdgeInset into the triangle.
            const glm::vec2 mid = (t[0] + t[1] + t[2]) / 3.0f;
            const float to_mid = glm::length(mid - q);
            const float f = to_mid > 0.0f ? std::min(1.0f, kEdgeInset / to_mid) : 0.0f;
            b = glm::mix(b, glm::vec3(1.0f / 3.0f), f);
            q = b.x * t[0] + b.y * t[1] + b.z * t[2];
          }
          if (d2 < best_d2) best_d2 = d2, best = {glm::dot(q - centre, q - centre), tris[k], b, q};
        }
        constexpr float kSlack = 1e-4f;  // texels: a point on the square's border is in it
        if (!(best_d2 < std::numeric_limits<float>::infinity()) || best.uv.x < lo.x - kSlack ||
            best.uv.y < lo.y - kSlack || best.uv.x > lo.x + 1.0f + kSlack || best.uv.y > lo.y + 1.0f + kSlack)
          continue;
        bool seen = false;  // clamped samples often land on the same edge point
        for (int k = 0; k < count && !seen; ++k)
          seen = pts[k].triangle == best.triangle && glm::dot(pts[k].uv - best.uv, pts[k].uv - best.uv) < 1e-10f;
        if (!seen) pts[count++] = best;
      }
    }
    // Nearest the centre first; equal distances in sample order (stable sort): deterministic.
    std::stable_sort(pts, pts + count, [](const FootprintPoint& a, const FootprintPoint& b) { return a.d2 < b.d2; });
    bool sealed_only = centre_valid;  // every valid point seen so far is sealed
    for (int k = 0; k < count; ++k) {
      const glm::vec3 q = surfacePoint(mesh, pts[k].triangle, pts[k].bary);
      if (q == out.position[i]) continue;  // the centre, already tested
      const glm::vec3 nq = hemisphereAxis(mesh, pts[k].triangle, pts[k].bary);
      const BackfaceProbe probe = probeBackfaces(scene, accel, q, nq, options.validity, 0.0f, contact_m);
      if (probe.fraction > max_back) continue;
      if (sealed(probe)) {
        sealed_only = true;
        continue;
      }
      out.position[i] = q;
      out.normal[i] = nq;
      out.triangle[i] = pts[k].triangle;
      out.pushed[i] = 1;
      return;
    }
    if (sealed_only) {
      out.valid[i] = 0;
      out.pushed[i] = 2;
      return;
    }
    // No point of the footprint is valid. Back faces nearer than a texel, for most of what
    // failed, are a one-sided sheet lying on the texel (a card, a rug): the texel is a real
    // surface in the sheet's shadow and keeps its own value; otherwise it is inside geometry.
    const BackfaceProbe probe =
        probeBackfaces(scene, accel, out.position[i], out.normal[i], options.validity, texel_m, contact_m);
    const bool centre_inside = all[texel_range[i].first].score == 0.0f;  // not a grazed texel
    if (centre_inside && probe.near_fraction > max_back && probe.near_fraction >= kSheetShare * probe.fraction) return;
    out.valid[i] = 0;
  });
  if (stopRequested(progress)) return cancelled("lightmap caches: cancelled");
  return out;
}

}  // namespace lightlink::caches
