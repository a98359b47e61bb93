#include "service/auth_limiter.h"

namespace lightlink::service {

std::string peerAddress(std::string_view peer) {
  for (std::string_view scheme : {"ipv4:", "ipv6:"}) {
    if (peer.substr(0, scheme.size()) != scheme) continue;
    std::string_view rest = peer.substr(scheme.size());
    if (!rest.empty() && rest.front() == '[') {
      const auto close = rest.find(']');
      return std::string(close == std::string_view::npos ? rest.substr(1) : rest.substr(1, close - 1));
    }
    const auto colon = rest.rfind(':');
    return std::string(colon == std::string_view::npos ? rest : rest.substr(0, colon));
  }
  const auto colon = peer.find(':');
  return std::string(colon == std::string_view::npos ? peer : peer.substr(0, colon));
}

AuthFailureLimiter::Clock::duration AuthFailureLimiter::blockedFor(const std::string& address, Clock::time_point now) {
  std::lock_guard lock(mutex_);
  const auto it = entries_.find(address);
  if (it == entries_.end() || it->second.blocked_until <= now) return Clock::duration::zero();
  return it->second.blocked_until - now;
}

bool AuthFailureLimiter::recordFailure(const std::string& address, Clock::time_point now) {
  std::lock_guard lock(mutex_);
  prune(now);
  Entry& e = entries_[address];
  if (e.failures == 0 || now - e.window_start > limits_.window) {
    e.window_start = now;
    e.failures = 0;
  }
  if (++e.failures < limits_.max_failures || e.blocked_until > now) return false;
  e.blocked_until = now + limits_.backoff;
  e.failures = 0;  // a new window starts after the back-off
  return true;
}

void AuthFailureLimiter::prune(Clock::time_point now) {
  // Bounded memory under many addresses: forget those with nothing left to remember.
  if (entries_.size() < 4096) return;
  for (auto it = entries_.begin(); it != entries_.end();) {
    const bool stale = it->second.blocked_until <= now && now - it->second.window_start > limits_.window;
    it = stale ? entries_.erase(it) : std::next(it);
  }
}

}  // namespace lightlink::service
