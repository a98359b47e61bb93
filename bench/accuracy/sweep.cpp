#include "bench/accuracy/sweep.h"

#include <fmt/format.h>

namespace lightlink::bench {

relight::RelightOptions baseRelightOptions() {
  relight::RelightOptions o;
  o.link_form = relight::LinkForm::kProjected;
  o.max_bounces = 64;
  o.bounce_threshold = 1e-4f;
  o.incremental = false;
  return o;
}

std::vector<StudyPoint> studyPoints(SweepSize size) {
  const precompute::PrecomputeOptions base = precompute::preset("medium").value();
  const relight::RelightOptions rbase = baseRelightOptions();
  std::vector<StudyPoint> out;
  out.push_back({"base", "medium", base, rbase});
  if (size == SweepSize::kBase) return out;

  if (size == SweepSize::kDiagnose) {
    auto single = [&](std::string value, precompute::PrecomputeOptions pre) {
      StudyPoint p{"single", std::move(value), pre, rbase};
      p.rel.max_bounces = 0;
      p.reference_bounces = 1;
      out.push_back(p);
    };
    single("medium", base);
    precompute::PrecomputeOptions o = base;
    o.surfels = 4096;
    single("surfels4096", o);
    o = base;
    o.links = 512;
    single("links512", o);
    o = base;
    o.rays = 4096;
    single("rays4096", o);
    o = base;
    o.bands = 4;
    single("bands4", o);
    return out;
  }
  const bool full = size == SweepSize::kFull;
  auto pick = [&](std::vector<int> all, std::vector<int> reduced) { return full ? all : reduced; };
  if (size != SweepSize::kPresets) {
    for (int v : pick({4096, 8192, 16384, 65536, 131072}, {8192, 131072})) {
      StudyPoint p{"surfels", std::to_string(v), base, rbase};
      p.pre.surfels = std::uint32_t(v);
      out.push_back(p);
    }
    for (int v : pick({16, 32, 64, 256, 512}, {32, 512})) {
      StudyPoint p{"links", std::to_string(v), base, rbase};
      p.pre.links = v;
      out.push_back(p);
    }
    for (int v : {2, 4}) {
      StudyPoint p{"bands", std::to_string(v), base, rbase};
      p.pre.bands = v;
      out.push_back(p);
    }
    for (int v : pick({256, 512, 2048, 4096}, {256, 4096})) {
      StudyPoint p{"rays", std::to_string(v), base, rbase};
      p.pre.rays = v;
      out.push_back(p);
    }
    {
      StudyPoint p{"builder", "kd", base, rbase};
      p.pre.builder = hierarchy::Builder::kKdMedian;
      out.push_back(p);
    }
    for (int v : pick({64, 96, 192, 256}, {64, 256})) {
      StudyPoint p{"density", std::to_string(v), base, rbase};
      p.pre.target_resolution = v;
      out.push_back(p);
    }
    for (int v : pick({2, 3, 4}, {3, 4})) {
      StudyPoint p{"form", fmt::format("runtime{}", v), base, rbase};
      p.rel.link_form = relight::LinkForm::kRuntime;
      p.rel.bands = v;
      out.push_back(p);
    }
    for (int v : pick({0, 1, 2, 3, 4, 8}, {0, 1, 2})) {
      StudyPoint p{"bounces", std::to_string(v), base, rbase};
      p.rel.max_bounces = v;
      out.push_back(p);
    }
  }
  if (size != SweepSize::kPresets) {
    struct Combo {
      const char* name;
      std::uint32_t surfels;
      int links, rays, resolution;
    };
    constexpr Combo kCombos[] = {{"s4k-l64-r512-64", 4096, 64, 512, 64},
                                 {"s8k-l96-r512", 8192, 96, 512, 128},
                                 {"s8k-l256", 8192, 256, 1024, 128},
                                 {"s16k-l256-r2048", 16384, 256, 2048, 128},
                                 {"s16k-l512-r2048", 16384, 512, 2048, 128}};
    for (const Combo& c : kCombos) {
      if (!full && c.links == 512) continue;
      StudyPoint p{"candidate", c.name, base, rbase};
      p.pre.surfels = c.surfels;
      p.pre.links = c.links;
      p.pre.rays = c.rays;
      p.pre.target_resolution = c.resolution;
      out.push_back(p);
    }
  }
  for (const char* name : {"draft", "high"}) {
    StudyPoint p{"preset", name, precompute::preset(name).value(), rbase};
    out.push_back(p);
  }
  return out;
}

}  // namespace lightlink::bench
