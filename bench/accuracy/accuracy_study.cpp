// accuracy_study: what accuracy costs in time and memory (DESIGN.md sec 7, docs/quality.md).
//
// For every scene given and every point of the sweep (bench/accuracy/sweep.h): precompute
// (timed), relight (median of --repeats full relights), and compare the baked irradiance
// against the path-traced reference (core/reference) at the layout's compare points
// (bench/accuracy/reference_set.h): relative RMSE, p95 of the relative error and energy bias
// of indirect and total irradiance at cache centres, the same at midpoints between caches
// (cache interpolation), the reference's own relative standard error, link count and bytes.
//
// Writes OUT/accuracy.csv (one row per point, every column; rewritten after each point, so a
// run cut short keeps what it measured) and OUT/accuracy.json (machine, options, per-scene
// rows, Pareto fronts of indirect RMSE vs relight and vs precompute time, the error budget of
// the base point, and the presets the front suggests under the rule of docs/quality.md).
// bench/accuracy/plot_pareto.py draws the plots from the CSV; bench/accuracy/run.sh does all.
//
// Usage:
//   accuracy_study --out DIR --scene A.gltf [--lights A.json] [--name N] [--scene-sweep S]
//                  [--resolution-scale K] [--scene B.glb ...]
//                  [--sweep full|reduced|presets|base|diagnose] [--others ...]
//                  [--centres N] [--midpoints N] [--repeats N] [--ref-cache DIR]
//                  [--ref-budget S] [--threads N]
// The first scene gets --sweep (default full), the others --others (default: same); options
// after a --scene apply to it: its light-set file, CSV name, own sweep, atlas scale factor.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <tbb/info.h>

#include "bench/accuracy/reference_set.h"
#include "bench/accuracy/rows.h"
#include "bench/accuracy/sweep.h"
#include "bench/rt/throughput.h"
#include "core/common/memory.h"
#include "core/precompute/precompute.h"
#include "core/reference/compare.h"
#include "core/relight/direct_layer.h"
#include "core/relight/relight.h"
#include "core/scene/load.h"
#include "core/sh/sh.h"

namespace {

using namespace lightlink;
using Clock = std::chrono::steady_clock;
using bench::SweepSize;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct SceneArg {
  std::string path, lights;
  std::string name;                // CSV name; default the file's stem
  std::optional<SweepSize> sweep;  // default: --sweep for the first scene, --others after
  int resolution_scale = 1;        // multiplies every point's atlas resolution (zdm2 needs 4)
};

struct Args {
  std::string out;
  std::vector<SceneArg> scenes;
  SweepSize sweep = SweepSize::kFull;
  std::optional<SweepSize> others;
  bench::ReferenceSetOptions ref;
  int repeats = 5;
  int threads = 0;
};

std::optional<SweepSize> parseSweep(const std::string& s) {
  if (s == "full") return SweepSize::kFull;
  if (s == "reduced") return SweepSize::kReduced;
  if (s == "presets") return SweepSize::kPresets;
  if (s == "base") return SweepSize::kBase;
  if (s == "diagnose") return SweepSize::kDiagnose;
  return std::nullopt;
}

Status parse(int argc, char** argv, Args& a) {
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (i + 1 >= argc) return invalidInput("{} needs a value", k);
    const std::string v = argv[++i];
    try {
      if (k == "--out") a.out = v;
      else if (k == "--scene") a.scenes.push_back({v, ""});
      else if (k == "--lights") {
        if (a.scenes.empty()) return invalidInput("--lights {} must follow the --scene it applies to", v);
        a.scenes.back().lights = v;
      } else if (k == "--name" || k == "--scene-sweep" || k == "--resolution-scale") {
        if (a.scenes.empty()) return invalidInput("{} {} must follow the --scene it applies to", k, v);
        SceneArg& sa = a.scenes.back();
        if (k == "--name") sa.name = v;
        else if (k == "--resolution-scale") {
          sa.resolution_scale = std::stoi(v);
          if (sa.resolution_scale < 1 || sa.resolution_scale > 64)
            return invalidInput("--resolution-scale {} is out of range (1..64)", v);
        } else {
          sa.sweep = parseSweep(v);
          if (!sa.sweep) return invalidInput("--scene-sweep '{}' must be full, reduced, presets, base or diagnose", v);
        }
      } else if (k == "--sweep" || k == "--others") {
        auto s = parseSweep(v);
        if (!s) return invalidInput("{} '{}' must be full, reduced, presets, base or diagnose", k, v);
        (k == "--sweep" ? a.sweep : a.others.emplace()) = *s;
      } else if (k == "--centres") a.ref.centres = std::stoi(v);
      else if (k == "--midpoints") a.ref.midpoints = std::stoi(v);
      else if (k == "--repeats") a.repeats = std::stoi(v);
      else if (k == "--ref-cache") a.ref.cache_dir = v;
      else if (k == "--ref-budget") a.ref.time_budget_s = std::stod(v);
      else if (k == "--threads") a.threads = std::stoi(v);
      else return invalidInput("unknown option {}", k);
    } catch (const std::exception&) {
      return invalidInput("{} '{}' is not a number", k, v);
    }
  }
  if (a.out.empty()) return invalidInput("--out DIR is required");
  if (a.scenes.empty()) return invalidInput("at least one --scene is required");
  if (a.ref.centres < 1 || a.ref.centres > 100000) return invalidInput("--centres {} is out of range (1..100000)", a.ref.centres);
  if (a.ref.midpoints < 0 || a.ref.midpoints > 100000)
    return invalidInput("--midpoints {} is out of range (0..100000)", a.ref.midpoints);
  if (a.repeats < 1 || a.repeats > 1000) return invalidInput("--repeats {} is out of range (1..1000)", a.repeats);
  if (a.ref.cache_dir.empty()) a.ref.cache_dir = (std::filesystem::path(a.out) / "reference_cache").string();
  return {};
}

std::string readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

using bench::Row;
using bench::formName;
using bench::netRmse;
using bench::csvHeader;

// Marks the points no other point beats in both indirect RMSE and cost.
template <typename Cost, typename Flag>
void markPareto(std::vector<Row*> rows, Cost cost, Flag flag) {
  // Diagnostic rows (compared with a truncated reference) are no candidates.
  std::erase_if(rows, [](const Row* r) { return !r->error.empty() || r->reference_bounces >= 0; });
  std::sort(rows.begin(), rows.end(), [&](const Row* a, const Row* b) {
    return cost(*a) != cost(*b) ? cost(*a) < cost(*b) : a->indirect.rel_rmse < b->indirect.rel_rmse;
  });
  double best = INFINITY;
  for (Row* r : rows)
    if (r->indirect.rel_rmse < best) {
      best = r->indirect.rel_rmse;
      flag(*r) = true;
    }
}

struct Bake {
  std::vector<glm::vec3> total, indirect;
};

// The baked irradiance at the compare points: a centre reads its cache's texel, a midpoint
// the average of its two texels (bilinear halfway between texel centres), at its own normal.
Bake bakedAt(const relight::RelightResult& res, const precompute::Precomputation& p,
             const std::vector<bench::ComparePoint>& points) {
  Bake b;
  const int nc = res.coeffCount();
  std::vector<float> sh(3 * nc);
  std::vector<glm::vec3> direct;  // at the caches' texels (a finer direct layer box-filtered)
  relight::directAtLightmapSize(res, direct);
  for (const auto& pt : points) {
    const std::uint32_t ta = p.lightmap.texel[pt.cache_a], tb = p.lightmap.texel[pt.cache_b];
    const float* a = res.lightmap_sh.data() + std::size_t(ta) * 3 * nc;
    const float* c = res.lightmap_sh.data() + std::size_t(tb) * 3 * nc;
    for (int k = 0; k < 3 * nc; ++k) sh[k] = 0.5f * (a[k] + c[k]);
    const glm::vec3 ind(sh::irradiance(res.bands, sh.data(), pt.normal),
                        sh::irradiance(res.bands, sh.data() + nc, pt.normal),
                        sh::irradiance(res.bands, sh.data() + 2 * nc, pt.normal));
    b.indirect.push_back(ind);
    b.total.push_back(ind + 0.5f * (direct[ta] + direct[tb]));
  }
  return b;
}

// Root mean square of the reference's relative standard error over points above the floor.
double referenceNoise(const std::vector<reference::IrradianceEstimate>& est, bool indirect) {
  double mean = 0.0;
  for (const auto& e : est) mean += reference::luminance(indirect ? e.indirect : e.total);
  mean /= std::max<std::size_t>(1, est.size());
  double sq = 0.0;
  std::size_t n = 0;
  for (const auto& e : est) {
    const double v = reference::luminance(indirect ? e.indirect : e.total);
    if (!(v > 1e-3 * mean)) continue;
    const double se = reference::luminance(indirect ? e.std_error_indirect : e.std_error_total);
    sq += (se / v) * (se / v);
    ++n;
  }
  return n ? std::sqrt(sq / double(n)) : 0.0;
}

class Study {
 public:
  explicit Study(Args args) : args_(std::move(args)) {}

  int run() {
    std::error_code ec;
    std::filesystem::create_directories(args_.out, ec);
    if (ec) return fail(ioError("cannot create --out {}: {}", args_.out, ec.message()));
    json_["machine"] = {{"cpu", bench::cpuModel()}, {"threads", tbb::info::default_concurrency()}};
    json_["reference"] = {{"target_rel_error_total", args_.ref.target_rel_error},
                          {"target_rel_error_indirect", args_.ref.indirect_target},
                          {"centres", args_.ref.centres},
                          {"midpoints", args_.ref.midpoints}};
    json_["relight_repeats"] = args_.repeats;
    const auto t0 = Clock::now();
    for (std::size_t s = 0; s < args_.scenes.size(); ++s) {
      const SweepSize size = args_.scenes[s].sweep.value_or(s == 0 ? args_.sweep : args_.others.value_or(args_.sweep));
      auto points = bench::studyPoints(size);
      for (auto& p : points) p.pre.target_resolution *= args_.scenes[s].resolution_scale;
      runScene(args_.scenes[s], std::move(points));
    }
    json_["seconds"] = secondsSince(t0);
    finish();
    fmt::print("wrote {}/accuracy.csv and accuracy.json ({:.0f} s)\n", args_.out, secondsSince(t0));
    return 0;
  }

 private:
  int fail(const Status& s) {
    std::fprintf(stderr, "accuracy_study: %s\n", s.toString().c_str());
    return 2;
  }

  void runScene(const SceneArg& sa, std::vector<bench::StudyPoint> points) {
    const std::string name = sa.name.empty() ? std::filesystem::path(sa.path).stem().string() : sa.name;
    fmt::print("== scene {} ({} points){}\n", sa.path, points.size(), sa.lights.empty() ? "" : " lights " + sa.lights);
    std::fflush(stdout);
    const std::string scene_bytes = readFile(sa.path), light_bytes = sa.lights.empty() ? "" : readFile(sa.lights);
    nlohmann::ordered_json& js = json_["scenes"][name];
    js["path"] = sa.path;
    js["lights"] = sa.lights;
    // Points that share a precomputation run back to back on one Relighter.
    std::vector<std::string> order;
    std::map<std::string, std::vector<bench::StudyPoint>> groups;
    for (auto& p : points) {
      const std::string key = p.pre.canonical();
      if (!groups.count(key)) order.push_back(key);
      groups[key].push_back(p);
    }
    for (const auto& key : order) runGroup(name, sa, scene_bytes + "|" + light_bytes, groups[key], js);
  }

  void runGroup(const std::string& name, const SceneArg& sa, const std::string& input_bytes,
                const std::vector<bench::StudyPoint>& group, nlohmann::ordered_json& js) {
    auto failAll = [&](const Status& s) {
      for (const auto& pt : group) {
        Row r{.scene = name, .factor = pt.factor, .value = pt.value, .error = s.toString(), .pre = pt.pre, .rel = pt.rel};
        std::replace(r.error.begin(), r.error.end(), ',', ';');
        fmt::print("  {:<8} {:<10} FAILED: {}\n", pt.factor, pt.value, r.error);
        rows_.push_back(r);
      }
      writeCsv();
    };
    auto scene = scene::loadScene(sa.path);
    if (!scene) return failAll(scene.status());
    auto lights = relight::LightSet::fromSceneLights(scene->lights);
    if (!sa.lights.empty())
      if (Status s = lights.applyFile(sa.lights); !s) return failAll(s);
    const precompute::PrecomputeOptions& pre = group.front().pre;
    const auto t0 = Clock::now();
    auto p = precompute::run(*scene, pre);
    const double precompute_s = secondsSince(t0);
    if (!p) return failAll(p.status());
    auto accel = rt::Accel::build(*scene);
    if (!accel) return failAll(accel.status());

    // The layout: whatever places the lightmap caches.
    const std::string layout = fmt::format(
        "{}|layout:texel={},res={},target={},validity={}", input_bytes,
        pre.texel_size_m ? fmt::format("{:a}", *pre.texel_size_m) : "auto",
        pre.lightmap_resolution ? std::to_string(*pre.lightmap_resolution) : "auto", pre.target_resolution,
        pre.validity_rays);
    // Compare points and reference per reference bounce cap (-1: all), computed on first use.
    struct Truth {
      std::vector<bench::ComparePoint> pts_c, pts_m;
      std::vector<reference::IrradianceEstimate> ref_c, ref_m;
    };
    std::map<int, Truth> truths;
    auto truthFor = [&](int ref_bounces) -> Expected<const Truth*> {
      if (auto it = truths.find(ref_bounces); it != truths.end()) return &it->second;
      bench::ReferenceSetOptions ro = args_.ref;
      if (ref_bounces >= 0) ro.max_bounces = ref_bounces;
      auto ref = bench::referenceFor(*scene, *accel, lights, bench::selectPoints(*p, ro.centres, ro.midpoints),
                                     layout, ro);
      if (!ref) return ref.status();
      if (!ref->from_disk) {
        fmt::print("  reference: {} points ({} atlas{}) in {:.1f} s -> {}\n", ref->points.size(), p->atlas.resolution,
                   ref_bounces >= 0 ? fmt::format(", {} bounce", ref_bounces) : "", ref->seconds, ref->file);
        js["reference_seconds"][fmt::format("{}_b{}", p->atlas.resolution, ref_bounces)] = ref->seconds;
      }
      Truth& t = truths[ref_bounces];
      for (std::size_t i = 0; i < ref->points.size(); ++i) {
        (ref->points[i].midpoint() ? t.pts_m : t.pts_c).push_back(ref->points[i]);
        (ref->points[i].midpoint() ? t.ref_m : t.ref_c).push_back(ref->estimates[i]);
      }
      return &t;
    };
    auto relighter = relight::Relighter::create(*scene, *accel, *p);
    if (!relighter) return failAll(relighter.status());
    const auto report = p->report();
    const auto& mem = report["memory_bytes"];

    for (const auto& pt : group) {
      Row r{.scene = name, .factor = pt.factor, .value = pt.value, .pre = pt.pre, .rel = pt.rel};
      r.reference_bounces = pt.reference_bounces;
      auto truth = truthFor(pt.reference_bounces);
      if (!truth) {
        r.error = truth.status().toString();
        std::replace(r.error.begin(), r.error.end(), ',', ';');
        rows_.push_back(r);
        continue;
      }
      const auto& [pts_c, pts_m, ref_c, ref_m] = **truth;
      r.lightmap_resolution = p->atlas.resolution;
      r.texel_size_m = p->atlas.texel_size_m;
      r.caches_valid = p->lightmap.validCount();
      r.links = p->lightmap_links.linkCount() + p->grid_links.linkCount();
      r.links_per_cache = p->lightmap_links.cacheCount()
                              ? double(p->lightmap_links.linkCount()) / double(p->lightmap_links.cacheCount())
                              : 0.0;
      r.precompute_s = precompute_s;
      r.links_s = report["seconds"].value("links", 0.0);
      const bool projected = pt.rel.link_form == relight::LinkForm::kProjected;
      r.link_bytes = projected ? mem["lightmap_links_projected"].get<std::size_t>() +
                                     mem["grid_links_projected"].get<std::size_t>()
                               : mem["lightmap_links_runtime"].get<std::size_t>() +
                                     mem["grid_links_runtime"].get<std::size_t>();
      r.memory_bytes = r.link_bytes + mem["surfels"].get<std::size_t>() + mem["tree"].get<std::size_t>() +
                       mem["sky_visibility"].get<std::size_t>();
      relight::RelightResult res;
      std::vector<double> times;
      Status status;
      for (int k = 0; k <= args_.repeats && status; ++k) {
        relighter->invalidate();
        const auto tr = Clock::now();
        status = relighter->relightInto(lights, pt.rel, res);
        if (k > 0) times.push_back(secondsSince(tr));  // the first one warms caches
      }
      if (!status) {
        r.error = status.toString();
        std::replace(r.error.begin(), r.error.end(), ',', ';');
        rows_.push_back(r);
        continue;
      }
      std::sort(times.begin(), times.end());
      r.relight_ms = 1e3 * times[times.size() / 2];
      r.bounces_run = int(res.bounce_log.size());
      r.bounce_stop = res.bounce_stop;
      r.sky = lights.sky().emits();
      const Bake bc = bakedAt(res, *p, pts_c), bm = bakedAt(res, *p, pts_m);
      std::vector<glm::vec3> rt, ri;
      for (const auto& e : ref_c) rt.push_back(e.total), ri.push_back(e.indirect);
      r.total = reference::errorStats(bc.total, rt);
      r.indirect = reference::errorStats(bc.indirect, ri);
      // The same with the energy bias divided out: what is left is the error of the shape.
      if (r.indirect.bias > 0.0 && std::isfinite(r.indirect.bias)) {
        std::vector<glm::vec3> scaled = bc.indirect;
        for (auto& v : scaled) v /= float(r.indirect.bias);
        r.indirect_rmse_debiased = reference::errorStats(scaled, ri).rel_rmse;
      }
      rt.clear(), ri.clear();
      for (const auto& e : ref_m) rt.push_back(e.total), ri.push_back(e.indirect);
      r.mid_total = reference::errorStats(bm.total, rt);
      r.mid_indirect = reference::errorStats(bm.indirect, ri);
      r.ref_points = pts_c.size();
      r.mid_points = pts_m.size();
      r.ref_noise_total = referenceNoise(ref_c, false);
      r.ref_noise_indirect = referenceNoise(ref_c, true);
      fmt::print("  {:<8} {:<10} ind RMSE {:6.2f} % (net {:5.2f}) p95 {:6.2f} % bias {:.3f} | total {:6.2f} % | "
                 "debiased {:5.2f} % | mid ind {:6.2f} % | pre {:6.2f} s relight {:7.2f} ms links {:.1f} MB | ref noise ind {:.2f} %\n",
                 pt.factor, pt.value, 100 * r.indirect.rel_rmse, 100 * netRmse(r.indirect.rel_rmse, r.ref_noise_indirect),
                 100 * r.indirect.p95_rel_error, r.indirect.bias, 100 * r.total.rel_rmse,
                 100 * r.indirect_rmse_debiased, 100 * r.mid_indirect.rel_rmse, r.precompute_s, r.relight_ms, r.link_bytes / 1e6,
                 100 * r.ref_noise_indirect);
      std::fflush(stdout);
      rows_.push_back(r);
      writeCsv();
    }
  }

  void writeCsv() const {
    const std::string path = (std::filesystem::path(args_.out) / "accuracy.csv").string();
    std::ofstream f(path + ".tmp");
    f << csvHeader();
    for (const auto& r : rows_) f << csvRow(r);
    f.close();
    std::error_code ec;
    std::filesystem::rename(path + ".tmp", path, ec);
  }

  // Pareto flags, the base point's error budget and the suggested presets, per scene.
  void finish() {
    std::map<std::string, std::vector<Row*>> by_scene;
    for (auto& r : rows_) by_scene[r.scene].push_back(&r);
    for (auto& [name, rows] : by_scene) {
      markPareto(rows, [](const Row& r) { return r.relight_ms; }, [](Row& r) -> bool& { return r.pareto_relight; });
      markPareto(rows, [](const Row& r) { return r.precompute_s; }, [](Row& r) -> bool& { return r.pareto_precompute; });
      nlohmann::ordered_json& js = json_["scenes"][name];
      js["rows"] = nlohmann::ordered_json::array();
      for (const Row* r : rows) js["rows"].push_back(rowJson(*r));
      const Row* base = nullptr;
      for (const Row* r : rows)
        if (r->factor == "base" && r->error.empty()) base = r;
      if (!base) continue;
      // Error budget: how much of the base point's indirect error each factor can remove at
      // the best value swept (negative: no value beats the base). Cache interpolation: the
      // extra error at midpoints.
      nlohmann::ordered_json budget;
      budget["base_indirect_rmse"] = base->indirect.rel_rmse;
      budget["reference_noise_indirect"] = base->ref_noise_indirect;
      budget["cache_interpolation_extra"] = base->mid_indirect.rel_rmse - base->indirect.rel_rmse;
      for (const char* f : {"surfels", "links", "bands", "rays", "builder", "density", "form"}) {
        const Row* best = nullptr;
        for (const Row* r : rows)
          if (r->factor == f && r->error.empty() && (!best || r->indirect.rel_rmse < best->indirect.rel_rmse)) best = r;
        if (best)
          budget["removable_by"][f] = {{"best_value", best->value},
                                       {"indirect_rmse", best->indirect.rel_rmse},
                                       {"reduction", base->indirect.rel_rmse - best->indirect.rel_rmse}};
      }
      js["error_budget"] = budget;
      // Preset rule (docs/quality.md). Candidates: projected links, bounces to convergence,
      // compared with the full reference; errors are indirect RMSE with the reference's noise
      // taken out; relight times within 10 % count as equal (timing noise).
      std::vector<const Row*> cand;
      for (const Row* r : rows)
        if (r->error.empty() && r->reference_bounces < 0 && r->factor != "bounces" &&
            r->rel.link_form == relight::LinkForm::kProjected &&
            r->rel.max_bounces == bench::baseRelightOptions().max_bounces)
          cand.push_back(r);
      auto err = [](const Row* r) { return netRmse(r->indirect.rel_rmse, r->ref_noise_indirect); };
      auto best = [&](auto&& ok, auto&& better) {
        const Row* pick = nullptr;
        for (const Row* r : cand)
          if (ok(r) && (!pick || better(r, pick))) pick = r;
        return pick;
      };
      // medium: the reference workload, unless a point is more accurate at no more relight
      // time and memory, here and on every other scene where both were measured.
      auto beatsBaseEverywhere = [&](const Row* r) {
        for (const auto& [other, orows] : by_scene) {
          const Row *ob = nullptr, *orow = nullptr;
          for (const Row* x : orows) {
            if (!x->error.empty() || x->reference_bounces >= 0) continue;
            if (x->factor == "base") ob = x;
            if (x->factor == r->factor && x->value == r->value) orow = x;
          }
          if (ob && orow && err(orow) > err(ob)) return false;
        }
        return true;
      };
      const Row* medium = best([&](const Row* r) {
        return r == base || (err(r) < err(base) && r->relight_ms <= 1.1 * base->relight_ms &&
                             r->memory_bytes <= base->memory_bytes && beatsBaseEverywhere(r));
      }, [&](const Row* a, const Row* b) { return err(a) < err(b); });
      // draft: the fastest relight within 1.5x medium's error (then the fastest precompute).
      const Row* draft = best([&](const Row* r) { return err(r) <= 1.5 * err(medium); },
                              [&](const Row* a, const Row* b) {
                                return a->relight_ms < 0.9 * b->relight_ms ||
                                       (a->relight_ms <= 1.1 * b->relight_ms && a->precompute_s < b->precompute_s);
                              });
      // high: within 2x medium's relight time and 4x its memory, the lowest error relative to
      // the base, averaged over the scenes whose reference is trustworthy (indirect noise
      // <= 2 %) and that measured the same point: one small box alone would pick its quirks.
      auto score = [&](const Row* r) {
        double sum = 0.0;
        int n = 0;
        for (const auto& [other, orows] : by_scene) {
          const Row *ob = nullptr, *orow = nullptr;
          for (const Row* x : orows) {
            if (!x->error.empty() || x->reference_bounces >= 0) continue;
            if (x->factor == "base") ob = x;
            if (x->factor == r->factor && x->value == r->value) orow = x;
          }
          if (ob && orow && ob->ref_noise_indirect <= 0.02 && err(ob) > 0.0) sum += err(orow) / err(ob), ++n;
        }
        return n ? sum / n : err(r) / std::max(err(base), 1e-9);
      };
      const Row* high = best([&](const Row* r) {
        return r->relight_ms <= 2.0 * medium->relight_ms && r->memory_bytes <= 4 * medium->memory_bytes;
      }, [&](const Row* a, const Row* b) { return score(a) < score(b); });
      nlohmann::ordered_json suggested;
      for (const auto& [preset, r, target] :
           {std::tuple{"draft", draft, 0.0}, std::tuple{"medium", medium, 0.10}, std::tuple{"high", high, 0.05}}) {
        suggested[preset] = {{"factor", r->factor}, {"value", r->value}, {"options", r->pre.canonical()},
                             {"indirect_rmse_net", err(r)}, {"indirect_p95", r->indirect.p95_rel_error},
                             {"total_rmse", r->total.rel_rmse}, {"relight_ms", r->relight_ms},
                             {"precompute_s", r->precompute_s}, {"memory_bytes", r->memory_bytes},
                             {"error_vs_base_over_scenes", score(r)}};
        if (target > 0.0) suggested[preset]["target"] = target, suggested[preset]["met"] = err(r) <= target;
      }
      js["suggested_presets"] = suggested;
    }
    writeCsv();
    std::ofstream((std::filesystem::path(args_.out) / "accuracy.json").string()) << json_.dump(2) << "\n";
  }

  Args args_;
  std::vector<Row> rows_;
  nlohmann::ordered_json json_;
};

}  // namespace

int main(int argc, char** argv) {
  Args args;
  if (Status s = parse(argc, argv, args); !s) {
    std::fprintf(stderr,
                 "accuracy_study: %s\nusage: accuracy_study --out DIR --scene A.gltf [--lights A.json] [--scene ...] "
                 "[--name N] [--scene-sweep S] [--resolution-scale K] [--sweep full|reduced|presets|base|diagnose] "
                 "[--others ...] [--centres N] [--midpoints N] [--repeats N] "
                 "[--ref-cache DIR] [--ref-budget S] [--threads N]\n",
                 s.toString().c_str());
    return 1;
  }
  std::unique_ptr<tbb::global_control> threads;
  if (args.threads > 0)
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, args.threads);
  // Its precomputes reuse each other's freed link blocks (core/common/memory.h).
  const HugeBlockCacheScope huge_blocks;
  return Study(std::move(args)).run();
}
