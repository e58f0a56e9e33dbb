// SHA-256 against the FIPS 180-4 example vectors (NIST's "Examples with intermediate values",
// SHA256.pdf, and the long message of FIPS 180-2 Appendix B.3): any wrong constant, rotation
// or padding step changes every digit.
#include <catch2/catch.hpp>

#include <string>

#include "fogbench/model/sha256.hpp"

using fogbench::model::Sha256;
using fogbench::model::sha256_hex;

TEST_CASE("sha256: FIPS 180-4 example vectors") {
  CHECK(sha256_hex("abc") == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  CHECK(sha256_hex("") == "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  // 448 bits: the padding no longer fits the block, a second one is needed.
  CHECK(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq") ==
        "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  CHECK(sha256_hex(std::string(1000000, 'a')) ==
        "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

TEST_CASE("sha256: fed in pieces of any size, the digest is the one of the whole") {
  const std::string msg = std::string(1000000, 'a');
  for (std::size_t piece : {1u, 55u, 63u, 64u, 65u, 1000u}) {
    Sha256 s;
    for (std::size_t i = 0; i < msg.size(); i += piece) s.update(std::string_view(msg).substr(i, piece));
    const auto d = s.digest();
    CHECK(d[0] == 0xcd);
    CHECK(d[31] == 0xd0);
  }
  // reset() starts again.
  Sha256 s;
  s.update("junk");
  (void)s.digest();
  s.reset();
  s.update("abc");
  CHECK(s.digest()[0] == 0xba);
}
