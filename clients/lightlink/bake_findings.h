// What a bake has to tell its user besides its outputs: every warning of ingest (missing or
// undecodable images, dropped triangles, ...), of the precompute (its notes and any
// warnings) and of the relight, each naming its object; and whether the bake was lit at all
// (no light of any kind, or a lightmap with no lit texel). `lightlink bake` prints the
// warnings on stderr, lists them in report.json and, under --fail-on, turns them into an
// exit code (docs/cli.md "Exit codes"). Kept apart from cmd_bake.cpp so that the rules are
// one small unit with its own tests.
#pragma once

#include <cstdio>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/common/status.h"
#include "core/relight/relight.h"
#include "core/scene/scene.h"

namespace lightlink::cli {

struct BakeFindings {
  std::vector<std::string> warnings;  // each names its file / object
  std::vector<std::string> notes;     // decisions the precompute took (not problems)
  bool no_light = false;   // no light, emitter or sky lit the scene
  bool all_black = false;  // no lightmap texel received any light (direct or indirect)

  bool dark() const { return no_light || all_black; }
};

// Gathers the findings of a finished bake. `precompute_report` is ResidentScene's
// precomputeReport() (its "notes" and, where present, "warnings").
BakeFindings collectFindings(const scene::Scene& scene, const nlohmann::ordered_json& precompute_report,
                             const relight::RelightResult& result);

// True when every lightmap texel is black: no positive direct irradiance and no positive
// DC term of the indirect SH in any channel (a lightmap with no texels counts as black).
bool lightmapAllBlack(const relight::RelightResult& result);

// --fail-on: which findings make `bake` exit non-zero (after writing every output).
enum class FailOn { kNever, kDark, kWarning };
Expected<FailOn> parseFailOn(const std::string& text);

// kExitOk, or kExitDark / kExitWarnings as --fail-on asks (a dark bake is also a warning;
// it takes the more specific code).
int bakeExitCode(const BakeFindings& findings, FailOn fail_on);

// "lightlink bake: warning: ..." lines on `out`, at most `limit` of them and then a count of
// the rest (report.json has them all).
void printWarnings(const BakeFindings& findings, std::FILE* out, std::size_t limit = 20);

}  // namespace lightlink::cli
