// Bake options: the one set of options `lightlink bake`, `compare`, `precompute`, `open`,
// OpenScene and the daemon accept, with one table, one parser and one validator.
//
// Every front end collects (name, value) settings as the user wrote them (CLI flags without
// the dashes, OpenScene `options` keys) and hands them to BakeOptionsBuilder, which applies
// the preset first, then every setting, then validates the whole. So a value means the same,
// is range-checked the same and reaches the artifact's cache key the same way whichever
// front end it came through (docs/cli.md "Bake options", docs/service.md "OpenScene").
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/common/status.h"
#include "core/precompute/precompute.h"
#include "core/relight/relight.h"

namespace lightlink::bake {

struct BakeOptions {
  std::string preset;                    // the preset applied first ("" = none: the raw defaults)
  precompute::PrecomputeOptions precompute;
  relight::RelightOptions relight;       // link_form and max_bounces are the bake options
};

// One row of the table: the name (CLI flag without "--", OpenScene options key), the value
// syntax and range as users read them, and the help text.
struct OptionInfo {
  std::string_view name;
  std::string_view value;  // e.g. "1..4", "auto|on|off", "metres > 0"
  std::string_view help;
};

// Every bake option, in the order help and docs list them.
std::span<const OptionInfo> optionTable();

class BakeOptionsBuilder {
 public:
  // `default_preset` applies when no "preset" setting is given ("" = PrecomputeOptions'
  // defaults); `relight_defaults` are the relight options before any setting (the daemon's
  // --bounces). `flag_prefix` is how messages name an option ("--" on the CLI).
  explicit BakeOptionsBuilder(std::string default_preset = "medium", relight::RelightOptions relight_defaults = {},
                              std::string flag_prefix = "--");

  // Records one setting; an unknown name (the message lists the known ones) or a malformed
  // or out-of-range value fails here with a message naming the option. `label`, when given,
  // is how the message names it instead (an older field name).
  Status set(std::string_view name, std::string_view value, std::string_view label = {});
  // The settings given so far, in order (name, value).
  const std::vector<std::pair<std::string, std::string>>& settings() const { return settings_; }
  bool has(std::string_view name) const;

  // Preset, then every setting in order, then the validator.
  Expected<BakeOptions> build() const;

 private:
  std::string default_preset_;
  relight::RelightOptions relight_defaults_;
  std::string prefix_;
  std::vector<std::pair<std::string, std::string>> settings_;
  std::vector<std::string> labels_;
};

// Builds from a list of settings in one call (the CLI's and OpenScene's path).
Expected<BakeOptions> buildBakeOptions(std::span<const std::pair<std::string, std::string>> settings,
                                       std::string default_preset = "medium",
                                       relight::RelightOptions relight_defaults = {},
                                       std::string flag_prefix = "--");

// The one validator: PrecomputeOptions::validate plus the relight options' ranges.
Status validate(const BakeOptions& options);

}  // namespace lightlink::bake
