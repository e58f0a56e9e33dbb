// The termios speed constant of a baud rate (bits/s), for every serial line the drivers open:
// the Espec chamber's line (line_link.cpp) and the serial gyro's (transport_serial.cpp).
// Which rates a configuration may ask for is decided where it is read (config.cpp); this is
// only the table Linux knows.
#pragma once

#include <termios.h>

#include <optional>

namespace fogbench::drivers::detail {

inline std::optional<speed_t> termios_baud(int baud) noexcept {
  switch (baud) {
    case 1200: return B1200;
    case 2400: return B2400;
    case 4800: return B4800;
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 500000: return B500000;
    case 921600: return B921600;
    case 1000000: return B1000000;
    case 2000000: return B2000000;
    case 3000000: return B3000000;
    case 4000000: return B4000000;
    default: return std::nullopt;
  }
}

}  // namespace fogbench::drivers::detail
