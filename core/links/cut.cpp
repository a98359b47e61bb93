#include "core/links/cut.h"

#include <algorithm>
#include <bit>

namespace lightlink::links {

CutTree cutTree(const hierarchy::Tree& tree) {
  CutTree out;
  out.leaf_of_surfel = tree.leaf_of_surfel;
  std::vector<CutNode>& nodes = out.nodes;
  nodes.resize(tree.nodeCount());
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    if (tree.isLeaf(i)) {
      nodes[i] = {kLeaf, kLeaf, 0};
    } else {
      const auto l = static_cast<std::uint32_t>(tree.left[i]);
      nodes[i] = {l, static_cast<std::uint32_t>(tree.right[i]), tree.end[l]};
    }
  }
  return out;
}

namespace {

inline std::uint64_t openKey(std::uint32_t count, std::uint32_t node) {
  return (std::uint64_t(count) << 32) | std::uint32_t(~node);
}

// The entry being placed is held in registers while the hole moves and written once, where
// it lands. Written to its start slot first and read back from there, every push and
// replacement read back as one load what two smaller stores had just written, which the
// CPU cannot forward (perf put samples on the instructions after those loads). Measured
// together with lowerBound's counted tail below (docs/results.md, issue 4 twelfth pass).
class OpenHeap {
 public:
  explicit OpenHeap(std::vector<OpenEntry>& storage) : h_(storage) { h_.clear(); }
  bool empty() const { return h_.empty(); }
  std::size_t size() const { return h_.size(); }
  const OpenEntry& top() const { return h_[0]; }
  void push(OpenEntry e) {
    h_.emplace_back();
    siftUp(h_.size() - 1, e);
  }
  // Replaces the top (with a key no larger than it had: a child of the popped node).
  void replaceTop(OpenEntry e) { siftDown(0, e); }
  void popTop() {
    const OpenEntry last = h_.back();
    h_.pop_back();
    if (!h_.empty()) siftDown(0, last);
  }
  const std::vector<OpenEntry>& entries() const { return h_; }

 private:
  // Places e in the hole at i, moving the hole up past smaller parents.
  void siftUp(std::size_t i, const OpenEntry e) {
    while (i > 0) {
      const std::size_t parent = (i - 1) / 2;
      if (h_[parent].key >= e.key) break;
      h_[i] = h_[parent];
      i = parent;
    }
    h_[i] = e;
  }
  // Places e in the hole at i, moving the hole down past larger children.
  void siftDown(std::size_t i, const OpenEntry e) {
    const std::size_t n = h_.size();
    for (;;) {
      std::size_t c = 2 * i + 1;
      if (c >= n) break;
      c += (c + 1 < n && h_[c + 1].key > h_[c].key) ? 1 : 0;
      if (h_[c].key <= e.key) break;
      h_[i] = h_[c];
      i = c;
    }
    h_[i] = e;
  }
  std::vector<OpenEntry>& h_;
};

// First position in sorted [first, first + n) whose key is >= key. Branch-free: halving
// steps (the select compiles to a conditional move; a profile of the old cut had its samples
// on std::lower_bound's branches) until at most kLinearCount keys are left, which are then
// counted. Each halving step waits on its load; the count's loads are independent. With the
// heap's change above, the cut went from 6.2 to 5.9 us per cache (cut_bench, CornellBox-Original;
// docs/results.md, issue 4 twelfth pass); counting 8 gained no more, 16 lost.
inline constexpr std::uint32_t kLinearCount = 4;
inline std::uint32_t lowerBound(const Sample* first, std::uint32_t n, Sample key) {
  const Sample* base = first;
  while (n > kLinearCount) {
    const std::uint32_t half = n / 2;
    base = base[half] < key ? base + half : base;
    n -= half;
  }
  // n is 1..4 here (a node in the heap has samples): always four compares, the ones past n
  // reading the last key and not counted, so no loop exit to mispredict.
  std::uint32_t below = 0;
  for (std::uint32_t i = 0; i < kLinearCount; ++i)
    below += (i < n && base[std::min(i, n - 1)] < key) ? 1u : 0u;
  return static_cast<std::uint32_t>(base - first) + below;
}

}  // namespace

void chooseCut(const CutTree& tree, std::span<const Sample> samples, int max_links, CutScratch& s,
               std::vector<CutEntry>& cut) {
  cut.clear();
  const std::span<const CutNode> nodes = tree.nodes;
  if (samples.empty() || nodes.empty()) return;
  // Open and linked nodes hold disjoint, non-empty sets of the samples' surfels, so there are
  // never more of them than distinct surfels. With no more of those than the budget, the
  // refinement therefore never stops early and ends with one leaf per surfel: that cut
  // straight from the runs of the sorted samples, without walking every root-to-leaf path.
  // (On ShadowsDirectional, 52 links per cache on average, this halved chooseCut's perf
  // samples: docs/results.md, "Cuts that end at the leaves".)
  // (Counting stops once past the budget: most caches of a closed scene see hundreds of surfels.)
  std::uint32_t distinct = 0;
  for (std::size_t k = 0; k < samples.size() && distinct <= static_cast<std::uint32_t>(max_links); ++k)
    distinct += (k == 0 || surfelOf(samples[k]) != surfelOf(samples[k - 1])) ? 1 : 0;
  if (distinct <= static_cast<std::uint32_t>(max_links)) {
    for (std::uint32_t k = 0; k < samples.size();) {
      const std::uint32_t surfel = surfelOf(samples[k]);
      std::uint32_t end = k + 1;
      while (end < samples.size() && surfelOf(samples[end]) == surfel) ++end;
      cut.push_back({end - k, tree.leaf_of_surfel[surfel], k});
      k = end;
    }
    return;
  }
  OpenHeap open(s.open);
  open.push({openKey(static_cast<std::uint32_t>(samples.size()), 0), 0});
  const auto limit = static_cast<std::size_t>(max_links);
  while (!open.empty()) {
    const OpenEntry top = open.top();
    const auto node = static_cast<std::uint32_t>(~static_cast<std::uint32_t>(top.key));
    const auto count = static_cast<std::uint32_t>(top.key >> 32);
    const CutNode& tn = nodes[node];
    if (tn.left == kLeaf) {
      open.popTop();
      cut.push_back({count, node, top.first});
      continue;
    }
    // The left child's surfels come first in the parent's range, so its samples are a
    // prefix of the parent's: one binary search inside the parent's samples.
    const std::uint32_t l = tn.left, r = tn.right;
    // The children's records are read when they come to the top, often the next step: start
    // their loads now, under the binary search.
    __builtin_prefetch(&nodes[l]);
    __builtin_prefetch(&nodes[r]);
    const std::uint32_t cl = lowerBound(samples.data() + top.first, count, makeSample(tn.split, 0));
    const std::uint32_t cr = count - cl;
    const std::size_t grow = (cl > 0 && cr > 0) ? 1 : 0;
    if (open.size() + cut.size() + grow > limit) break;
    if (cl > 0 && cr > 0) {
      // The larger child takes the top (it often stays there: a short sift down), the
      // smaller one enters at the bottom (a short sift up). Keys are unique, so the heap's
      // layout does not change which node is refined next.
      const OpenEntry left{openKey(cl, l), top.first}, right{openKey(cr, r), top.first + cl};
      const bool left_larger = left.key > right.key;
      open.replaceTop(left_larger ? left : right);
      open.push(left_larger ? right : left);
    } else if (cl > 0) {
      open.replaceTop({openKey(cl, l), top.first});
    } else {
      open.replaceTop({openKey(cr, r), top.first + cl});
    }
  }
  for (const OpenEntry& e : open.entries())
    cut.push_back({static_cast<std::uint32_t>(e.key >> 32), ~static_cast<std::uint32_t>(e.key), e.first});
  // The entries' sample ranges partition [0, samples): ordering them by first sample is a
  // walk over a bitmap of the first samples, lowest bit first, through a first-sample ->
  // entry table (no comparison sort). Walking the ranges themselves (k += count of the entry
  // at k) was a chain of three dependent loads per entry.
  const std::size_t words = (samples.size() + 63) / 64;
  if (s.at_first.size() < samples.size()) s.at_first.resize(samples.size());
  s.starts.assign(words, 0);
  for (std::uint32_t e = 0; e < cut.size(); ++e) {
    const std::uint32_t first = cut[e].first;
    s.at_first[first] = e;
    s.starts[first / 64] |= std::uint64_t(1) << (first % 64);
  }
  s.ordered.resize(cut.size());
  CutEntry* out = s.ordered.data();
  for (std::size_t w = 0; w < words; ++w)
    for (std::uint64_t bits = s.starts[w]; bits != 0; bits &= bits - 1)
      *out++ = cut[s.at_first[w * 64 + static_cast<std::uint32_t>(std::countr_zero(bits))]];
  cut.swap(s.ordered);
}

}  // namespace lightlink::links
