#include "service/auth.h"

#include <arpa/inet.h>

#include <array>
#include <cstdint>
#include <fstream>
#include <random>

#include <fmt/format.h>

namespace lightlink::service {

namespace {

// The host of "host:port" / "[v6]:port".
std::string_view hostOf(std::string_view address) {
  if (!address.empty() && address.front() == '[') {
    const auto close = address.find(']');
    return close == std::string_view::npos ? address.substr(1) : address.substr(1, close - 1);
  }
  const auto colon = address.rfind(':');
  return colon == std::string_view::npos ? address : address.substr(0, colon);
}

// 127.0.0.0/8 or ::1; with `v4_mapped` also ::ffff:127.0.0.0/104 (how a dual-stack socket
// names an IPv4 loopback peer).
bool isLoopbackAddress(std::string_view host, bool v4_mapped) {
  const std::string h(host);
  in_addr v4{};
  if (::inet_pton(AF_INET, h.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (::inet_pton(AF_INET6, h.c_str(), &v6) == 1)
    return IN6_IS_ADDR_LOOPBACK(&v6) || (v4_mapped && IN6_IS_ADDR_V4MAPPED(&v6) && v6.s6_addr[12] == 127);
  return false;
}

}  // namespace

bool isLoopbackListen(std::string_view listen) {
  const std::string_view host = hostOf(listen);
  if (host == "localhost") return true;
  return isLoopbackAddress(host, false);  // a name other than localhost, 0.0.0.0, [::]: exposed
}

bool isLocalPeer(std::string_view peer) {
  if (peer.starts_with("unix:") || peer.starts_with("unix-abstract:")) return true;
  for (std::string_view scheme : {"ipv4:", "ipv6:"})
    if (peer.starts_with(scheme)) return isLoopbackAddress(hostOf(peer.substr(scheme.size())), true);
  return false;
}

std::string randomToken() {
  std::array<std::uint8_t, 16> bytes{};
  std::ifstream urandom("/dev/urandom", std::ios::binary);
  if (!urandom.read(reinterpret_cast<char*>(bytes.data()), bytes.size())) {
    // No /dev/urandom (a very odd system): std::random_device is the next best source.
    std::random_device rd;
    for (auto& b : bytes) b = static_cast<std::uint8_t>(rd());
  }
  std::string hex;
  hex.reserve(32);
  for (auto b : bytes) hex += fmt::format("{:02x}", b);
  return hex;
}

bool constantTimeEqual(std::string_view a, std::string_view b) {
  // Length is not secret (tokens have a fixed format); the bytes are.
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

std::string checkBearer(std::string_view value, bool present, std::string_view expected) {
  if (expected.empty()) return {};
  if (!present) return "authorization: missing (expected 'Bearer <token>')";
  constexpr std::string_view kPrefix = "Bearer ";
  if (value.substr(0, kPrefix.size()) != kPrefix) return "authorization: expected 'Bearer <token>'";
  if (!constantTimeEqual(value.substr(kPrefix.size()), expected)) return "authorization: wrong bearer token";
  return {};
}

std::string clientKey(std::string_view peer) { return std::string(peer); }

}  // namespace lightlink::service
