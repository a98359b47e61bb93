// cut_bench: the cut (links::chooseCut) alone, on the very samples link generation gives it.
//
// precompute_bench's phase timers give the cut's share of link time, but that share moves
// with the tracing's noise on a shared VM (±5 % between runs), more than most changes to the
// cut are worth. Here the sorted samples of real caches are made once (the precompute's
// surfels, tree and lightmap caches, each cache's fan traced and credited as link generation
// does), then chooseCut runs over all of them on one thread, `repeats` times: the median
// time per cache (each cache's samples hot in cache, as the sort leaves them), and what the
// cut did (links per cache, a checksum of the chosen nodes), and how often consecutive hits
// (in ray order) fall on the same surfel. --cut-kernel scalar times the
// one-node-at-a-time splits (links::CutKernel::kScalar: the code on CPUs without AVX-512).
// Usage: cut_bench [--scene F] [--surfels N] [--links N] [--bands B] [--rays N] [--resolution R] [--hierarchy hac|fast]
//                  [--caches N] [--repeats N] [--cut-kernel best|scalar] [--json OUT]
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "bench/common/bench_common.h"
#include "core/links/cut.h"
#include "core/links/hit_credit.h"
#include "core/links/links.h"
#include "core/links/surfel_locator.h"
#include "core/precompute/precompute.h"
#include "core/scene/load.h"

using namespace lightlink;

namespace {

struct Args {
  std::string scene = std::string(LIGHTLINK_SOURCE_DIR) + "/clients/demo/cornell_box.gltf";
  std::string json;
  std::size_t caches = 4096;  // evenly spaced over the lightmap caches
  int repeats = 15;
  links::CutKernel kernel = links::CutKernel::kBest;
  precompute::PrecomputeOptions options;
};

bool parse(int argc, char** argv, Args& a) {
  a.options.lightmap_resolution = bench::kMediumResolution;  // as precompute_bench
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (i + 1 >= argc) return false;
    const char* v = argv[++i];
    if (k == "--scene") a.scene = v;
    else if (k == "--json") a.json = v;
    else if (k == "--caches") a.caches = std::max<std::size_t>(1, std::stoul(v));
    else if (k == "--repeats") a.repeats = std::max(1, std::stoi(v));
    else if (k == "--cut-kernel" && (std::strcmp(v, "best") == 0 || std::strcmp(v, "scalar") == 0))
      a.kernel = std::strcmp(v, "scalar") == 0 ? links::CutKernel::kScalar : links::CutKernel::kBest;
    else if (!bench::parsePrecomputeFlag(k, v, a.options)) return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  if (!parse(argc, argv, args)) {
    std::fprintf(stderr, "usage: cut_bench [--scene F] [--surfels N] [--links N] [--bands B] [--rays N] [--resolution R] "
                         "[--hierarchy hac|fast] "
                         "[--caches N] [--repeats N] [--cut-kernel best|scalar] [--json OUT]\n");
    return 1;
  }
  auto scene = scene::loadScene(args.scene);
  if (bench::failed(scene)) return 2;
  auto p = precompute::run(*scene, args.options);
  if (bench::failed(p)) return 2;
  auto accel = rt::Accel::build(*scene);
  if (bench::failed(accel)) return 2;
  const links::SurfelLocator locator(p->surfels, *scene);
  const links::LinkRays pattern(args.options.linkOptions());
  const std::uint32_t n = pattern.count();
  const std::vector<std::uint32_t> double_sided = links::doubleSidedByMesh(*scene);

  // Every cache's samples, sorted by (surfel, ray) as link generation's radix sort leaves
  // them (the keys are unique, so any sort gives the same order).
  const std::size_t lightmap = p->lightmap.size();
  const std::size_t caches = std::min(args.caches, lightmap);
  std::vector<links::Sample> all;
  std::vector<std::size_t> begin{0};
  std::size_t same_as_previous = 0;
  {
    std::vector<float> dx(n + 16), dy(n + 16), dz(n + 16), u(n), v(n), t(n), nx(n), ny(n), nz(n), escaped(n);
    std::vector<std::uint32_t> mesh(n), tri(n), slots(n);
    std::vector<links::Sample> samples(n + links::kHitCreditSlack);
    const rt::HitArrays hits{mesh.data(), tri.data(), u.data(), v.data(), t.data(), nx.data(), ny.data(), nz.data()};
    for (std::size_t k = 0; k < caches; ++k) {
      const std::size_t c = k * lightmap / caches;
      const links::LinkRays::Directions d{dx.data(), dy.data(), dz.data()};
      const rt::RayFan fan = pattern.fan(*accel, c, p->lightmap.position[c], p->lightmap.normal[c], d);
      accel->intersectFan(fan, hits);
      const links::HitCredit credit = links::creditHits(fan, hits, double_sided.data(), locator, slots.data(),
                                                        escaped.data(), samples.data());
      // In ray order, as the sort receives them: how often a hit's surfel is the previous hit's.
      for (std::uint32_t i = 1; i < credit.sampled; ++i)
        same_as_previous += links::surfelOf(samples[i]) == links::surfelOf(samples[i - 1]) ? 1 : 0;
      std::sort(samples.begin(), samples.begin() + credit.sampled);
      all.insert(all.end(), samples.begin(), samples.begin() + credit.sampled);
      begin.push_back(all.size());
    }
  }

  const links::CutTree tree = links::cutTree(p->tree);
  links::CutScratch scratch;
  std::vector<links::CutEntry> cut;
  std::size_t links_total = 0;
  std::uint64_t checksum = 0;  // what the cut chose, so no run can be optimised away
  std::vector<double> cut_ns;
  // Link generation hands the cut samples its sort has just written (in L1/L2): each
  // cache's samples are copied into one hot buffer first, outside the timed part, so that the
  // cut is not timed on samples streamed from memory.
  std::vector<links::Sample> hot(n);
  for (int r = 0; r < args.repeats; ++r) {
    double cut_s = 0.0;
    std::size_t total = 0;
    std::uint64_t chosen = 0;
    for (std::size_t k = 0; k < caches; ++k) {
      const std::size_t m = begin[k + 1] - begin[k];
      std::copy(all.begin() + begin[k], all.begin() + begin[k + 1], hot.begin());
      const auto t0 = bench::Clock::now();
      links::chooseCut(tree, std::span<const links::Sample>(hot.data(), m), args.options.links, scratch, cut,
                       args.kernel);
      cut_s += bench::secondsSince(t0);
      total += cut.size();
      for (const links::CutEntry& e : cut) chosen = chosen * 31 + e.node;
    }
    cut_ns.push_back(1e9 * cut_s / double(caches));
    links_total = total;
    checksum = chosen;
  }
  const double cut_med = bench::median(cut_ns);
  const double samples_per_cache = double(all.size()) / double(caches);
  const double links_per_cache = double(links_total) / double(caches);
  fmt::print("{} caches of {} ({} rays each), {:.0f} samples and {:.1f} links per cache\n", caches, lightmap, n,
             samples_per_cache, links_per_cache);
  const double same_share = all.empty() ? 0.0 : double(same_as_previous) / double(all.size());
  fmt::print("hits in ray order on the same surfel as the previous hit: {:.1f} %\n", 100.0 * same_share);
  fmt::print("chooseCut: {:.0f} ns per cache (min {:.0f}), {:.1f} ns per link; checksum {:016x}\n", cut_med,
             *std::min_element(cut_ns.begin(), cut_ns.end()), cut_med / std::max(1.0, links_per_cache), checksum);
  if (!args.json.empty()) {
    nlohmann::ordered_json j;
    j["scene"] = args.scene;
    j["caches"] = caches;
    j["rays_per_cache"] = n;
    j["samples_per_cache"] = samples_per_cache;
    j["links_per_cache"] = links_per_cache;
    j["same_surfel_as_previous_hit"] = same_share;
    j["cut_ns_per_cache"] = cut_ns;
    j["median_cut_ns_per_cache"] = cut_med;
    j["checksum"] = checksum;
    j["cut_kernel"] = args.kernel == links::CutKernel::kScalar ? "scalar" : "best";
    std::ofstream(args.json) << j.dump(2) << "\n";
  }
  return 0;
}
