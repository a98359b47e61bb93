// AuthFailureLimiter: slows down guessing of the daemon bearer token.
//
// Failed authentications are counted per client address (the host of the gRPC peer, so
// new connections from the same machine count together). After `max_failures` within
// `window`, every call from that address is refused for `backoff` without comparing the
// token, so a guesser learns nothing while blocked. The block is logged once when it
// starts, not once per refused call.
#pragma once

#include <chrono>
#include <cstddef>
#include <map>
#include <mutex>
#include <string>
#include <string_view>

namespace lightlink::service {

class AuthFailureLimiter {
 public:
  using Clock = std::chrono::steady_clock;
  struct Limits {
    int max_failures = 10;
    Clock::duration window = std::chrono::seconds(60);
    Clock::duration backoff = std::chrono::seconds(60);
  };
  AuthFailureLimiter() : AuthFailureLimiter(Limits{}) {}
  explicit AuthFailureLimiter(Limits limits) : limits_(limits) {}

  // Zero when `address` may try to authenticate now, else how long it is still blocked.
  Clock::duration blockedFor(const std::string& address, Clock::time_point now = Clock::now());
  // Records a failure; true when this failure starts a block (log it then).
  bool recordFailure(const std::string& address, Clock::time_point now = Clock::now());
  const Limits& limits() const { return limits_; }

 private:
  struct Entry {
    Clock::time_point window_start;
    int failures = 0;
    Clock::time_point blocked_until;
  };
  void prune(Clock::time_point now);

  Limits limits_;
  std::mutex mutex_;
  std::map<std::string, Entry> entries_;
};

// The address part of a gRPC peer string: "ipv4:10.0.0.5:4242" -> "10.0.0.5",
// "ipv6:[::1]:4242" -> "::1", "unix:/path" -> "unix".
std::string peerAddress(std::string_view peer);

}  // namespace lightlink::service
