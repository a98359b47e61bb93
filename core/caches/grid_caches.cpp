#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

#include "core/caches/caches.h"

namespace lightlink::caches {
namespace {
// 16M caches is ~0.8 GB of SH at 3 bands before links; beyond that a spacing is a typo.
constexpr std::size_t kMaxGridCaches = std::size_t(1) << 24;
}  // namespace

std::size_t GridCaches::validCount() const {
  return static_cast<std::size_t>(std::count(valid.begin(), valid.end(), std::uint8_t{1}));
}

Expected<GridCaches> placeGridCaches(const scene::Scene& scene, const rt::Accel& accel,
                                     const GridCacheOptions& options) {
  const Aabb volume = options.volume.empty() ? scene.bounds : options.volume;
  if (volume.empty()) return invalidInput("grid caches: the volume is empty");
  const glm::vec3 extent = volume.extent();
  if (!std::isfinite(extent.x) || !std::isfinite(extent.y) || !std::isfinite(extent.z))
    return invalidInput("grid caches: the volume is not finite");
  float spacing = options.spacing_m;
  if (!(spacing >= 0.0f) || !std::isfinite(spacing))
    return invalidInput("grid spacing {} m must be a finite number > 0 (or 0 to derive it)", spacing);
  if (spacing == 0.0f) {
    if (options.resolution < 2 || options.resolution > 1024)
      return invalidInput("grid resolution {} is out of range (2..1024)", options.resolution);
    const float longest = std::max(extent.x, std::max(extent.y, extent.z));
    if (longest <= 0.0f) return invalidInput("grid caches: the volume has zero size");
    spacing = longest / static_cast<float>(options.resolution - 1);
  }
  // The tolerance keeps an extent that is a whole number of spacings (1 m / 0.1 m) from
  // losing its last point to float rounding.
  glm::dvec3 counts = glm::floor(glm::dvec3(extent) / double(spacing) + 1e-4) + 1.0;
  const double total = counts.x * counts.y * counts.z;
  if (total > double(kMaxGridCaches))
    return invalidInput("grid spacing {} m gives {:.0f} x {:.0f} x {:.0f} = {:.0f} caches, more than the limit "
                        "of {}; use a larger spacing",
                        spacing, counts.x, counts.y, counts.z, total, kMaxGridCaches);
  GridCaches grid;
  grid.spacing_m = spacing;
  grid.dims = glm::ivec3(counts);
  // Centre the lattice in the volume so both ends get the same margin.
  grid.origin = volume.center() - 0.5f * spacing * glm::vec3(grid.dims - 1);
  const std::size_t n = static_cast<std::size_t>(total);
  grid.position.resize(n);
  grid.valid.assign(n, 1);
  for (int z = 0; z < grid.dims.z; ++z)
    for (int y = 0; y < grid.dims.y; ++y)
      for (int x = 0; x < grid.dims.x; ++x)
        grid.position[(std::size_t(z) * grid.dims.y + y) * grid.dims.x + x] =
            grid.origin + spacing * glm::vec3(x, y, z);
  tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
    if (stopRequested(options.validity.progress)) return;
    const float f = backfaceFraction(scene, accel, grid.position[i], glm::vec3(0.0f), options.validity);
    grid.valid[i] = f <= options.validity.max_backface_fraction ? 1 : 0;
  });
  if (stopRequested(options.validity.progress)) return cancelled("grid caches: cancelled");
  return grid;
}

}  // namespace lightlink::caches
