#include "clients/lightlink/bake_findings.h"

#include <fmt/format.h>

#include "clients/lightlink/exit_codes.h"

namespace lightlink::cli {
namespace {

void appendStrings(const nlohmann::ordered_json& j, const char* key, std::vector<std::string>& out) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_array()) return;
  for (const auto& v : *it)
    if (v.is_string()) out.push_back(v.get<std::string>());
}

}  // namespace

bool lightmapAllBlack(const relight::RelightResult& result) {
  for (const glm::vec3& d : result.direct)
    if (d.x > 0.0f || d.y > 0.0f || d.z > 0.0f) return false;
  const std::size_t nc = static_cast<std::size_t>(result.coeffCount());
  const std::size_t stride = 3 * nc;
  if (nc == 0) return true;
  for (std::size_t t = 0; t + stride <= result.lightmap_sh.size(); t += stride)
    for (std::size_t c = 0; c < 3; ++c)
      if (result.lightmap_sh[t + c * nc] > 0.0f) return false;  // DC term of channel c
  return true;
}

BakeFindings collectFindings(const scene::Scene& scene, const nlohmann::ordered_json& precompute_report,
                             const relight::RelightResult& result) {
  BakeFindings f;
  f.warnings = scene.warnings;
  appendStrings(precompute_report, "warnings", f.warnings);
  appendStrings(precompute_report, "notes", f.notes);
  f.warnings.insert(f.warnings.end(), result.warnings.begin(), result.warnings.end());
  const std::string& file = scene.source_path;
  f.no_light = !(result.plan.punctual || result.plan.emissive || result.plan.sky);
  if (f.no_light) {
    f.warnings.push_back(fmt::format("{}: scene: no light: it has no glTF light, no emissive material and no "
                                     "sky, and no light-set file (--lights) adds one; every output is black",
                                     file));
  } else if (lightmapAllBlack(result)) {
    f.all_black = true;
    f.warnings.push_back(fmt::format("{}: lightmap: every texel is black: no light reaches a static surface "
                                     "(lights outside the geometry, zero range, or only realtime lights with "
                                     "bounces off)", file));
  }
  return f;
}

Expected<FailOn> parseFailOn(const std::string& text) {
  if (text == "never") return FailOn::kNever;
  if (text == "dark") return FailOn::kDark;
  if (text == "warning") return FailOn::kWarning;
  return invalidInput("--fail-on '{}' must be 'never', 'dark' or 'warning'", text);
}

int bakeExitCode(const BakeFindings& findings, FailOn fail_on) {
  if (fail_on == FailOn::kNever) return kExitOk;
  if (findings.dark()) return kExitDark;
  if (fail_on == FailOn::kWarning && !findings.warnings.empty()) return kExitWarnings;
  return kExitOk;
}

void printWarnings(const BakeFindings& findings, std::FILE* out, std::size_t limit) {
  std::string text;
  const std::size_t n = findings.warnings.size();
  for (std::size_t i = 0; i < n && i < limit; ++i) text += fmt::format("lightlink bake: warning: {}\n", findings.warnings[i]);
  if (n > limit) text += fmt::format("lightlink bake: ... and {} more warnings (report.json lists all {})\n", n - limit, n);
  std::fwrite(text.data(), 1, text.size(), out);
}

}  // namespace lightlink::cli
