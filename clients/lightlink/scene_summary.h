// A scene summary as `lightlink inspect` reports it: counts, lights by kind, emissive
// area, bounds, static/dynamic split and lightmap-UV presence, as JSON (for machines)
// and as aligned text (for people). Shared by every command that opens a scene.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "core/scene/scene.h"

namespace lightlink::cli {

nlohmann::ordered_json summarizeScene(const scene::Scene& scene);
std::string formatSummary(const nlohmann::ordered_json& summary);

}  // namespace lightlink::cli
