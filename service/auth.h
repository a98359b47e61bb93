// Authentication and identity: who may talk to the daemon and which scene a caller may use.
//
// Two independent checks (proto/lightlink.proto, "Authentication"):
//  - the daemon bearer token: when configured (always when listening beyond loopback) every
//    call carries `authorization: Bearer <token>`; a missing or wrong one is UNAUTHENTICATED;
//  - the scene token: random 128 bits handed out by OpenScene; every call naming a scene
//    must carry it (PERMISSION_DENIED otherwise), so one client cannot read or change a
//    scene it did not open unless it was given the token.
// Tokens are compared in constant time so the comparison leaks no prefix length. A
// "client" for per-client limits is one gRPC peer (transport address and port, i.e. one
// connection).
#pragma once

#include <string>
#include <string_view>

namespace lightlink::service {

// True when the host of "host:port" / "[v6]:port" is loopback (127.0.0.0/8, ::1, localhost).
bool isLoopbackListen(std::string_view listen);

// True when a gRPC peer string (ServerContext::peer(): "ipv4:127.0.0.1:5555",
// "ipv6:[::1]:5555", "unix:/path") names a connection from this machine: a loopback address
// (IPv4-mapped ones included) or a Unix socket.
bool isLocalPeer(std::string_view peer);

// 128 random bits as 32 lowercase hex characters (from the OS random source).
std::string randomToken();

bool constantTimeEqual(std::string_view a, std::string_view b);

// Checks an `authorization` metadata value against the daemon token. Empty `expected`:
// no token configured, every caller passes. Returns an empty string when accepted, else
// the reason (for the UNAUTHENTICATED message).
std::string checkBearer(std::string_view header_value, bool header_present, std::string_view expected);

// The key of per-client limits for a gRPC peer string ("ipv4:127.0.0.1:5555").
std::string clientKey(std::string_view peer);

}  // namespace lightlink::service
