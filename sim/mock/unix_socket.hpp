// Listening unix sockets for the mock bench (the CAN bus and the control socket).
#pragma once

#include <expected>
#include <string>

namespace fogbench::mock {

std::string errno_text(int err);

// A non-blocking listening socket of `type` (SOCK_STREAM, SOCK_SEQPACKET) bound at `path`. A
// stale socket file nobody listens on is replaced; a live one or any other file is an error.
std::expected<int, std::string> listen_unix(const std::string& path, int type);

}  // namespace fogbench::mock
