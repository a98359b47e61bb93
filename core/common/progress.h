// Progress reporting from long core stages (unwrap, precompute, bake) to whoever runs
// them: the CLI draws a bar, the daemon streams messages, tests ignore it. Core code only
// sees this small interface, never a terminal or a socket. Callbacks may come from any
// thread; implementations must be thread-safe. `cancelled()` is polled between chunks of
// work so a caller (a deadline, a closed client) can stop a stage early.
#pragma once

#include <atomic>
#include <cstddef>
#include <string_view>

namespace lightlink {

class Progress {
 public:
  virtual ~Progress() = default;
  // A new stage begins; `total` units of work (0 = unknown).
  virtual void begin(std::string_view stage, std::size_t total) = 0;
  // `done` units of the current stage are complete (monotonic).
  virtual void update(std::size_t done) = 0;
  virtual void end() = 0;
  virtual bool cancelled() const { return false; }
};

// True when `progress` asks the work to stop: long loops poll this once per chunk (a few
// ms of work) and their stage then returns a Code::kCancelled status.
inline bool stopRequested(const Progress* progress) { return progress != nullptr && progress->cancelled(); }

// Does nothing; the default when a caller does not care.
class NullProgress final : public Progress {
 public:
  void begin(std::string_view, std::size_t) override {}
  void update(std::size_t) override {}
  void end() override {}
};

// Counts work from many threads and forwards to a Progress at most every `step` units,
// so hot loops pay one relaxed atomic add per chunk.
class ProgressCounter {
 public:
  ProgressCounter(Progress& sink, std::size_t step) : sink_(sink), step_(step == 0 ? 1 : step) {}
  void add(std::size_t n) {
    const std::size_t before = done_.fetch_add(n, std::memory_order_relaxed);
    if ((before + n) / step_ != before / step_) sink_.update(before + n);
  }
  std::size_t done() const { return done_.load(std::memory_order_relaxed); }

 private:
  Progress& sink_;
  std::size_t step_;
  std::atomic<std::size_t> done_{0};
};

}  // namespace lightlink
