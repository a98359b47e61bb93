// `lightlink compare`: bake a scene and measure its lightmap against the path-traced
// reference at the exact cache positions and normals (DESIGN.md sec 7, docs/quality.md):
// relative RMSE (black references included, through an absolute error floor), 95th percentile
// of the relative error, energy bias and leak counts, for total and indirect irradiance, over
// all points and separately over the near-contact band; error and leak heat maps.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>

#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"
#include "clients/lightlink/scene_access.h"
#include "clients/lightlink/progress_bar.h"
#include "core/bake/bake_options.h"
#include "core/common/png.h"
#include "core/output/output.h"
#include "core/precompute/precompute.h"
#include "core/reference/compare.h"
#include "core/reference/contact_band.h"
#include "core/reference/reference.h"
#include "core/relight/direct_layer.h"
#include "core/relight/relight.h"
#include "core/scene/load.h"

namespace lightlink::cli {
namespace {

constexpr float kBandTexels = 2.0f;  // the near-contact band's half-width

// Relative error 0 -> dark blue, 10 % -> green, >= 25 % -> red; texels not compared grey.
Status writeHeatMap(const std::string& path, int w, int h, const std::vector<std::uint32_t>& texels,
                    const std::vector<float>& rel_error) {
  std::vector<std::uint8_t> rgb(std::size_t(w) * h * 3, 40);
  for (std::size_t k = 0; k < texels.size(); ++k) {
    const float e = std::clamp(rel_error[k] / 0.25f, 0.0f, 1.0f);
    const glm::vec3 c = e < 0.4f ? glm::mix(glm::vec3(0.05f, 0.05f, 0.5f), glm::vec3(0.1f, 0.8f, 0.1f), e / 0.4f)
                                 : glm::mix(glm::vec3(0.1f, 0.8f, 0.1f), glm::vec3(0.9f, 0.1f, 0.05f), (e - 0.4f) / 0.6f);
    for (int ch = 0; ch < 3; ++ch) rgb[3 * std::size_t(texels[k]) + ch] = encodeSrgb8(c[ch]);
  }
  return writePngRgb8(path, w, h, rgb, "error heat map");
}

// Leaks red, missing light blue, other near-contact points dull yellow, other compared points
// grey; texels not compared dark.
Status writeLeakMap(const std::string& path, int w, int h, const std::vector<std::uint32_t>& texels,
                    const std::vector<glm::vec3>& baked, const std::vector<glm::vec3>& ref,
                    const std::vector<std::uint8_t>& band, const reference::ErrorStats& stats,
                    const reference::ErrorOptions& options) {
  std::vector<std::uint8_t> rgb(std::size_t(w) * h * 3, 20);
  const double dark = options.dark_fraction * stats.floor;
  for (std::size_t k = 0; k < texels.size(); ++k) {
    const double b = reference::luminance(baked[k]), r = reference::luminance(ref[k]);
    std::array<std::uint8_t, 3> c = band[k] ? std::array<std::uint8_t, 3>{130, 120, 40} : std::array<std::uint8_t, 3>{90, 90, 90};
    if (r < dark && b > stats.floor) c = {255, 30, 20};
    if (b < dark && r > stats.floor) c = {30, 80, 255};
    for (int ch = 0; ch < 3; ++ch) rgb[3 * std::size_t(texels[k]) + ch] = c[ch];
  }
  return writePngRgb8(path, w, h, rgb, "leak map");
}

std::vector<glm::vec3> pick(const std::vector<glm::vec3>& v, const std::vector<std::uint8_t>& mask, bool want) {
  std::vector<glm::vec3> out;
  for (std::size_t k = 0; k < v.size(); ++k)
    if (bool(mask[k]) == want) out.push_back(v[k]);
  return out;
}

}  // namespace

// compare.json's "worst_points": how many.
constexpr std::size_t kWorstPoints = 10;

int runCompare(const CompareArgs& args) {
  constexpr const char* kCmd = "compare";
  if (args.against != "reference")
    return reportError(kCmd, invalidInput("--against '{}': only 'reference' is known", args.against));
  if (args.max_points < 1 || args.max_points > (1 << 22))
    return reportError(kCmd, invalidInput("--max-points {} is out of range (1..4194304)", args.max_points));
  if (!(args.error_floor > 0.0 && args.error_floor <= 10.0))
    return reportError(kCmd, invalidInput("--error-floor {} is out of range (0..10]", args.error_floor));
  // compare's own choice: the baker runs to convergence (64 bounces, threshold 1e-4) unless
  // --bounces says otherwise, so that the error measured is the method's, not the cap's.
  relight::RelightOptions to_convergence;
  to_convergence.max_bounces = 64;
  to_convergence.bounce_threshold = 1e-4f;
  auto bake_options = bake::buildBakeOptions(args.options, "medium", to_convergence);
  if (!bake_options) return reportError(kCmd, bake_options.status());
  scene::LoadOptions load;
  load.files = sceneFileAccess(args.allow_outside_scene);
  auto scene = scene::loadScene(args.scene_path, load);
  if (!scene) return reportError(kCmd, scene.status());
  scene::applySurfaceRules(*scene, bake_options->precompute.surfaces);
  auto lights = relight::LightSet::fromSceneLights(scene->lights);
  if (!args.lights_path.empty())
    if (Status s = lights.applyFile(args.lights_path); !s) return reportError(kCmd, s);
  reference::ReferenceOptions ref_options;
  ref_options.target_rel_error = args.target_error;
  ref_options.time_budget_s = args.time_budget_s;
  if (Status s = reference::ReferenceRenderer::validate(ref_options); !s) return reportError(kCmd, s);

  ProgressBar bar(!args.quiet);
  auto p = precompute::run(*scene, bake_options->precompute, &bar);
  if (!p) return reportError(kCmd, p.status());
  auto accel = rt::Accel::build(*scene);  // static geometry only: what the baker sees
  if (!accel) return reportError(kCmd, accel.status());
  auto relighter = relight::Relighter::create(*scene, *accel, *p);
  if (!relighter) return reportError(kCmd, relighter.status());
  const relight::RelightOptions ro = bake_options->relight;
  bar.begin("relight", 0);
  auto baked = relighter->relight(lights, ro);
  bar.end();
  if (!baked) return reportError(kCmd, baked.status());

  // Evenly strided valid lightmap caches.
  const auto& lm = p->lightmap;
  std::vector<std::uint32_t> valid;
  for (std::uint32_t c = 0; c < lm.size(); ++c)
    if (lm.valid[c]) valid.push_back(c);
  const std::size_t stride = std::max<std::size_t>(1, (valid.size() + args.max_points - 1) / args.max_points);
  std::vector<glm::vec3> pos, nrm;
  std::vector<std::uint32_t> texels;
  std::vector<float> band_radius;
  std::vector<std::uint8_t> pushed;
  for (std::size_t k = 0; k < valid.size(); k += stride) {
    const std::uint32_t c = valid[k];
    pos.push_back(lm.position[c]);
    nrm.push_back(lm.normal[c]);
    texels.push_back(lm.texel[c]);
    band_radius.push_back(kBandTexels * reference::texelSizeOnTriangle(scene->meshes[lm.mesh[c]], lm.triangle[c],
                                                                       lm.width, lm.height));
    pushed.push_back(lm.pushed[c]);
  }
  if (pos.empty()) return reportError(kCmd, invalidInput("{}: no valid lightmap cache to compare", args.scene_path));
  // The near-contact band: another surface within two texels, or a cache the validity test
  // moved (its texel's own point saw the back of something, so it lies at a contact).
  std::vector<std::uint8_t> band = reference::nearContact(*accel, pos, nrm, band_radius);
  for (std::size_t k = 0; k < band.size(); ++k) band[k] |= pushed[k];

  auto ref = reference::ReferenceRenderer::create(*scene, *accel, lights);
  if (!ref) return reportError(kCmd, ref.status());
  auto est = ref->irradiance({pos, nrm}, ref_options, &bar);  // reports its own progress
  if (!est) return reportError(kCmd, est.status());

  // The direct light at the caches' texels (a finer direct layer box-filtered to them).
  std::vector<glm::vec3> direct;
  relight::directAtLightmapSize(*baked, direct);
  std::vector<glm::vec3> b_total, b_ind, r_total, r_ind;
  double ref_rel_err = 0.0;
  std::size_t converged = 0;
  for (std::size_t k = 0; k < pos.size(); ++k) {
    const glm::vec3 ind = baked->lightmapIndirect(texels[k], nrm[k]);
    b_ind.push_back(ind);
    b_total.push_back(ind + direct[texels[k]]);
    const auto& e = (*est)[k];
    r_total.push_back(e.total);
    r_ind.push_back(e.indirect);
    const float lt = reference::luminance(e.total);
    if (lt > 0.0f) ref_rel_err += reference::luminance(e.std_error_total) / lt;
    converged += e.converged ? 1 : 0;
  }
  ref_rel_err /= double(pos.size());
  reference::ErrorOptions eo;
  eo.floor_fraction = args.error_floor;
  const auto total = reference::errorStats(b_total, r_total, eo);
  // One floor for every figure: a fraction of the scene's mean total irradiance (the light
  // level an error is seen against), not of the indirect's or a subset's own mean.
  eo.floor_mean = total.mean_reference;
  const auto indirect = reference::errorStats(b_ind, r_ind, eo);
  auto subset = [&](const std::vector<glm::vec3>& b, const std::vector<glm::vec3>& r, bool in_band) {
    return reference::errorStats(pick(b, band, in_band), pick(r, band, in_band), eo);
  };
  const auto band_total = subset(b_total, r_total, true);
  const auto band_ind = subset(b_ind, r_ind, true);
  const auto inner_total = subset(b_total, r_total, false);
  const auto inner_ind = subset(b_ind, r_ind, false);
  const bool sky = lights.sky().emits();

  nlohmann::ordered_json report;
  report["scene"] = args.scene_path;
  report["preset"] = bake_options->preset;
  report["options"] = bake_options->precompute.canonical();  // what bake's report calls precompute.options
  report["points"] = pos.size();
  report["reference"] = {{"target_rel_error", args.target_error},
                         {"mean_rel_std_error_total", ref_rel_err},
                         {"converged_points", converged}};
  report["error_floor"] = {{"fraction_of_mean", args.error_floor},
                           {"formula", "rel_error = |baked - ref| / max(ref, floor), floor = fraction_of_mean * mean(ref total), luminance"},
                           {"floor", total.floor},
                           {"leak", "ref < 0.1 * floor and baked > floor"},
                           {"missing_light", "baked < 0.1 * floor and ref > floor"}};
  report["total"] = total.toJson();
  report["indirect"] = indirect.toJson();
  report["near_contact"] = {{"definition", "another surface within 2 texel sizes of the point, or a cache moved by the "
                                           "validity test"},
                            {"radius_texels", kBandTexels},
                            {"points", band_total.points},
                            {"total", band_total.toJson()},
                            {"indirect", band_ind.toJson()}};
  report["interior"] = {{"points", inner_total.points}, {"total", inner_total.toJson()}, {"indirect", inner_ind.toJson()}};
  report["leaks"] = {{"leaks", total.leaks},
                     {"missing_light", total.missing_light},
                     {"near_contact_leaks", band_total.leaks},
                     {"points", total.points}};
  if (sky)
    report["note"] = "the scene has a sky: the baker's indirect SH holds the sky's direct light, the reference's "
                     "indirect does not, so only 'total' compares like with like";
  // Where to look first: the points with the largest floored total error (a leak, a cache on
  // a contact), in world space, worst first; ties in point order.
  {
    std::vector<std::size_t> order(pos.size());
    std::vector<float> err(pos.size());
    for (std::size_t k = 0; k < pos.size(); ++k) order[k] = k, err[k] = reference::flooredRelError(b_total[k], r_total[k], total.floor);
    const std::size_t shown = std::min<std::size_t>(kWorstPoints, order.size());
    std::partial_sort(order.begin(), order.begin() + shown, order.end(),
                      [&](std::size_t a, std::size_t b) { return err[a] > err[b] || (err[a] == err[b] && a < b); });
    nlohmann::ordered_json worst = nlohmann::ordered_json::array();
    for (std::size_t w = 0; w < shown; ++w) {
      const std::size_t k = order[w];
      worst.push_back({{"position", {pos[k].x, pos[k].y, pos[k].z}},
                       {"normal", {nrm[k].x, nrm[k].y, nrm[k].z}},
                       {"texel", {texels[k] % std::uint32_t(lm.width), texels[k] / std::uint32_t(lm.width)}},
                       {"near_contact", band[k] != 0},
                       {"baked", reference::luminance(b_total[k])},
                       {"reference", reference::luminance(r_total[k])},
                       {"baked_indirect", reference::luminance(b_ind[k])},
                       {"reference_indirect", reference::luminance(r_ind[k])},
                       {"rel_error", err[k]}});
    }
    report["worst_points"] = std::move(worst);
  }
  report["baker"] = baked->report();
  if (!args.output_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(args.output_dir, ec);
    if (ec) return reportError(kCmd, ioError("cannot create {}: {}", args.output_dir, ec.message()));
    const std::filesystem::path out(args.output_dir);
    if (Status s = output::writeReportJson(report, (out / "compare.json").string()); !s) return reportError(kCmd, s);
    for (const auto& [name, b, r] : {std::tuple{"error_total.png", &b_total, &r_total},
                                      std::tuple{"error_indirect.png", &b_ind, &r_ind}}) {
      const double floor = (b == &b_total ? total : indirect).floor;
      std::vector<float> rel(texels.size(), 0.0f);
      for (std::size_t k = 0; k < texels.size(); ++k) rel[k] = reference::flooredRelError((*b)[k], (*r)[k], floor);
      if (Status s = writeHeatMap((out / name).string(), lm.width, lm.height, texels, rel); !s)
        return reportError(kCmd, s);
    }
    if (Status s = writeLeakMap((out / "leaks.png").string(), lm.width, lm.height, texels, b_total, r_total, band,
                                total, eo);
        !s)
      return reportError(kCmd, s);
  }
  if (!args.quiet) {
    std::string text = fmt::format("compared     {} lightmap caches against the reference (its mean rel. error {:.2f} %)\n",
                                   pos.size(), 100.0 * ref_rel_err);
    text += fmt::format("error floor  {:.3g} x mean reference: rel. error = |b - r| / max(r, floor)\n", args.error_floor);
    for (const auto& [what, st] : {std::pair{"total", total}, std::pair{"indirect", indirect}})
      text += fmt::format("{:<12} rel. RMSE {:.2f} %, p95 {:.2f} %, bias {:.4f} (mean baked {:.4g} vs {:.4g}); "
                          "lit points only {:.2f} %\n",
                          what, 100.0 * st.rel_rmse, 100.0 * st.p95_rel_error, st.bias, st.mean_baked,
                          st.mean_reference, 100.0 * st.lit_rel_rmse);
    for (const auto& [what, t, i] : {std::tuple{"contact band", band_total, band_ind},
                                     std::tuple{"interior", inner_total, inner_ind}})
      text += fmt::format("{:<12} {} points: total rel. RMSE {:.2f} %, bias {:.4f}; indirect {:.2f} %, bias {:.4f}\n",
                          what, t.points, 100.0 * t.rel_rmse, t.bias, 100.0 * i.rel_rmse, i.bias);
    text += fmt::format("leaks        {} points lit where the reference is black ({} in the contact band), "
                        "{} black where it is lit\n",
                        total.leaks, band_total.leaks, total.missing_light);
    if (sky) text += "note         sky present: compare 'total' only\n";
    std::fwrite(text.data(), 1, text.size(), stdout);
  }
  return kExitOk;
}

}  // namespace lightlink::cli
