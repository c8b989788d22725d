#!/usr/bin/env bash
# Runs each reader's libFuzzer harness (fuzz_ply, fuzz_off, fuzz_obj, fuzz_xyz) for a
# fixed time, starting from the seed corpus tests/fuzz/corpus/<reader>/ (read only: new
# inputs go to <build>/fuzz-work/corpus_<reader>/). A reader stops at its first finding,
# whose input is saved under <build>/fuzz-work/findings/; the script then exits 1.
# Usage: tests/fuzz/run_fuzzers.sh BUILD_DIR [SECONDS_PER_READER=25] [libFuzzer options...]
# (BUILD_DIR configured with -DCMAKE_CXX_COMPILER=clang++ -DKINTSUGI_BUILD_FUZZ=ON).
# KINTSUGI_FUZZ_JOBS (default 1) readers are fuzzed at a time, each on one core.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=$(cd "$1" && pwd)
seconds=${2:-25}
shift $(($# < 2 ? $# : 2))
out=$build/fuzz-work
mkdir -p "$out/findings"
jobs=${KINTSUGI_FUZZ_JOBS:-1}

fuzz_reader() {
  local reader=$1; shift
  local work=$out/corpus_$reader log=$out/$reader.log
  mkdir -p "$work"
  # Inputs up to 8 KB; one allocation over 64 MB from such an input is a finding (the
  # readers bound what they allocate by the file size), and so is 10 s on one input.
  if ! "$build/tests/fuzz/fuzz_$reader" "$work" "$here/corpus/$reader" -dict="$here/$reader.dict" \
      -max_total_time="$seconds" -max_len=8192 -malloc_limit_mb=64 -rss_limit_mb=2048 -timeout=10 \
      -artifact_prefix="$out/findings/$reader-" -print_final_stats=1 "$@" >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    echo "fuzz_$reader: FINDING (input in $out/findings/, log $log)" >&2
    return 1
  fi
  local runs
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
  echo "fuzz_$reader: ${runs:-?} executions in $seconds s, no finding"
}

status=0
running=0
for reader in ply off obj xyz; do
  if [ "$running" -ge "$jobs" ]; then
    wait -n || status=1
    running=$((running - 1))
  fi
  fuzz_reader "$reader" "$@" &
  running=$((running + 1))
done
while [ "$running" -gt 0 ]; do
  wait -n || status=1
  running=$((running - 1))
done
exit $status
