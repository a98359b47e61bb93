#include "core/links/cut.h"

#include <algorithm>
#include <bit>
#include <stdexcept>

#include "core/common/avx512.h"
#include "core/common/check.h"
#include "core/common/isa.h"

namespace lightlink::links {

CutTree cutTree(const hierarchy::Tree& tree) {
  if (tree.nodeCount() >= kRightIsLeaf) throw std::length_error("cutTree: more tree nodes than the cut can index");
  CutTree out;
  out.leaf_of_surfel = tree.leaf_of_surfel;
  std::vector<CutNode>& nodes = out.nodes;
  nodes.resize(tree.nodeCount());
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    if (tree.isLeaf(i)) {
      nodes[i] = {kLeaf, 0};
      continue;
    }
    const auto l = static_cast<std::uint32_t>(tree.left[i]), r = static_cast<std::uint32_t>(tree.right[i]);
    // Breadth-first numbering gives siblings consecutive indices (hierarchy/tree.h).
    if (r != l + 1) throw std::logic_error("cutTree: a node's children are not consecutive nodes");
    nodes[i] = {l | (tree.isLeaf(l) ? kLeftIsLeaf : 0u) | (tree.isLeaf(r) ? kRightIsLeaf : 0u), tree.end[l]};
  }
  return out;
}

namespace {

// The nodes the search reached, one array per field (records), the internal ones still to
// be split (queue: more samples than the threshold; pending: the others), and the split
// nodes with samples on both sides (growing). Every array keeps kSlack entries of room past
// its end, so that a batch of up to kBatch nodes can store whole vectors unchecked.
constexpr std::size_t kBatch = 16, kSlack = 2 * kBatch;
constexpr std::size_t kVectorFrom = 6;

struct Search {
  const CutNode* nodes;
  const Sample* samples;
  std::uint32_t threshold;
  CutScratch& s;
  // Records: node (with kLeafChild for a leaf), samples, first sample, parent's samples and
  // parent's node (the parent's key, split in two for 32-bit lanes).
  std::uint32_t *rn, *rc, *rf, *pc, *pn;
  std::uint32_t *qn, *qc, *qf;  // queue
  std::uint32_t *wn, *wc, *wf;  // pending
  std::uint32_t *gc, *gn;       // growing
  std::size_t records = 0, head = 0, tail = 0, pending = 0, growing = 0;

  Search(const CutNode* n, const Sample* sm, std::uint32_t t, CutScratch& scratch)
      : nodes(n), samples(sm), threshold(t), s(scratch) {
    grow(std::max<std::size_t>(s.field[0].size(), 256));
  }
  void bind() {
    std::uint32_t* p[kCutFields];
    for (std::size_t f = 0; f < kCutFields; ++f) p[f] = s.field[f].data();
    rn = p[0], rc = p[1], rf = p[2], pc = p[3], pn = p[4];
    qn = p[5], qc = p[6], qf = p[7];
    wn = p[8], wc = p[9], wf = p[10];
    gc = p[11], gn = p[12];
  }
  void grow(std::size_t size) {
    for (auto& f : s.field) f.resize(size);
    bind();
  }
  // Room for one more batch: it adds at most six records per node (its children's and,
  // split in the same go, its grandchildren's), at most as many queue or pending entries, and
  // three growing nodes per node. The queue is never compacted while a cut is chosen, so
  // every array is bounded by the records.
  void reserveBatch() {
    const std::size_t need = std::max(records, tail) + 6 * kBatch + kSlack;
    if (need > s.field[0].size()) grow(2 * need);
  }
  void record(std::uint32_t node, std::uint32_t count, std::uint32_t first, std::uint32_t parent_count,
              std::uint32_t parent_node) {
    rn[records] = node, rc[records] = count, rf[records] = first, pc[records] = parent_count, pn[records] = parent_node;
    ++records;
    if (node & kLeafChild) return;
    if (count > threshold) {
      qn[tail] = node, qc[tail] = count, qf[tail] = first;
      ++tail;
    } else {
      wn[pending] = node, wc[pending] = count, wf[pending] = first;
      ++pending;
    }
  }
};

// First position in sorted [first, first + n) whose key is >= key, n >= 1: halving steps
// (the select compiles to a conditional move) until one key is left, then that key compared.
inline std::uint32_t lowerBound(const Sample* first, std::uint32_t n, Sample key) {
  const Sample* base = first;
  while (n > 1) {
    const std::uint32_t half = n / 2;
    base = base[half] < key ? base + half : base;
    n -= half;
  }
  return static_cast<std::uint32_t>(base - first) + (*base < key ? 1u : 0u);
}

// Splits queue entries [head, head + m), m <= kBatch, one node at a time.
void splitScalar(Search& x, std::size_t m) {
  for (std::size_t i = x.head; i < x.head + m; ++i) {
    const std::uint32_t node = x.qn[i], count = x.qc[i], first = x.qf[i];
    const CutNode& tn = x.nodes[node];
    const std::uint32_t left = leftChild(tn.children), right = rightChild(tn.children);
    // The left child's surfels come first in the parent's range, so its samples are a
    // prefix of the parent's: one binary search inside the parent's samples.
    const std::uint32_t cl = lowerBound(x.samples + first, count, makeSample(tn.split, 0)), cr = count - cl;
    if (cl > 0) x.record(left, cl, first, count, node);
    if (cr > 0) x.record(right, cr, first + cl, count, node);
    if (cl > 0 && cr > 0) {
      x.gc[x.growing] = count, x.gn[x.growing] = node;
      ++x.growing;
    }
  }
  x.head += m;
}

#if LL_AVX512
// The same for 16 nodes in the lanes of one vector (splitAvx512, below): their 16 binary
// searches advance together (one gather per halving step, as many steps as the largest node
// needs), and the children are appended to the arrays by compressing the lanes that have
// them. A search that waits on its loads one after the other is what the one-node-at-a-time
// loop is made of; here 16 of them share each wait.

// Appends v's lanes in `keep` to dst at `at`: compressed in a register and stored whole (a
// compressing store to memory is microcoded on Zen 4/5; the arrays have the slack).
LL_AVX512_FN inline void append(std::uint32_t* dst, std::size_t& at, __mmask16 keep, __m512i v) {
  _mm512_storeu_si512(dst + at, _mm512_maskz_compress_epi32(keep, v));
  at += static_cast<std::size_t>(__builtin_popcount(keep));
}

// The node records of 16 nodes: children (with kLeafChild for a leaf) and split.
LL_AVX512_FN inline void gatherNode(__m512i node, __mmask16 lanes, const CutNode* nodes, __m512i& left,
                                        __m512i& right, __m512i& split) {
  const auto* words = reinterpret_cast<const int*>(nodes);
  const __m512i zero = _mm512_setzero_si512();
  const __m512i w = _mm512_slli_epi32(node, 1);  // CutNode is 2 words
  const __m512i children = _mm512_mask_i32gather_epi32(zero, lanes, w, words, 4);
  split = _mm512_mask_i32gather_epi32(zero, lanes, _mm512_add_epi32(w, _mm512_set1_epi32(1)), words, 4);
  const __m512i index = _mm512_and_si512(children, _mm512_set1_epi32(static_cast<int>(kChildIndex)));
  const __m512i leaf_bit = _mm512_set1_epi32(static_cast<int>(kLeafChild));
  left = _mm512_or_si512(index, _mm512_and_si512(children, leaf_bit));
  right = _mm512_or_si512(_mm512_add_epi32(index, _mm512_set1_epi32(1)),
                          _mm512_and_si512(_mm512_slli_epi32(children, 1), leaf_bit));
}

// One vector of nodes being split: their fields, their records' fields, and then the left
// child's count.
struct Lanes {
  __mmask16 lanes;
  __m512i node, count, first, left, right, split, cl;
};

LL_AVX512_FN inline Lanes loadLanes(const Search& x, std::size_t at, std::size_t m) {
  Lanes l;
  l.lanes = firstLanes(m);
  l.node = _mm512_maskz_loadu_epi32(l.lanes, x.qn + at);
  l.count = _mm512_maskz_loadu_epi32(l.lanes, x.qc + at);
  l.first = _mm512_maskz_loadu_epi32(l.lanes, x.qf + at);
  gatherNode(l.node, l.lanes, x.nodes, l.left, l.right, l.split);
  return l;
}

// The binary searches of V vectors of nodes, interleaved: V independent chains of gathers,
// each as long as the largest range needs.
template <int V>
LL_AVX512_FN inline void searchLanes(const Search& x, Lanes* l) {
  // The surfel of sample k is the high word of the 8-byte key.
  const int* surfels = reinterpret_cast<const int*>(x.samples) + 1;
  const __m512i zero = _mm512_setzero_si512(), one = _mm512_set1_epi32(1);
  std::uint32_t widest = 0;
  __m512i base[V], n[V];
  for (int v = 0; v < V; ++v) {
    widest = std::max(widest, static_cast<std::uint32_t>(_mm512_mask_reduce_max_epu32(l[v].lanes, l[v].count)));
    base[v] = l[v].first, n[v] = l[v].count;
  }
  for (std::uint32_t w = widest; w > 1; w -= w / 2) {
    for (int v = 0; v < V; ++v) {
      const __m512i half = _mm512_srli_epi32(n[v], 1);
      const __m512i probe = _mm512_add_epi32(base[v], half);
      const __m512i s = _mm512_mask_i32gather_epi32(zero, l[v].lanes, probe, surfels, 8);
      base[v] = _mm512_mask_mov_epi32(base[v], _mm512_cmplt_epu32_mask(s, l[v].split), probe);
      n[v] = _mm512_sub_epi32(n[v], half);
    }
  }
  for (int v = 0; v < V; ++v) {
    const __m512i s = _mm512_mask_i32gather_epi32(zero, l[v].lanes, base[v], surfels, 8);
    const __m512i below = _mm512_sub_epi32(base[v], l[v].first);
    l[v].cl = _mm512_mask_add_epi32(below, _mm512_cmplt_epu32_mask(s, l[v].split), below, one);
  }
}

// Appends the split nodes' children (and the split nodes to growing). Children in
// done_l / done_r are split in the same call (splitAvx512's second level): not queued.
LL_AVX512_FN inline void appendLanes(Search& x, const Lanes& l, __mmask16 done_l = 0, __mmask16 done_r = 0) {
  const __m512i zero = _mm512_setzero_si512();
  const __m512i cr = _mm512_sub_epi32(l.count, l.cl);
  const __m512i right_first = _mm512_add_epi32(l.first, l.cl);
  const __mmask16 has_l = _mm512_mask_cmpneq_epi32_mask(l.lanes, l.cl, zero);
  const __mmask16 has_r = _mm512_mask_cmpneq_epi32_mask(l.lanes, cr, zero);
  // Records, the left children first, then the right ones (the order of records does not
  // change the cut).
  const std::size_t r0 = x.records;
  std::size_t k = r0;
  append(x.rn, k, has_l, l.left), append(x.rn, k, has_r, l.right);
  k = r0, append(x.rc, k, has_l, l.cl), append(x.rc, k, has_r, cr);
  k = r0, append(x.rf, k, has_l, l.first), append(x.rf, k, has_r, right_first);
  k = r0, append(x.pc, k, has_l, l.count), append(x.pc, k, has_r, l.count);
  k = r0, append(x.pn, k, has_l, l.node), append(x.pn, k, has_r, l.node);
  x.records = k;
  // Internal children: to the queue above the threshold, else to pending.
  const __m512i threshold = _mm512_set1_epi32(static_cast<int>(x.threshold));
  const __m512i leaf_bit = _mm512_set1_epi32(static_cast<int>(kLeafChild));
  const __mmask16 inner_l = _mm512_mask_testn_epi32_mask(has_l, l.left, leaf_bit);
  const __mmask16 inner_r = _mm512_mask_testn_epi32_mask(has_r, l.right, leaf_bit);
  const __mmask16 big_l = _mm512_mask_cmpgt_epu32_mask(inner_l, l.cl, threshold);
  const __mmask16 big_r = _mm512_mask_cmpgt_epu32_mask(inner_r, cr, threshold);
  const __mmask16 small_l = inner_l & ~big_l, small_r = inner_r & ~big_r;
  const __mmask16 queue_l = big_l & ~done_l, queue_r = big_r & ~done_r;
  std::size_t t = x.tail;
  append(x.qn, t, queue_l, l.left), append(x.qn, t, queue_r, l.right);
  t = x.tail, append(x.qc, t, queue_l, l.cl), append(x.qc, t, queue_r, cr);
  t = x.tail, append(x.qf, t, queue_l, l.first), append(x.qf, t, queue_r, right_first);
  x.tail = t;
  std::size_t p = x.pending;
  append(x.wn, p, small_l, l.left), append(x.wn, p, small_r, l.right);
  p = x.pending, append(x.wc, p, small_l, l.cl), append(x.wc, p, small_r, cr);
  p = x.pending, append(x.wf, p, small_l, l.first), append(x.wf, p, small_r, right_first);
  x.pending = p;
  const __mmask16 both = has_l & has_r;
  std::size_t g = x.growing;
  append(x.gc, g, both, l.count);
  g = x.growing, append(x.gn, g, both, l.node);
  x.growing = g;
}

// Splits queue entries [head, head + m), m <= kBatch, and those of their children that
// are to be split too, in one go. The split search of a child needs no result of its
// parent's: it searches the child's split in the parent's samples, which holds the child's.
// So the parents' and the children's searches run as three interleaved chains, and a path
// from the root costs half as many chains one after the other (the search's depth, not its
// width, is what it waits on: most batches hold fewer than 16 nodes).
LL_AVX512_FN void splitAvx512(Search& x, std::size_t m) {
  Lanes l[3];
  l[0] = loadLanes(x, x.head, m);
  x.head += m;
  const Lanes& p = l[0];
  const __m512i leaf_bit = _mm512_set1_epi32(static_cast<int>(kLeafChild));
  for (int c = 1; c <= 2; ++c) {
    Lanes& k = l[c];
    k.node = c == 1 ? p.left : p.right;
    k.lanes = _mm512_mask_testn_epi32_mask(p.lanes, k.node, leaf_bit);
    k.first = p.first, k.count = p.count;  // searched in the parent's samples
    gatherNode(k.node, k.lanes, x.nodes, k.left, k.right, k.split);
  }
  searchLanes<3>(x, l);
  // The children's own ranges: the left child has the parent's first cl samples, the right
  // one the rest; children above the threshold are split here.
  const __m512i threshold = _mm512_set1_epi32(static_cast<int>(x.threshold));
  Lanes& a = l[1];
  Lanes& b = l[2];
  a.count = p.cl;
  b.count = _mm512_sub_epi32(p.count, p.cl);
  b.first = _mm512_add_epi32(p.first, p.cl);
  b.cl = _mm512_sub_epi32(b.cl, p.cl);
  a.lanes = _mm512_mask_cmpgt_epu32_mask(a.lanes, a.count, threshold);
  b.lanes = _mm512_mask_cmpgt_epu32_mask(b.lanes, b.count, threshold);
  appendLanes(x, p, a.lanes, b.lanes);
  if (a.lanes) appendLanes(x, a);
  if (b.lanes) appendLanes(x, b);
}

#endif

// The distinct surfels among sorted samples, counted until past `enough`. Blocks of 16
// samples without a branch inside (the one-sample loop's exit test was taken about every
// other sample).
LL_ISA_INLINE std::uint32_t distinctSurfelsImpl(std::span<const Sample> samples, std::uint32_t enough) {
  constexpr std::size_t kBlock = 16;
  const std::size_t n = samples.size();
  std::uint32_t distinct = 1;
  std::size_t k = 1;
  for (; k + kBlock <= n && distinct <= enough; k += kBlock)
    for (std::size_t i = k; i < k + kBlock; ++i) distinct += surfelOf(samples[i]) != surfelOf(samples[i - 1]) ? 1u : 0u;
  for (; k < n && distinct <= enough; ++k) distinct += surfelOf(samples[k]) != surfelOf(samples[k - 1]) ? 1u : 0u;
  return distinct;
}
LL_ISA_CLONES(std::uint32_t, distinctSurfels, (std::span<const Sample> samples, std::uint32_t enough), (samples, enough), distinctSurfelsImpl)

// How many of counts[0, n) are >= c.
LL_ISA_INLINE std::uint32_t countAtLeastImpl(const std::uint32_t* counts, std::size_t n, std::uint32_t c) {
  std::uint32_t k = 0;
  for (std::size_t i = 0; i < n; ++i) k += counts[i] >= c ? 1u : 0u;
  return k;
}
LL_ISA_CLONES(std::uint32_t, countAtLeast, (const std::uint32_t* counts, std::size_t n, std::uint32_t c), (counts, n, c), countAtLeastImpl)

inline bool keyAbove(std::uint32_t count, std::uint32_t node, std::uint32_t stop_count, std::uint32_t stop_node) {
  return count > stop_count || (count == stop_count && node < stop_node);
}

// Marks the cut's records in the ordering's table and bitmap: a record is in the cut when
// its parent is refined (key above g's) and it is not (a leaf, or a key not above g's).
void markScalar(const Search& x, std::uint32_t stop_count, std::uint32_t stop_node, std::uint32_t* at_first,
                std::uint64_t* starts) {
  for (std::uint32_t r = 0; r < x.records; ++r) {
    const std::uint32_t node = x.rn[r] & ~kLeafChild;
    const bool refined = !(x.rn[r] & kLeafChild) && keyAbove(x.rc[r], node, stop_count, stop_node);
    if (!keyAbove(x.pc[r], x.pn[r], stop_count, stop_node) || refined) continue;
    at_first[x.rf[r]] = r;
    starts[x.rf[r] / 64] |= std::uint64_t(1) << (x.rf[r] % 64);
  }
}

#if LL_AVX512
// The same test on 16 records at a time (the branches of the one above mispredicted on
// about every other record).
LL_AVX512_FN void markAvx512(const Search& x, std::uint32_t stop_count, std::uint32_t stop_node,
                                 std::uint32_t* at_first, std::uint64_t* starts) {
  const __m512i sc = _mm512_set1_epi32(static_cast<int>(stop_count));
  const __m512i sn = _mm512_set1_epi32(static_cast<int>(stop_node));
  const __m512i leaf_bit = _mm512_set1_epi32(static_cast<int>(kLeafChild));
  for (std::size_t r = 0; r < x.records; r += kBatch) {
    const __mmask16 lanes = firstLanes(x.records - r);
    const __m512i rn = _mm512_maskz_loadu_epi32(lanes, x.rn + r), rc = _mm512_maskz_loadu_epi32(lanes, x.rc + r);
    const __m512i pc = _mm512_maskz_loadu_epi32(lanes, x.pc + r), pn = _mm512_maskz_loadu_epi32(lanes, x.pn + r);
    const __mmask16 parent_refined =
        _mm512_mask_cmpgt_epu32_mask(lanes, pc, sc) |
        (_mm512_mask_cmpeq_epi32_mask(lanes, pc, sc) & _mm512_cmplt_epu32_mask(pn, sn));
    // A leaf's kLeafChild bit makes its node compare above any stop node: never refined.
    const __mmask16 refined = _mm512_cmpgt_epu32_mask(rc, sc) & _mm512_testn_epi32_mask(rn, leaf_bit);
    const __mmask16 refined_tie = _mm512_cmpeq_epi32_mask(rc, sc) & _mm512_cmplt_epu32_mask(rn, sn);
    for (unsigned in = parent_refined & ~(refined | refined_tie); in != 0; in &= in - 1) {
      const auto k = static_cast<std::uint32_t>(r) + static_cast<std::uint32_t>(std::countr_zero(in));
      const std::uint32_t first = x.rf[k];
      at_first[first] = k;
      starts[first / 64] |= std::uint64_t(1) << (first % 64);
    }
  }
}
#endif

}  // namespace

void chooseCut(const CutTree& tree, std::span<const Sample> samples, int max_links, CutScratch& s,
               std::vector<CutEntry>& cut, CutKernel kernel) {
  cut.clear();
  const std::span<const CutNode> nodes = tree.nodes;
  if (samples.empty() || nodes.empty()) return;
  // Open and linked nodes hold disjoint, non-empty sets of the samples' surfels, so there are
  // never more of them than distinct surfels. With no more of those than the budget, the
  // refinement therefore never stops early and ends with one leaf per surfel: that cut
  // straight from the runs of the sorted samples, without walking every root-to-leaf path.
  // (It pays on open scenes, where a cache sees few surfels: ShadowsDirectional averages
  // ~52 links per cache; cut_bench --scene times the cut there.)
  // (Counting stops once past the budget: most caches of a closed scene see hundreds of surfels.)
  const std::uint32_t distinct = distinctSurfels(samples, static_cast<std::uint32_t>(max_links));
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
  // Largest-first refinement, without replaying it step by step. A node's key (samples, then
  // the lower node index) is unique and, children having higher indices than their parents
  // (breadth-first layout), falls strictly from a node to its children. So the refinement
  // pops nodes in falling key order; every refinement of a node with samples on both sides
  // ("growing") opens one entry more; and it stops at the max_links-th growing node in key
  // order, g (one exists: there are more distinct surfels than the budget). Refined are
  // exactly the internal nodes with keys above g's, and the cut is every reached node whose
  // parent is refined and which is not refined itself (tests/links/cut_test.cpp holds this
  // against the refinement taken literally).
  // Finding g needs every node with a key above g's split: a search that splits every
  // internal node with more than T samples has done so once it found max_links growing
  // nodes. T starts just below the last cut's stopping count (neighbouring caches see much
  // the same) and is lowered while fewer were found; the cut does not depend on T. The
  // splits need no order among themselves, so they run 16 at a time (splitAvx512).
  const auto limit = static_cast<std::uint32_t>(max_links);
  Search x(nodes.data(), samples.data(), s.stop_count > 1 ? s.stop_count - 1 : 0, s);
  x.record(0, static_cast<std::uint32_t>(samples.size()), 0, ~0u, 0);
#if LL_AVX512
  const bool vector = kernel == CutKernel::kBest && isaAtLeast(Isa::kAvx512);
  auto split = vector ? &splitAvx512 : &splitScalar;
  auto mark = vector ? &markAvx512 : &markScalar;
#else
  (void)kernel;
  auto split = &splitScalar;
  auto mark = &markScalar;
#endif
  for (;;) {
    while (x.head < x.tail) {
      x.reserveBatch();
      const std::size_t m = std::min(kBatch, x.tail - x.head);
      // A batch of a few nodes (the first ones, from the root down) waits on one gather per
      // halving step where single loads would do: fewer than kVectorFrom go one at a time
      // (kVectorFrom is where cut_bench finds the vector split starts to pay).
      (m < kVectorFrom ? &splitScalar : split)(x, m);
    }
    if (x.growing >= limit || x.pending == 0) break;
    // Lowered by a quarter (at least 1; not tuned): a further round only splits the nodes
    // that the lower threshold adds, while every node split below g's count is wasted.
    x.threshold -= std::max<std::uint32_t>(1, x.threshold / 4);
    std::size_t kept = 0;
    for (std::size_t i = 0; i < x.pending; ++i) {
      if (x.wc[i] > x.threshold) {
        x.qn[x.tail] = x.wn[i], x.qc[x.tail] = x.wc[i], x.qf[x.tail] = x.wf[i];
        ++x.tail;
      } else {
        x.wn[kept] = x.wn[i], x.wc[kept] = x.wc[i], x.wf[kept] = x.wf[i];
        ++kept;
      }
    }
    x.pending = kept;
  }
  // g: the limit-th largest key among the growing nodes. Its count c first, the largest
  // with at least `limit` growing nodes of c samples or more: all of them have more than the
  // final threshold, and c is mostly just above it, so the search gallops up from there.
  // Then, among the growing nodes of exactly c samples, the one of the right rank by node
  // index.
  // The search only stops short of `limit` growing nodes with nothing left to split, and
  // then the whole tree had only distinct - 1 < limit of them: the leaves' case above.
  LL_CHECK_GE(x.growing, std::size_t(limit));
  std::uint32_t lo = x.threshold + 1, hi = lo + 1;  // atLeast(lo) >= limit > atLeast(hi)
  for (std::uint32_t step = 1; countAtLeast(x.gc, x.growing, hi) >= limit; step *= 2) lo = hi, hi += step;
  while (hi - lo > 1) {
    const std::uint32_t mid = lo + (hi - lo) / 2;
    (countAtLeast(x.gc, x.growing, mid) >= limit ? lo : hi) = mid;
  }
  const std::uint32_t stop_count = lo;
  const std::uint32_t rank = limit - countAtLeast(x.gc, x.growing, lo + 1);  // 1-based among the ties
  auto& ties = s.ties;
  ties.resize(x.growing);
  std::size_t n_ties = 0;
  for (std::size_t i = 0; i < x.growing; ++i) {
    ties[n_ties] = x.gn[i];
    n_ties += x.gc[i] == lo ? 1 : 0;
  }
  std::nth_element(ties.begin(), ties.begin() + (rank - 1), ties.begin() + static_cast<std::ptrdiff_t>(n_ties));
  const std::uint32_t stop_node = ties[rank - 1];
  s.stop_count = stop_count;
  // The cut, put in order of first sample: the entries' sample ranges partition
  // [0, samples), so that is a walk over a bitmap of their first samples, lowest bit first,
  // through a first-sample -> record table (no comparison sort).
  const std::size_t words = (samples.size() + 63) / 64;
  if (s.at_first.size() < samples.size()) s.at_first.resize(samples.size());
  s.starts.assign(words, 0);
  mark(x, stop_count, stop_node, s.at_first.data(), s.starts.data());
  for (std::size_t w = 0; w < words; ++w)
    for (std::uint64_t bits = s.starts[w]; bits != 0; bits &= bits - 1) {
      const std::uint32_t r = s.at_first[w * 64 + static_cast<std::uint32_t>(std::countr_zero(bits))];
      cut.push_back({x.rc[r], x.rn[r] & ~kLeafChild, x.rf[r]});
    }
}

}  // namespace lightlink::links
