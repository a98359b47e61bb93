// The summary of a batch bake (`lightlink bake A B ... -o OUT`): one entry per scene, written
// as OUT/summary.json and as JUnit XML (OUT/summary.xml) for CI dashboards (Jenkins, GitLab,
// GitHub test reporters read <testsuite>/<testcase>/<error>/<failure>). A scene whose bake
// stopped is an <error> (no outputs: bad input, I/O, over a limit); one whose outputs were
// written but tripped --fail-on is a <failure>. Both files are written atomically (temp +
// rename) so a dashboard never reads half a summary. docs/cli.md "Batch bakes".
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/common/status.h"

namespace lightlink::cli {

struct SceneOutcome {
  std::string scene;    // the path given
  std::string folder;   // its output folder, relative to the batch's output directory
  int exit_code = 0;    // what `lightlink bake SCENE` alone would have returned
  bool outputs_written = false;  // false: the bake stopped (error); true with exit_code != 0: --fail-on
  std::string message;  // the error, or why --fail-on tripped
  std::string artifact; // the artifact note: reused from the cache, or computed and saved
  std::string cache_key;
  std::size_t warnings = 0;
  double seconds = 0.0;
};

// "ok", "failed" (outputs written, --fail-on tripped) or "error" (the bake stopped).
const char* outcomeStatus(const SceneOutcome& o);

nlohmann::ordered_json summaryJson(const std::vector<SceneOutcome>& scenes, double seconds);
std::string summaryJunitXml(const std::vector<SceneOutcome>& scenes, double seconds);

// summary.json and summary.xml into `dir`.
Status writeBatchSummary(const std::vector<SceneOutcome>& scenes, double seconds, const std::string& dir);

}  // namespace lightlink::cli
