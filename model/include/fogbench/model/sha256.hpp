// SHA-256 (FIPS 180-4), for the hashes a run's identity and a certificate carry: the daemon's
// configuration, the profile's text, a certificate's canonical JSON. Pure and allocation-free
// beyond the hex string; here, in the lowest library, because the daemon, the store's readers
// and fogctl all need the same one and OpenSSL is no dependency of fogbench (tests: the FIPS
// 180-4 / NIST example vectors in tests/model/sha256_test.cpp).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace fogbench::model {

class Sha256 {
 public:
  Sha256();
  // Feeds more bytes; may be called any number of times before digest().
  void update(std::string_view bytes);
  // The 32-byte digest; the object is spent afterwards (reset() to reuse it).
  std::array<std::uint8_t, 32> digest();
  void reset();

 private:
  void block(const std::uint8_t* p);
  std::array<std::uint32_t, 8> h_{};
  std::array<std::uint8_t, 64> buf_{};
  std::size_t used_ = 0;     // bytes in buf_
  std::uint64_t bytes_ = 0;  // message length so far, bytes
};

// The digest of `bytes` as 64 lowercase hexadecimal digits.
std::string sha256_hex(std::string_view bytes);

}  // namespace fogbench::model
