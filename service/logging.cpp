#include "service/logging.h"

#include <chrono>
#include <memory>

#include <fmt/chrono.h>
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

namespace lightlink::service {
namespace {

std::shared_ptr<spdlog::logger>& logger() {
  static std::shared_ptr<spdlog::logger> instance;
  return instance;
}
LogFormat g_format = LogFormat::kText;

spdlog::level::level_enum toSpd(LogLevel level) {
  switch (level) {
    case LogLevel::kTrace: return spdlog::level::trace;
    case LogLevel::kDebug: return spdlog::level::debug;
    case LogLevel::kInfo: return spdlog::level::info;
    case LogLevel::kWarn: return spdlog::level::warn;
    case LogLevel::kError: return spdlog::level::err;
  }
  return spdlog::level::info;
}

const char* levelName(LogLevel level) {
  switch (level) {
    case LogLevel::kTrace: return "trace";
    case LogLevel::kDebug: return "debug";
    case LogLevel::kInfo: return "info";
    case LogLevel::kWarn: return "warn";
    case LogLevel::kError: return "error";
  }
  return "info";
}

// Text form of one field value: strings quoted only when they contain spaces or quotes.
std::string textValue(const nlohmann::ordered_json& v) {
  if (v.is_string()) {
    const auto& s = v.get_ref<const std::string&>();
    if (s.find_first_of(" \"=\t\n") == std::string::npos && !s.empty()) return s;
    return nlohmann::json(s).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  }
  return v.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace

Status initLogging(const DaemonConfig& config) {
  std::shared_ptr<spdlog::logger> l;
  try {
    if (config.log_file.empty()) {
      l = std::make_shared<spdlog::logger>("lightlinkd", std::make_shared<spdlog::sinks::stderr_sink_mt>());
    } else {
      l = std::make_shared<spdlog::logger>(
          "lightlinkd", std::make_shared<spdlog::sinks::basic_file_sink_mt>(config.log_file, /*truncate=*/false));
    }
  } catch (const spdlog::spdlog_ex& e) {
    return ioError("--log-file {}: {}", config.log_file, e.what());
  }
  // The line is fully formatted by logEvent (timestamp included), so both formats stay
  // one self-contained line.
  l->set_pattern("%v");
  l->set_level(spdlog::level::from_str(config.log_level));
  l->flush_on(spdlog::level::info);
  g_format = config.log_format;
  logger() = std::move(l);
  return {};
}

void logEvent(LogLevel level, std::string_view event, const nlohmann::ordered_json& fields) {
  auto& l = logger();
  if (!l) return;
  const auto spd = toSpd(level);
  if (!l->should_log(spd)) return;
  const auto now = std::chrono::system_clock::now();
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  const std::string ts = fmt::format("{:%Y-%m-%dT%H:%M:%S}.{:03d}Z",
                                     fmt::gmtime(std::chrono::system_clock::to_time_t(now)), static_cast<int>(ms));
  std::string line;
  if (g_format == LogFormat::kJson) {
    nlohmann::ordered_json j;
    j["ts"] = ts;
    j["level"] = levelName(level);
    j["event"] = event;
    if (fields.is_object())
      for (auto it = fields.begin(); it != fields.end(); ++it) j[it.key()] = it.value();
    line = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  } else {
    line = fmt::format("{} {:<5} {}", ts, levelName(level), event);
    if (fields.is_object())
      for (auto it = fields.begin(); it != fields.end(); ++it) line += fmt::format(" {}={}", it.key(), textValue(it.value()));
  }
  l->log(spd, fmt::runtime("{}"), line);
}

void flushLogs() {
  if (auto& l = logger()) l->flush();
}

}  // namespace lightlink::service
