// A terminal progress bar for lightlink::Progress, drawn on stderr. On a terminal it
// redraws one line in place; elsewhere (CI logs) it prints one line per stage with its
// time, so logs stay short.
#pragma once

#include <chrono>
#include <cstdio>
#include <mutex>
#include <string>

#include "core/common/progress.h"

namespace lightlink::cli {

class ProgressBar final : public Progress {
 public:
  explicit ProgressBar(bool enabled = true);
  void begin(std::string_view stage, std::size_t total) override;
  void update(std::size_t done) override;
  void end() override;

 private:
  void draw(std::size_t done, bool final_line);

  bool enabled_;
  bool tty_;
  std::mutex mutex_;
  std::string stage_;
  std::size_t total_ = 0;
  std::size_t last_drawn_ = 0;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_time_;
};

}  // namespace lightlink::cli
