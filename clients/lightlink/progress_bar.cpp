#include "clients/lightlink/progress_bar.h"

#include <unistd.h>

#include <fmt/format.h>

namespace lightlink::cli {

ProgressBar::ProgressBar(bool enabled) : enabled_(enabled), tty_(::isatty(STDERR_FILENO) != 0) {}

void ProgressBar::begin(std::string_view stage, std::size_t total) {
  std::lock_guard lock(mutex_);
  stage_ = std::string(stage);
  total_ = total;
  last_drawn_ = 0;
  start_ = last_draw_time_ = std::chrono::steady_clock::now();
  if (enabled_ && tty_) draw(0, false);
}

void ProgressBar::update(std::size_t done) {
  std::lock_guard lock(mutex_);
  if (!enabled_ || !tty_ || done < last_drawn_) return;
  // Redraw at most ~20 times a second: a terminal is slower than our loops.
  const auto now = std::chrono::steady_clock::now();
  if (now - last_draw_time_ < std::chrono::milliseconds(50)) return;
  last_draw_time_ = now;
  last_drawn_ = done;
  draw(done, false);
}

void ProgressBar::end() {
  std::lock_guard lock(mutex_);
  if (enabled_) draw(total_, true);
}

void ProgressBar::draw(std::size_t done, bool final_line) {
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  std::string line;
  if (total_ > 0) {
    constexpr int kWidth = 30;
    const double f = std::min(1.0, static_cast<double>(done) / static_cast<double>(total_));
    const int filled = static_cast<int>(f * kWidth);
    line = fmt::format("{:<14} [{}{}] {:5.1f}% {:7.2f} s", stage_, std::string(filled, '#'),
                       std::string(kWidth - filled, '.'), 100.0 * f, seconds);
  } else {
    line = fmt::format("{:<14} {:7.2f} s", stage_, seconds);
  }
  if (tty_) {
    std::fprintf(stderr, "\r%s%s", line.c_str(), final_line ? "\n" : "");
  } else if (final_line) {
    std::fprintf(stderr, "%s\n", line.c_str());
  }
  std::fflush(stderr);
}

}  // namespace lightlink::cli
