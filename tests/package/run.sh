#!/usr/bin/env bash
# Installs the build tree's fogbench into a temporary prefix, then configures, builds and runs
# the downstream project beside this script against it: find_package(fogbench) must find the
# libraries, the headers and their dependencies with nothing from the source or build tree.
#   run.sh BUILD_DIR
set -euo pipefail
build=$1
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" --component dev >/dev/null
cmake -S "$here" -B "$tmp/build" -DCMAKE_PREFIX_PATH="$tmp/prefix" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$tmp/build" >/dev/null
"$tmp/build/downstream"
