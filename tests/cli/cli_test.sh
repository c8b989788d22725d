#!/usr/bin/env bash
# Behaviour of the kintsugi command-line tool: exit codes, error messages, JSON
# contract, and that a failed command writes no output file.
# Usage: cli_test.sh KINTSUGI_BINARY TEST_DATA_DIR WORK_DIR
set -u
bin=$1; data=$2; work=$3
rm -rf "$work"; mkdir -p "$work"
PY=/usr/bin/python3; [ -x "$PY" ] || PY=python3
pass=0; fail=0

ok()   { pass=$((pass + 1)); }
bad()  { fail=$((fail + 1)); echo "FAIL: $*" >&2; }

# expect CODE DESCRIPTION -- command...   (stdout -> $work/out, stderr -> $work/err)
expect() {
  local code=$1 what=$2; shift 3
  "$@" >"$work/out" 2>"$work/err"; local rc=$?
  if [ $rc -eq "$code" ]; then ok; else bad "$what: exit $rc, expected $code; stderr: $(head -c 400 "$work/err")"; fi
}
# json_check DESCRIPTION PYTHON_EXPR (j is the parsed stdout)
json_check() {
  if "$PY" -c "import json,sys; j=json.load(open('$work/out')); sys.exit(0 if ($2) else 1)" 2>/dev/null; then ok
  else bad "$1: $(head -c 600 "$work/out")"; fi
}
stderr_has() { if grep -q -- "$2" "$work/err"; then ok; else bad "$1: stderr lacks '$2': $(head -c 400 "$work/err")"; fi; }

mesh=$data/bunny.off            # closed genus-0 mesh, 1,839 vertices / 3,674 faces
open_mesh=$data/bun_zipper_res4.ply
cloud=$data/kitten.xyz

# ---- info
expect 0 "info --json" -- "$bin" info "$mesh" --json
json_check "info fields" "j['vertices']==1839 and j['faces']==3674 and j['components']==1 and j['genus']==0 and j['closed'] is True and j['boundary_loops']==0 and j['isolated_vertices']==0 and j['non_manifold_edges']==0 and 'timings' in j"
expect 0 "info human" -- "$bin" info "$open_mesh"
if grep -q "boundary loops" "$work/out"; then ok; else bad "info human output"; fi
expect 0 "info point cloud" -- "$bin" info "$cloud" --json
json_check "info point cloud fields" "j['vertices']==5210 and j['faces']==0 and j['has_normals'] is True"

# ---- errors: exit 1, clear message
expect 1 "info missing file" -- "$bin" info "$work/does_not_exist.ply"
stderr_has "missing file message" "kintsugi: error: .*does_not_exist.ply"
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n4 5 6\n' > "$work/in_truncated.ply"
expect 1 "truncated ply" -- "$bin" info "$work/in_truncated.ply"
stderr_has "truncated message" "in_truncated.ply"
printf 'OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n' > "$work/in_badindex.off"
expect 1 "face index out of range" -- "$bin" info "$work/in_badindex.off"
stderr_has "index message" "in_badindex.off"
printf 'OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n' > "$work/in_nan.off"
expect 1 "nan coordinate" -- "$bin" info "$work/in_nan.off"
: > "$work/in_empty.ply"
expect 1 "empty file" -- "$bin" info "$work/in_empty.ply"

# ---- usage errors: exit 2
expect 2 "no subcommand" -- "$bin"
expect 2 "unknown option" -- "$bin" info "$mesh" --no-such-option
expect 2 "missing argument" -- "$bin" normals "$cloud"
expect 2 "k out of range" -- "$bin" normals "$cloud" "$work/n.ply" --k 1
if [ ! -e "$work/n.ply" ]; then ok; else bad "usage error wrote a file"; fi

# ---- normals
expect 0 "normals" -- "$bin" normals "$cloud" "$work/normals.ply" --k 16 --json --threads 1
json_check "normals json" "j['points']==5210 and j['parameters']['k']==16 and 'timings' in j"
if [ -s "$work/normals.ply" ]; then ok; else bad "normals output missing"; fi
expect 0 "normals output readable" -- "$bin" info "$work/normals.ply" --json
json_check "normals output has normals" "j['vertices']==5210 and j['has_normals'] is True"
expect 1 "normals bad input" -- "$bin" normals "$work/in_nan.off" "$work/never.ply"
if [ ! -e "$work/never.ply" ]; then ok; else bad "failed normals wrote its output"; fi
expect 1 "normals unwritable output" -- "$bin" normals "$cloud" "/nonexistent-dir/x.ply"
stderr_has "unwritable message" "kintsugi: error:"

# ---- compare
expect 0 "compare X X" -- "$bin" compare "$mesh" "$mesh" --samples 20000 --json
json_check "compare X X is zero" "all(j[s][m] < 1e-9 for s in ('a_to_b','b_to_a','chamfer') for m in ('mean','rms','p99','hausdorff')) and j['chamfer']['fscore'] > 0.999"
expect 0 "compare open vs closed" -- "$bin" compare "$open_mesh" "$mesh" --samples 20000 --json
json_check "compare fields" "all(k in j[s] for s in ('a_to_b','b_to_a','chamfer') for k in ('mean','rms','p99','hausdorff','fscore'))"
expect 1 "compare against a point cloud" -- "$bin" compare "$mesh" "$cloud"

# ---- reconstruct: a far outlier is left out, far-apart objects each get a surface, any magnitude
awk 'NR<=5210' "$cloud" > "$work/kitten.xyz"
{ cat "$work/kitten.xyz"; echo "1000 0 0 1 0 0"; } > "$work/kitten_far.xyz"
expect 0 "reconstruct with a far outlier" -- "$bin" reconstruct "$work/kitten_far.xyz" "$work/far.ply" --max-level 6 --json
json_check "far outlier left out" "j['far_points']==1 and j['parts']==1 and j['components']==1 and j['closed'] and j['vertices']>500"
stderr_has "far outlier notice" "left out"
{ cat "$work/kitten.xyz"; awk '{printf "%.17g %s %s %s %s %s\n", $1+1000, $2, $3, $4, $5, $6}' "$work/kitten.xyz"; } > "$work/kittens.xyz"
expect 0 "reconstruct two far-apart objects" -- "$bin" reconstruct "$work/kittens.xyz" "$work/two.ply" --max-level 6 --json
json_check "two objects, two surfaces" "j['far_points']==0 and j['parts']==2 and j['components']==2 and j['closed']"
awk '{printf "%.17g %.17g %.17g %s %s %s\n", $1*1e200, $2*1e200, $3*1e200, $4, $5, $6}' "$work/kitten.xyz" > "$work/kitten_huge.xyz"
expect 0 "reconstruct at 1e200" -- "$bin" reconstruct "$work/kitten_huge.xyz" "$work/huge.ply" --max-level 6 --json
json_check "1e200: one closed surface" "j['components']==1 and j['closed'] and j['vertices']>500"

echo "cli: $pass passed, $fail failed"
[ $fail -eq 0 ]
