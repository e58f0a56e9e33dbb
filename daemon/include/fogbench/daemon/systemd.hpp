// fogbenchd under systemd, without libsystemd: the sd_notify protocol (one datagram of
// "KEY=VALUE" lines to the AF_UNIX socket in $NOTIFY_SOCKET: READY=1, STATUS=..., WATCHDOG=1,
// STOPPING=1) and the journal's stream conventions (a "<N>" priority prefix per line, no
// timestamp of our own: the journal stamps every line). See docs/daemon.md, "As a service".
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

namespace spdlog {
class logger;
}

namespace fogbench::daemon::systemd {

// Sends `state` (e.g. "READY=1\nSTATUS=listening") to $NOTIFY_SOCKET (a path, or '@' for the
// abstract namespace). false when the variable is unset (not under systemd, or Type=simple) or
// the send failed; never throws, never blocks.
bool notify(std::string_view state);
// The same to an explicit socket path (tests).
bool notify_to(const std::string& socket_path, std::string_view state);

// The watchdog interval systemd asks for ($WATCHDOG_USEC, for this process if $WATCHDOG_PID
// names one); empty when there is no watchdog.
std::optional<std::chrono::microseconds> watchdog_interval();

// Whether stderr is connected to the journal ($JOURNAL_STREAM names stderr's device:inode).
bool stderr_is_journal();

// A logger for stderr: under the journal each line "<N>message" (N the syslog priority of the
// level, so `journalctl -p warning` works) with no timestamp and no trailing blank line, a
// multi-line message one entry per line; elsewhere "[time] [level] message" as before.
std::shared_ptr<spdlog::logger> stderr_logger(const std::string& name, bool journal);

}  // namespace fogbench::daemon::systemd
