# Initial cache of the fuzzing build (cmake -C fuzz/clang.cmake, as scripts/fuzz does): clang,
# every library instrumented for libFuzzer's coverage and for ASan and UBSan, asserts on.
#
# The compiler is clang 16 (Debian 12's clang-16 and libclang-rt-16-dev) with g++ 12's
# libstdc++, the library every dependency was built against. clang 14 cannot compile
# libstdc++'s <expected>: the header needs __cpp_concepts >= 202002L and clang 14 lacks the
# constrained special members (P0848) it relies on. clang 16 has them but still reports
# __cpp_concepts 201907L (it bumps the value only once all of C++20 concepts is in), so the
# value is raised here; with it <expected> compiles and behaves as under g++.
set(CMAKE_CXX_COMPILER clang++-16 CACHE STRING "fuzzing needs clang")
set(FOGBENCH_FUZZ ON CACHE BOOL "")
set(BUILD_TESTING OFF CACHE BOOL "")
# The fuzzers need model, profiles, storage, drivers and daemon: the rest is left out.
set(FOGBENCH_SKIP "sim;cli;bench" CACHE STRING "")
# -O1 without NDEBUG: the project's asserts are the fuzzers' oracles too. -g1: the line tables
# that ASan's and UBSan's reports need to name file and line, without full -g's compile time.
set(CMAKE_BUILD_TYPE Fuzz CACHE STRING "")
set(CMAKE_CXX_FLAGS_FUZZ "-O1 -g1" CACHE STRING "")
set(CMAKE_CXX_FLAGS
    "-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer -U__cpp_concepts -D__cpp_concepts=202002L"
    CACHE STRING "")
