#!/usr/bin/env bash
# Builds the libFuzzer targets with clang in a nested build folder and runs
# them for a bounded time (the fuzz ctest of that build). Skips (exit 77)
# when clang++ is not installed.
set -euo pipefail
src=$1 build=$2 clangxx=$3 shared=$4
if [ -z "$clangxx" ] || [ ! -x "$clangxx" ]; then
  echo "clang++ not found: install clang and libclang-rt-14-dev to run the fuzz test"
  exit 77
fi
clangc=${clangxx%++}
cmake -S "$src" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER="$clangc" -DCMAKE_CXX_COMPILER="$clangxx" \
  -DLOCFORGE_BUILD_FUZZERS=ON -DLOCFORGE_BUILD_TESTS=OFF -DLOCFORGE_BUILD_BENCHMARKS=OFF \
  -DLOCFORGE_SHARED_DIR="$shared" -DLOCFORGE_FUZZ_SECONDS="${LOCFORGE_FUZZ_SECONDS:-30}" >/dev/null
cmake --build "$build" --target kapture_text_fuzz -j2
cd "$build"
ctest -L fuzz --output-on-failure
