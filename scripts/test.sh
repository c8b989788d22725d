#!/usr/bin/env bash
# Builds kintsugi and runs every test: an optimised build of the command-line tool and the
# examples with the tests that use them (CLI behaviour, examples, the installed package);
# with clang, every public header compiled alone, the benchmarks compiled unoptimised
# (they must build; a Release configuration measures) and a short fuzzing run of each file
# reader (tests/fuzz/); then the doctest programs, built once, under AddressSanitizer +
# UndefinedBehaviorSanitizer with assertions on.
# Usage: scripts/test.sh [--no-sanitize]   (the doctest programs then run in the optimised build)
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
scripts/setup.sh

jobs=$(nproc 2>/dev/null || echo 2)
sanitize=1
[ "${1:-}" = "--no-sanitize" ] && sanitize=0

if command -v ccache >/dev/null; then
  export CCACHE_DIR="${CCACHE_DIR:-$HOME/.cache/kintsugi-ccache}"
  # Hits across checkouts in different directories (CI clones elsewhere).
  export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=true
  # The test programs' precompiled header: ccache may reuse results compiled with it.
  export CCACHE_SLOPPINESS="${CCACHE_SLOPPINESS:-pch_defines,time_macros,include_file_mtime,include_file_ctime}"
  ccache --max-size=5G >/dev/null 2>&1 || true
fi

times_file=$(mktemp)
# cpu: the CPU seconds (user + system) of this shell's finished child processes. Beside
# the wall time, what a step costs on a machine of any speed or load. Called as a command,
# not in $(...), whose subshell would report its own.
cpu_now() {
  times >"$times_file"
  cpu=$(awk 'NR == 2 { n = 0; for (i = 1; i <= 2; ++i) { split($i, t, /[ms]/); n += t[1] * 60 + t[2] } printf "%d", n }' "$times_file")
}

build_suite() {
  local dir=$1; shift
  echo "== configure $dir" >&2
  cmake -S "$root" -B "$dir" -G Ninja "$@" >/dev/null
  echo "== build $dir" >&2
  local t0=$SECONDS c0
  cpu_now; c0=$cpu
  cmake --build "$dir" -j "$jobs"
  cpu_now
  echo "== built $dir in $((SECONDS - t0)) s, $((cpu - c0)) s of CPU" >&2
}

test_suite() {
  local dir=$1; shift
  echo "== test $dir" >&2
  local t0=$SECONDS c0
  cpu_now; c0=$cpu
  (cd "$dir" && ctest --output-on-failure -j "$jobs" --timeout 1500 "$@")
  cpu_now
  echo "== tested $dir in $((SECONDS - t0)) s, $((cpu - c0)) s of CPU" >&2
}

# clang: every public header compiled alone (-Wall -Wextra -Wpedantic -Werror) and the
# benchmarks compiled and linked at -O0 (not run here; clang compiles them in half GCC's
# time at the same level: bench_complete 35 s of CPU against 76 s), then each reader's
# libFuzzer harness for KINTSUGI_FUZZ_SECONDS (default 25) from the seed corpus, two at a
# time; a rejected header, a benchmark that does not build or a fuzzing finding fails the script.
# The clang build runs beside the optimised build: alone, the optimised build kept 1.4 of
# the 2 cores busy (548 s wall, 757 s of CPU; its precompiled header and the longest files
# are chains the other core cannot help with) and the clang build 1.8 (448 s, 819 s).
# Its log is shown when it ends.
clang_build=
mkdir -p build
if command -v clang++ >/dev/null; then
  (
    times_file=$(mktemp)
    t0=$SECONDS
    echo "== configure build/clang" >&2
    cmake -S "$root" -B build/clang -G Ninja -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=Debug \
      -DCMAKE_CXX_FLAGS_DEBUG="" -DKINTSUGI_BUILD_TESTS=OFF -DKINTSUGI_BUILD_EXAMPLES=OFF \
      -DKINTSUGI_CHECK_HEADERS=ON -DKINTSUGI_BUILD_FUZZ=ON -DKINTSUGI_BUILD_BENCH=ON >/dev/null
    echo "== build build/clang (header check, benchmarks, fuzzers), beside the optimised build" >&2
    cpu_now; c0=$cpu
    cmake --build build/clang -j "$jobs"
    cpu_now
    rm -f "$times_file"
    echo "== built build/clang in $((SECONDS - t0)) s, $((cpu - c0)) s of CPU" >&2
  ) >build/clang.log 2>&1 &
  clang_build=$!
else
  echo "== clang++ not found: header check and fuzzing skipped (scripts/setup.sh installs it)" >&2
fi
# Waits for a background step (its process id in the variable named $1, emptied once it
# ended) and prints its log ($2); returns its status.
finish_background() {
  local -n pid=$1
  [ -n "$pid" ] || return 0
  local status=0
  wait "$pid" || status=$?
  pid=
  cat "$2"
  return $status
}
finish_clang_build() { finish_background clang_build build/clang.log; }

# Release: the doctest programs too only when there is no sanitizer build to run them.
unit_in_release=OFF
[ $sanitize -eq 0 ] && unit_in_release=ON
build_suite build/release -DCMAKE_BUILD_TYPE=Release -DKINTSUGI_BUILD_BENCH=OFF -DKINTSUGI_UNIT_TESTS=$unit_in_release
# Without the doctest programs, the optimised suite is the CLI, the examples and the packaging
# test, whose one long step (the README's snippets, one translation unit) would leave a core
# idle for two minutes: it runs beside the clang build, and its log is shown after it.
release_tests=
finish_release_tests() { finish_background release_tests build/release/ctest.log; }
# If a later step fails, the background steps still finish and their logs are shown.
trap 'rc=$?; if [ -n "$clang_build$release_tests" ]; then echo "== a step failed; the background steps run to their end" >&2; finish_clang_build || true; finish_release_tests || true; fi; rm -f "$times_file"; exit $rc' EXIT
if [ $sanitize -eq 1 ]; then
  test_suite build/release >build/release/ctest.log 2>&1 &
  release_tests=$!
else
  test_suite build/release
fi

if [ -n "$clang_build" ]; then
  if ! finish_clang_build; then
    echo "== clang build: a header, benchmark or fuzzer did not build (above)" >&2
    exit 1
  fi
  t0=$SECONDS
  KINTSUGI_FUZZ_JOBS=$jobs tests/fuzz/run_fuzzers.sh build/clang "${KINTSUGI_FUZZ_SECONDS:-25}"
  echo "== fuzzed in $((SECONDS - t0)) s" >&2
fi

if ! finish_release_tests; then
  echo "== optimised suite: a test failed (above)" >&2
  exit 1
fi

if [ $sanitize -eq 1 ]; then
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:strict_string_checks=1
  export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  # The library under the sanitizers through the doctest programs; the command-line tool,
  # the examples and the packaging test (an install and a second project's build) ran
  # in the optimised suite, which keeps this build to the test programs. -g1 (line
  # tables) is what the sanitizers' reports need and compiles faster than -g. Three of
  # UBSan's checks are left out: null (a null access is a fault that ASan reports with its
  # stack), alignment and vptr (the readers, where a misaligned access could arise, are
  # fuzzed with all of UBSan above); they cost 29 % of the compile time and 27 % of the
  # memory (tests/metrics/test_distance.cpp: 154 -> 110 s of CPU, 2.46 -> 1.79 GB).
  build_suite build/asan -DCMAKE_BUILD_TYPE=Debug -DKINTSUGI_SANITIZE=address,undefined \
    -DKINTSUGI_NO_SANITIZE=null,alignment,vptr -DKINTSUGI_BUILD_EXAMPLES=OFF -DCMAKE_CXX_FLAGS_DEBUG="-O1 -g1"
  test_suite build/asan -LE consumer
fi
cpu_now
echo "== every step passed in $SECONDS s, $cpu s of CPU on $jobs cores" >&2
