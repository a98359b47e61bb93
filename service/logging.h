// Structured logs: one line per event, as `key=value` text or one JSON object per line.
//
// Handlers and sessions log *events* ("scene_opened", "relight", "update_rejected", ...)
// with named fields instead of free sentences, so a log can be grepped or fed to a log
// pipeline without parsing prose. spdlog does the output (thread-safe, stderr or a file).
#pragma once

#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "core/common/status.h"
#include "service/config.h"

namespace lightlink::service {

enum class LogLevel { kTrace, kDebug, kInfo, kWarn, kError };

// Configures the process-wide logger (format, level, destination).
Status initLogging(const DaemonConfig& config);

// Logs one event with its fields (a JSON object; scalars, strings, arrays).
void logEvent(LogLevel level, std::string_view event, const nlohmann::ordered_json& fields = {});

// Flushes pending lines (before exit).
void flushLogs();

}  // namespace lightlink::service
