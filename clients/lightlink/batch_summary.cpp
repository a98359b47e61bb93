#include "clients/lightlink/batch_summary.h"

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "clients/lightlink/version.h"

namespace lightlink::cli {
namespace {

namespace fs = std::filesystem;

// XML text and attribute values: the five predefined entities; control characters other
// than tab and newline are not allowed in XML 1.0 at all, so they become '?'.
std::string xmlEscape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (const char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default:
        out += (static_cast<unsigned char>(c) < 0x20 && c != '\t' && c != '\n') ? '?' : c;
    }
  }
  return out;
}

Status writeAtomically(const fs::path& path, const std::string& text) {
  const fs::path temp = path.parent_path() / fmt::format(".{}.tmp.{}", path.filename().string(), ::getpid());
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    out << text;
    out.flush();
    if (!out) {
      std::error_code ec;
      fs::remove(temp, ec);
      return ioError("cannot write {}", temp.string());
    }
  }
  std::error_code ec;
  fs::rename(temp, path, ec);
  if (ec) {
    fs::remove(temp, ec);
    return ioError("cannot rename {} to {}: {}", temp.string(), path.string(), ec.message());
  }
  return {};
}

}  // namespace

const char* outcomeStatus(const SceneOutcome& o) {
  if (o.exit_code == 0) return "ok";
  return o.outputs_written ? "failed" : "error";
}

nlohmann::ordered_json summaryJson(const std::vector<SceneOutcome>& scenes, double seconds) {
  nlohmann::ordered_json j;
  j["format"] = "lightlink.bake-summary";
  j["version"] = 1;
  j["lightlink"] = {{"version", lightlinkVersion()}, {"commit", lightlinkCommit()}};
  std::size_t ok = 0;
  nlohmann::ordered_json list = nlohmann::ordered_json::array();
  for (const SceneOutcome& o : scenes) {
    ok += o.exit_code == 0;
    list.push_back({{"scene", o.scene},
                    {"folder", o.folder},
                    {"status", outcomeStatus(o)},
                    {"exit_code", o.exit_code},
                    {"message", o.message},
                    {"artifact", o.artifact},
                    {"cache_key", o.cache_key},
                    {"warnings", o.warnings},
                    {"seconds", o.seconds}});
  }
  j["scenes_total"] = scenes.size();
  j["scenes_ok"] = ok;
  j["scenes_failed"] = scenes.size() - ok;
  j["seconds"] = seconds;
  j["scenes"] = std::move(list);
  return j;
}

std::string summaryJunitXml(const std::vector<SceneOutcome>& scenes, double seconds) {
  std::size_t failures = 0, errors = 0;
  for (const SceneOutcome& o : scenes) {
    if (o.exit_code == 0) continue;
    (o.outputs_written ? failures : errors) += 1;
  }
  std::string x = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  x += fmt::format("<testsuites name=\"lightlink bake\" tests=\"{}\" failures=\"{}\" errors=\"{}\" time=\"{:.3f}\">\n",
                   scenes.size(), failures, errors, seconds);
  x += fmt::format("  <testsuite name=\"lightlink bake\" tests=\"{}\" failures=\"{}\" errors=\"{}\" time=\"{:.3f}\">\n",
                   scenes.size(), failures, errors, seconds);
  for (const SceneOutcome& o : scenes) {
    x += fmt::format("    <testcase classname=\"lightlink.bake\" name=\"{}\" file=\"{}\" time=\"{:.3f}\">\n",
                     xmlEscape(o.folder), xmlEscape(o.scene), o.seconds);
    if (o.exit_code != 0)
      x += fmt::format("      <{0} type=\"exit {1}\" message=\"{2}\">{2}</{0}>\n", o.outputs_written ? "failure" : "error",
                       o.exit_code, xmlEscape(o.message));
    x += fmt::format("      <system-out>artifact: {}; warnings: {}; outputs in {}/</system-out>\n",
                     xmlEscape(o.artifact.empty() ? "none" : o.artifact), o.warnings, xmlEscape(o.folder));
    x += "    </testcase>\n";
  }
  x += "  </testsuite>\n</testsuites>\n";
  return x;
}

Status writeBatchSummary(const std::vector<SceneOutcome>& scenes, double seconds, const std::string& dir) {
  if (Status s = writeAtomically(fs::path(dir) / "summary.json", summaryJson(scenes, seconds).dump(2) + "\n"); !s)
    return s;
  return writeAtomically(fs::path(dir) / "summary.xml", summaryJunitXml(scenes, seconds));
}

}  // namespace lightlink::cli
