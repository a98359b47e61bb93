#include "service/auth.h"

#include <arpa/inet.h>

#include <array>
#include <cstdint>
#include <fstream>
#include <random>

#include <fmt/format.h>

namespace lightlink::service {

bool isLoopbackListen(std::string_view listen) {
  std::string_view host = listen;
  if (!host.empty() && host.front() == '[') {
    const auto close = host.find(']');
    host = close == std::string_view::npos ? host.substr(1) : host.substr(1, close - 1);
  } else if (const auto colon = host.rfind(':'); colon != std::string_view::npos) {
    host = host.substr(0, colon);
  }
  if (host == "localhost") return true;
  const std::string h(host);
  in_addr v4{};
  if (::inet_pton(AF_INET, h.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (::inet_pton(AF_INET6, h.c_str(), &v6) == 1) return IN6_IS_ADDR_LOOPBACK(&v6);
  return false;  // a name other than localhost, 0.0.0.0, [::]: exposed
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
