// HAC with the seed-000 distance: Müllner's generic algorithm (Müllner 2011, "Modern
// hierarchical, agglomerative clustering algorithms") with the O(n) nearest-neighbour
// scans replaced by searches in a uniform grid of cluster centroids.
//
// Every live cluster keeps a nearest-neighbour candidate and its distance; a min-heap holds
// (distance, cluster, stamp) entries, outdated ones are skipped lazily. Popping a cluster
// whose candidate died triggers a new search; popping one whose candidate lives merges the
// two. A new cluster's search also offers it as the new candidate to every cluster it
// examined (Müllner's update step), which is what makes a non-reducible distance work.
#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/common/aabb.h"
#include "core/common/check.h"
#include "core/hierarchy/builders.h"

namespace lightlink::hierarchy::detail {
namespace {

// Cells at most this many times the live cluster count: bounds the cost of a grid rebuild
// and of a search that has to scan empty space.
constexpr std::size_t kMaxCellsPerCluster = 8;

// What a distance evaluation reads, packed in one 32-byte record so that a candidate costs
// one cache line (with separate arrays the 32k-surfel build took ~25% longer).
struct ClusterHot {
  glm::vec3 pos;     // area-weighted centroid, world
  float area;        // m^2 (the exact sum lives in double beside it)
  glm::vec3 normal;  // normalised area-weighted mean normal, 0 if it cancels
  std::int32_t next; // next cluster in the same grid cell, -1 at the end
};
static_assert(sizeof(ClusterHot) == 32);

// Uniform grid over the surfel bounds with an intrusive doubly linked list per cell (the
// forward link inside ClusterHot), so insertion and removal are O(1) and allocation-free.
class ClusterGrid {
 public:
  explicit ClusterGrid(std::vector<ClusterHot>& hot)
      : hot_(hot), prev_(hot.size(), -1), cell_of_(hot.size(), 0) {}

  // Cell edge ~ the spacing of `live` clusters spread over `area_m2` of surface.
  void reset(const Aabb& box, double area_m2, std::size_t live) {
    origin_ = box.min;
    const glm::dvec3 ext = glm::max(glm::dvec3(box.extent()), glm::dvec3(1e-30));
    double cell = std::sqrt(std::max(area_m2, 0.0) / double(std::max<std::size_t>(live, 1)));
    if (!(cell > 0.0)) cell = std::max({ext.x, ext.y, ext.z}) / std::cbrt(double(std::max<std::size_t>(live, 1)));
    cell = std::max(cell, std::max({ext.x, ext.y, ext.z}) * 1e-6);
    const double max_cells = double(kMaxCellsPerCluster * live + 64);
    for (;;) {
      dims_ = glm::ivec3(glm::max(glm::dvec3(1.0), glm::ceil(ext / cell)));
      if (double(dims_.x) * dims_.y * dims_.z <= max_cells) break;
      cell *= 1.25;
    }
    cell_m_ = float(cell);
    inv_cell_ = float(1.0 / cell);
    head_.assign(std::size_t(dims_.x) * std::size_t(dims_.y) * std::size_t(dims_.z), -1);
  }

  float cellSize() const { return cell_m_; }

  void insert(std::int32_t node, const glm::vec3& p) {
    const std::uint32_t c = flat(cellOf(p));
    cell_of_[std::size_t(node)] = c;
    prev_[std::size_t(node)] = -1;
    hot_[std::size_t(node)].next = head_[c];
    if (head_[c] >= 0) prev_[std::size_t(head_[c])] = node;
    head_[c] = node;
  }

  void remove(std::int32_t node) {
    const std::int32_t p = prev_[std::size_t(node)], n = hot_[std::size_t(node)].next;
    if (p >= 0) hot_[std::size_t(p)].next = n;
    else head_[cell_of_[std::size_t(node)]] = n;
    if (n >= 0) prev_[std::size_t(n)] = p;
  }

  glm::ivec3 cellOf(const glm::vec3& p) const {
    const glm::ivec3 c(glm::floor((p - origin_) * inv_cell_));
    return glm::clamp(c, glm::ivec3(0), dims_ - 1);
  }

  // Calls f(node) for every cluster in the cells at Chebyshev distance exactly r from c.
  // Returns false once the ring lies entirely outside the grid (everything was scanned).
  template <typename F>
  bool forRing(const glm::ivec3& c, int r, F&& f) const {
    const glm::ivec3 lo = glm::max(c - r, glm::ivec3(0)), hi = glm::min(c + r, dims_ - 1);
    if (lo.x == c.x - r || lo.y == c.y - r || lo.z == c.z - r || hi.x == c.x + r || hi.y == c.y + r ||
        hi.z == c.z + r) {
      for (int z = lo.z; z <= hi.z; ++z) {
        const bool zface = std::abs(z - c.z) == r;
        for (int y = lo.y; y <= hi.y; ++y) {
          if (zface || std::abs(y - c.y) == r) {
            for (int x = lo.x; x <= hi.x; ++x) visit(glm::ivec3(x, y, z), f);
          } else {
            if (c.x - r >= 0) visit(glm::ivec3(c.x - r, y, z), f);
            if (r > 0 && c.x + r < dims_.x) visit(glm::ivec3(c.x + r, y, z), f);
          }
        }
      }
      return true;
    }
    return false;
  }

 private:
  std::uint32_t flat(const glm::ivec3& c) const {
    return std::uint32_t((std::size_t(c.z) * std::size_t(dims_.y) + std::size_t(c.y)) * std::size_t(dims_.x) +
                         std::size_t(c.x));
  }
  template <typename F>
  void visit(const glm::ivec3& cell, F& f) const {
    for (std::int32_t k = head_[flat(cell)]; k >= 0; k = hot_[std::size_t(k)].next) f(k);
  }

  glm::vec3 origin_{0.0f};
  glm::ivec3 dims_{1};
  float cell_m_ = 1.0f, inv_cell_ = 1.0f;
  std::vector<ClusterHot>& hot_;
  std::vector<std::int32_t> head_, prev_;
  std::vector<std::uint32_t> cell_of_;
};

struct HeapEntry {
  float distance;
  std::int32_t node;
  std::uint32_t stamp;
  // std::priority_queue is a max-heap: "greater" first means smallest distance on top,
  // ties broken by node id so the merge order is fully determined.
  bool operator<(const HeapEntry& o) const {
    return distance > o.distance || (distance == o.distance && node > o.node);
  }
};

class Agglomerator {
 public:
  Agglomerator(const surfels::Surfels& s, const TreeOptions& o)
      : n_(s.size()), count_(2 * n_ - 1), options_(o), hot_(count_, ClusterHot{glm::vec3(0.0f), 0.0f, glm::vec3(0.0f), -1}),
        grid_(hot_) {
    area_.resize(count_);
    normal_sum_.resize(count_);
    alive_.assign(count_, 0);
    nn_.assign(count_, -1);
    nn_dist_.assign(count_, std::numeric_limits<float>::infinity());
    stamp_.assign(count_, 0);
    for (std::size_t i = 0; i < n_; ++i) {
      hot_[i].pos = s.position[i];
      hot_[i].area = s.area[i];
      area_[i] = s.area[i];
      normal_sum_[i] = glm::dvec3(s.normal[i]) * double(s.area[i]);
      hot_[i].normal = glm::length(s.normal[i]) > 0.0f ? glm::normalize(s.normal[i]) : glm::vec3(0.0f);
      alive_[i] = 1;
      box_.grow(s.position[i]);
      total_area_ += s.area[i];
    }
    const float diag = box_.diagonal();
    inv_extent2_ = diag > 0.0f ? 1.0f / (diag * diag) : 1.0f;
  }

  MergeTree run() {
    MergeTree mt;
    mt.left.assign(count_, -1);
    mt.right.assign(count_, -1);
    if (n_ == 1) {
      mt.root = 0;
      return mt;
    }
    std::size_t live = n_;
    rebuildGrid(live);
    // Initial neighbours in parallel: each search only reads, each writes its own slot.
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n_), [&](const auto& r) {
      if (stopRequested(options_.progress)) return;
      for (std::size_t i = r.begin(); i < r.end(); ++i) {
        const Hit h = nearest(std::int32_t(i), false);
        nn_[i] = h.node;
        nn_dist_[i] = h.distance;
      }
    });
    if (stopRequested(options_.progress)) return mt;  // partial: buildTree checks the flag
    for (std::size_t i = 0; i < n_; ++i) heap_.push({nn_dist_[i], std::int32_t(i), 0});

    std::int32_t next = std::int32_t(n_);
    std::size_t rebuild_at = live / 2;
    std::size_t steps = 0;
    while (live > 1) {
      if (++steps % 4096 == 0 && stopRequested(options_.progress)) return mt;
      LL_CHECK(!heap_.empty());
      const HeapEntry e = heap_.top();
      heap_.pop();
      const std::size_t a = std::size_t(e.node);
      if (!alive_[a] || e.stamp != stamp_[a]) continue;  // outdated entry
      const std::int32_t b = nn_[a];
      if (b < 0 || !alive_[std::size_t(b)]) {
        const Hit h = nearest(e.node, false);
        setNeighbour(a, h.node, h.distance);
        continue;
      }
      const std::int32_t c = next++;
      mt.left[std::size_t(c)] = e.node;
      mt.right[std::size_t(c)] = b;
      merge(a, std::size_t(b), std::size_t(c));
      --live;
      if (live <= rebuild_at && live > 1) {
        rebuildGrid(live);
        rebuild_at = live / 2;
      }
      if (live > 1) {
        const Hit h = nearest(c, true);
        setNeighbour(std::size_t(c), h.node, h.distance);
      }
      mt.root = c;
    }
    return mt;
  }

 private:
  struct Hit {
    float distance = std::numeric_limits<float>::infinity();
    std::int32_t node = -1;
  };

  float distance(std::size_t a, std::size_t b) const {
    const ClusterHot& x = hot_[a];
    const ClusterHot& y = hot_[b];
    const glm::vec3 d = x.pos - y.pos;
    const float amax = std::max(x.area, y.area);
    const float balance = amax > 0.0f ? std::abs(x.area - y.area) / amax : 0.0f;
    return glm::dot(d, d) * inv_extent2_ + options_.normal_weight * (1.0f - glm::dot(x.normal, y.normal)) +
           options_.balance_weight * balance;
  }

  void setNeighbour(std::size_t a, std::int32_t b, float d) {
    nn_[a] = b;
    nn_dist_[a] = d;
    heap_.push({d, std::int32_t(a), ++stamp_[a]});
  }

  // Nearest live cluster to `a` under d. Exact when the spatial term alone rules out every
  // cluster not yet scanned; otherwise stops after at least `candidates` clusters. With
  // `offer`, every scanned cluster that is closer to `a` than to its current candidate takes
  // `a` as its new candidate.
  Hit nearest(std::int32_t a, bool offer) {
    Hit best;
    int examined = 0;
    const glm::ivec3 cell = grid_.cellOf(hot_[std::size_t(a)].pos);
    const float cell_m = grid_.cellSize();
    for (int r = 0;; ++r) {
      const bool any = grid_.forRing(cell, r, [&](std::int32_t b) {
        if (b == a) return;
        const float d = distance(std::size_t(a), std::size_t(b));
        ++examined;
        if (d < best.distance || (d == best.distance && b < best.node)) best = {d, b};
        if (offer && (d < nn_dist_[std::size_t(b)] || (d == nn_dist_[std::size_t(b)] && a < nn_[std::size_t(b)])))
          setNeighbour(std::size_t(b), a, d);
      });
      if (!any) break;  // the whole grid has been scanned
      if (best.node >= 0) {
        // Unscanned clusters are at least r cells away along some axis.
        const float reach = float(r) * cell_m;
        if (best.distance <= reach * reach * inv_extent2_ || examined >= options_.candidates) break;
      }
    }
    return best;
  }

  void merge(std::size_t a, std::size_t b, std::size_t c) {
    grid_.remove(std::int32_t(a));
    grid_.remove(std::int32_t(b));
    alive_[a] = alive_[b] = 0;
    area_[c] = area_[a] + area_[b];
    const glm::dvec3 pa(hot_[a].pos), pb(hot_[b].pos);
    hot_[c].pos = area_[c] > 0.0 ? glm::vec3((pa * area_[a] + pb * area_[b]) / area_[c]) : glm::vec3(0.5 * (pa + pb));
    hot_[c].area = float(area_[c]);
    normal_sum_[c] = normal_sum_[a] + normal_sum_[b];
    const double len = glm::length(normal_sum_[c]);
    hot_[c].normal = len > 1e-6 * area_[c] && len > 0.0 ? glm::vec3(normal_sum_[c] / len) : glm::vec3(0.0f);
    alive_[c] = 1;
    grid_.insert(std::int32_t(c), hot_[c].pos);
  }

  void rebuildGrid(std::size_t live) {
    grid_.reset(box_, total_area_, live);
    for (std::size_t k = 0; k < count_; ++k)
      if (alive_[k]) grid_.insert(std::int32_t(k), hot_[k].pos);
  }

  std::size_t n_, count_;
  TreeOptions options_;
  std::vector<ClusterHot> hot_;
  ClusterGrid grid_;
  Aabb box_;
  double total_area_ = 0.0;
  float inv_extent2_ = 1.0f;
  std::vector<double> area_;              // m^2, exact sums (hot_.area is its float copy)
  std::vector<glm::dvec3> normal_sum_;    // area-weighted normal sum
  std::vector<std::uint8_t> alive_;
  std::vector<std::int32_t> nn_;
  std::vector<float> nn_dist_;
  std::vector<std::uint32_t> stamp_;
  std::priority_queue<HeapEntry> heap_;
};

}  // namespace

MergeTree buildAgglomerative(const surfels::Surfels& surfels, const TreeOptions& options) {
  return Agglomerator(surfels, options).run();
}

}  // namespace lightlink::hierarchy::detail
