#include "core/surfels/surfels.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/common/check.h"
#include "core/common/sampling.h"
#include "core/scene/material_eval.h"
#include "core/surfels/surface.h"

namespace lightlink::surfels {
namespace {

// Relaxation moves a surfel into a neighbouring triangle only if the two normals are within
// ~8 degrees, so surfels never wrap around a crease onto another face of the object.
constexpr float kCosCoplanar = 0.990f;
// Neighbours count as "on the same surface" if their normals are within 60 degrees and they
// are less than half a kernel radius off the tangent plane (excludes the other side of a thin
// wall and surfaces stacked closely in parallel).
constexpr float kCosSameSurface = 0.5f;
constexpr float kMaxPlaneOffset = 0.5f;

float radicalInverse2(std::uint32_t i) {
  i = (i << 16) | (i >> 16);
  i = ((i & 0x00ff00ffU) << 8) | ((i & 0xff00ff00U) >> 8);
  i = ((i & 0x0f0f0f0fU) << 4) | ((i & 0xf0f0f0f0U) >> 4);
  i = ((i & 0x33333333U) << 2) | ((i & 0xccccccccU) >> 2);
  i = ((i & 0x55555555U) << 1) | ((i & 0xaaaaaaaaU) >> 1);
  return float(double(i) * 0x1p-32);
}

float radicalInverse3(std::uint32_t i) {
  double inv = 1.0 / 3.0, f = inv, r = 0.0;
  while (i > 0) {
    r += f * double(i % 3);
    i /= 3;
    f *= inv;
  }
  return float(std::min(r, 0.99999994));
}

// A uniform grid hashed into a table of 2^k buckets, rebuilt from scratch per use by a
// counting sort (serial fill in point order: deterministic). Collisions only add candidates;
// queries compare each candidate's true cell.
class GridHash {
 public:
  void build(const std::vector<glm::vec3>& points, float cell_m) {
    inv_cell_ = 1.0f / cell_m;
    origin_ = glm::vec3(std::numeric_limits<float>::max());
    for (const glm::vec3& p : points) origin_ = glm::min(origin_, p);
    std::uint32_t buckets = 1;
    while (buckets < 2 * points.size()) buckets <<= 1;
    mask_ = buckets - 1;
    cell_.resize(points.size());
    start_.assign(std::size_t(buckets) + 1, 0);
    for (std::size_t i = 0; i < points.size(); ++i) {
      cell_[i] = cellOf(points[i]);
      ++start_[bucket(cell_[i]) + 1];
    }
    for (std::size_t b = 0; b < buckets; ++b) start_[b + 1] += start_[b];
    items_.resize(points.size());
    std::vector<std::uint32_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < points.size(); ++i) items_[fill[bucket(cell_[i])]++] = std::uint32_t(i);
  }

  // Calls f(index) for every point in the 27 cells around p (each point once).
  template <typename F>
  void forNeighbours(const glm::vec3& p, F&& f) const {
    const glm::ivec3 c = cellOf(p);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const glm::ivec3 q = c + glm::ivec3(dx, dy, dz);
          const std::uint32_t b = bucket(q);
          for (std::uint32_t k = start_[b]; k < start_[b + 1]; ++k)
            if (cell_[items_[k]] == q) f(items_[k]);
        }
  }

 private:
  glm::ivec3 cellOf(const glm::vec3& p) const {
    const glm::vec3 g = glm::clamp((p - origin_) * inv_cell_, glm::vec3(-1e9f), glm::vec3(1e9f));
    return glm::ivec3(glm::floor(g));
  }
  std::uint32_t bucket(const glm::ivec3& c) const {
    return ((std::uint32_t(c.x) * 73856093U) ^ (std::uint32_t(c.y) * 19349663U) ^
            (std::uint32_t(c.z) * 83492791U)) & mask_;
  }

  float inv_cell_ = 1.0f;
  glm::vec3 origin_{0.0f};
  std::uint32_t mask_ = 0;
  std::vector<glm::ivec3> cell_;
  std::vector<std::uint32_t> start_, items_;
};

Status validate(const SurfelOptions& o) {
  if (o.count == 0) return invalidInput("surfel count must be > 0");
  if (o.count > (1u << 28)) return invalidInput("surfel count {} exceeds 2^28", o.count);
  if (o.relaxation_iterations < 0 || o.relaxation_iterations > 1000)
    return invalidInput("relaxation iterations {} not in [0, 1000]", o.relaxation_iterations);
  if (!std::isfinite(o.relaxation_step) || o.relaxation_step <= 0.0f || o.relaxation_step > 1.0f)
    return invalidInput("relaxation step {} not in (0, 1]", o.relaxation_step);
  return Status::ok();
}

// Jacobi relaxation: every surfel's push is computed from the previous positions, then all
// move, so the result does not depend on scheduling.
void relax(const StaticSurface& surface, std::vector<std::uint32_t>& tri, std::vector<glm::vec2>& uv,
           float spacing_m, const SurfelOptions& o) {
  const std::size_t n = tri.size();
  const float radius = spacing_m;  // repel only neighbours closer than the ideal spacing
  const float max_move = o.relaxation_step * spacing_m;
  std::vector<glm::vec3> pos(n), delta(n);
  GridHash grid;
  for (int it = 0; it < o.relaxation_iterations; ++it) {
    if (stopRequested(o.progress)) return;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const auto& r) {
      for (std::size_t j = r.begin(); j < r.end(); ++j) pos[j] = surface.pointAt(tri[j], uv[j]);
    });
    if (stopRequested(o.progress)) return;  // the grid build is serial: not started once cancelled
    grid.build(pos, radius);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const auto& r) {
      // A chunk's neighbour search is the slow part: a cancelled one leaves no move.
      if (stopRequested(o.progress)) {
        for (std::size_t j = r.begin(); j < r.end(); ++j) delta[j] = glm::vec3(0.0f);
        return;
      }
      for (std::size_t j = r.begin(); j < r.end(); ++j) {
        const glm::vec3 nj = surface.normal[tri[j]];
        glm::vec3 force(0.0f);
        grid.forNeighbours(pos[j], [&](std::uint32_t i) {
          if (i == j) return;
          const glm::vec3 nb = surface.normal[tri[i]];
          glm::vec3 diff = pos[j] - pos[i];
          if (glm::dot(nj, nb) < kCosSameSurface || std::abs(glm::dot(nj, diff)) > kMaxPlaneOffset * radius)
            return;
          diff -= nj * glm::dot(nj, diff);
          const float dist = glm::length(diff);
          if (dist >= radius) return;
          glm::vec3 dir;
          if (dist > 1e-6f * radius) {
            dir = diff / dist;
          } else {
            // Coincident surfels: split them along the triangle's first edge, by index order.
            dir = glm::normalize(surface.e1[tri[j]]) * (j < i ? 1.0f : -1.0f);
          }
          const float w = 1.0f - dist / radius;
          force += dir * (w * w);
        });
        glm::vec3 step = force * max_move;
        const float len = glm::length(step);
        if (len > max_move) step *= max_move / len;
        delta[j] = step;
      }
    });
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const auto& r) {
      for (std::size_t j = r.begin(); j < r.end(); ++j)
        moveOnSurface(surface, tri[j], uv[j], delta[j], kCosCoplanar);
    });
  }
}

}  // namespace

void Surfels::resize(std::size_t n) {
  position.resize(n);
  normal.resize(n);
  area.resize(n);
  albedo.resize(n);
  emission.resize(n);
  lightmap_uv.resize(n);
  mesh.resize(n);
  triangle.resize(n);
  barycentric.resize(n);
}

Expected<Surfels> placeSurfels(const scene::Scene& scene, const SurfelOptions& options) {
  if (Status s = validate(options); !s) return s;
  Expected<StaticSurface> built = buildStaticSurface(scene);
  if (!built) return built.status();
  const StaticSurface& surface = *built;

  Surfels out;
  const double total_m2 = surface.size() > 0 ? surface.totalArea() : 0.0;
  if (!(total_m2 > 0.0)) return out;  // nothing static to cover

  const std::uint32_t n = options.count;
  const double slice_m2 = total_m2 / n;

  // Surfel j sits on the triangle under the midpoint of its area slice; `local` numbers the
  // surfels of one triangle for its Halton points. Triangles thinner than a slice get no
  // surfel and their area is carried by the surfel whose slice covers them.
  std::vector<std::uint32_t> tri(n), local(n);
  {
    std::uint32_t t = 0, first = 0;
    const std::uint32_t last = std::uint32_t(surface.size() - 1);
    for (std::uint32_t j = 0; j < n; ++j) {
      const double x = (double(j) + 0.5) * slice_m2;
      std::uint32_t prev = t;
      while (t < last && surface.area_prefix[t + 1] <= x) ++t;
      // Rounding at the very end may leave x on trailing zero-area triangles: step back.
      while (t > 0 && surface.area_prefix[t + 1] <= surface.area_prefix[t]) --t;
      if (j == 0 || t != prev) first = j;
      tri[j] = t;
      local[j] = j - first;
    }
  }

  std::vector<glm::vec2> uv(n);
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, n), [&](const auto& r) {
    for (std::uint32_t j = r.begin(); j < r.end(); ++j) {
      // Random start per triangle (20 bits) keeps the sequence low-discrepancy within the
      // triangle while decorrelating neighbouring triangles; +1 skips the (0, 0) point.
      const std::uint32_t start = mixBits32(options.seed * 0x9e3779b9U ^ mixBits32(tri[j])) >> 12;
      const float a = radicalInverse2(start + local[j] + 1);
      const float b = radicalInverse3(start + local[j] + 1);
      // Area-preserving square -> triangle warp.
      const float sa = std::sqrt(a);
      uv[j] = glm::vec2(sa * (1.0f - b), sa * b);
    }
  });

  if (options.relaxation_iterations > 0 && n > 1) {
    // Ideal spacing of n points in a hexagonal packing of the area: slice = sqrt(3)/2 d^2.
    const float spacing_m = float(std::sqrt(2.0 * slice_m2 / std::sqrt(3.0)));
    relax(surface, tri, uv, spacing_m, options);
  }
  if (stopRequested(options.progress)) return cancelled("surfels: cancelled");

  out.resize(n);
  const float area_m2 = float(slice_m2);
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, n), [&](const auto& r) {
    if (stopRequested(options.progress)) return;
    for (std::uint32_t j = r.begin(); j < r.end(); ++j) {
      const std::uint32_t t = tri[j];
      const scene::MeshInstance& mesh = scene.meshes[surface.mesh[t]];
      const std::uint32_t mt = surface.triangle[t];
      const std::uint32_t* idx = &mesh.indices[3 * std::size_t(mt)];
      const glm::vec2 b = uv[j];
      const float w = 1.0f - b.x - b.y;
      glm::vec3 normal = surface.normal[t];
      if (mesh.normals.size() == mesh.positions.size()) {
        const glm::vec3 interp = w * mesh.normals[idx[0]] + b.x * mesh.normals[idx[1]] + b.y * mesh.normals[idx[2]];
        const float len = glm::length(interp);
        if (len > 1e-6f && std::isfinite(len)) normal = interp / len;
      }
      // A double-sided surface's surfels face their own side (the back copy's normal is
      // negated), whichever way its vertex normals point: the owner lookup tells the two
      // sides apart by this orientation (links/surfel_locator.h).
      if (scene.materialOf(mesh).double_sided) {
        const float side = glm::dot(normal, surface.normal[t]);
        if (side < 1e-3f) normal = side < -1e-3f ? -normal : surface.normal[t];
      }
      out.position[j] = surface.pointAt(t, b);
      out.normal[j] = normal;
      out.area[j] = area_m2;
      out.albedo[j] = scene::bounceAlbedoAt(scene, mesh, mt, b);
      out.emission[j] = scene::emissionAt(scene, mesh, mt, b);
      out.lightmap_uv[j] = mesh.hasLightmapUv() ? scene::texcoordAt(mesh, 1, mt, b) : glm::vec2(-1.0f);
      out.mesh[j] = surface.mesh[t];
      out.triangle[j] = mt;
      out.barycentric[j] = b;
    }
  });
  if (stopRequested(options.progress)) return cancelled("surfels: cancelled");
  // Alpha cut-outs: a surfel in a hole would stand for surface no ray can hit and reflect
  // light from it. Dropped, the others keep their slice, so the surfels' area is the opaque
  // area (holes make up their share of the uniformly placed points).
  bool any_cutout = false;
  for (const auto& mesh : scene.meshes)
    any_cutout |= mesh.is_static && mesh.material >= 0 &&
                  scene.materials[std::size_t(mesh.material)].hasCutout();
  if (any_cutout) {
    std::vector<std::uint8_t> keep(n, 1);
    tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, n), [&](const auto& r) {
      for (std::uint32_t j = r.begin(); j < r.end(); ++j)
        keep[j] = !scene::cutOutAt(scene, scene.meshes[out.mesh[j]], out.triangle[j], out.barycentric[j]);
    });
    std::size_t m = 0;  // compacted in place, in placement order
    for (std::uint32_t j = 0; j < n; ++j) {
      if (!keep[j]) continue;
      out.position[m] = out.position[j], out.normal[m] = out.normal[j], out.area[m] = out.area[j];
      out.albedo[m] = out.albedo[j], out.emission[m] = out.emission[j], out.lightmap_uv[m] = out.lightmap_uv[j];
      out.mesh[m] = out.mesh[j], out.triangle[m] = out.triangle[j], out.barycentric[m] = out.barycentric[j];
      ++m;
    }
    out.resize(m);
  }
  return out;
}

namespace {
template <typename T>
void permute(std::vector<T>& v, std::span<const std::uint32_t> new_to_old) {
  std::vector<T> tmp(v.size());
  for (std::size_t i = 0; i < new_to_old.size(); ++i) tmp[i] = v[new_to_old[i]];
  v.swap(tmp);
}
}  // namespace

void reorder(Surfels& s, std::span<const std::uint32_t> new_to_old) {
  LL_CHECK_EQ(new_to_old.size(), s.size());
  permute(s.position, new_to_old);
  permute(s.normal, new_to_old);
  permute(s.area, new_to_old);
  permute(s.albedo, new_to_old);
  permute(s.emission, new_to_old);
  permute(s.lightmap_uv, new_to_old);
  permute(s.mesh, new_to_old);
  permute(s.triangle, new_to_old);
  permute(s.barycentric, new_to_old);
}

}  // namespace lightlink::surfels
