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

# ---- glibc's allocator keeping freed memory (kintsugi::use_kept_heap_malloc re-executes the tool
# once with GLIBC_TUNABLES set, keeping the arguments and other tunables; opt-out variable)
if ldd --version 2>&1 | grep -qi glibc; then
  expect 0 "info, kept-heap malloc" -- env -u KINTSUGI_DEFAULT_MALLOC -u GLIBC_TUNABLES "$bin" info "$mesh" --json
  json_check "kept_heap_malloc on" "j['kept_heap_malloc'] is True and j['vertices']==1839"
  expect 0 "info, other tunables kept" -- env -u KINTSUGI_DEFAULT_MALLOC GLIBC_TUNABLES=glibc.malloc.check=0 "$bin" info "$mesh" --json
  json_check "kept_heap_malloc with other tunables" "j['kept_heap_malloc'] is True and j['faces']==3674"
else
  echo "SKIPPED: kept-heap malloc checks (not glibc)" >&2
fi
expect 0 "info, kept-heap malloc off" -- env -u GLIBC_TUNABLES KINTSUGI_DEFAULT_MALLOC=1 "$bin" info "$mesh" --json
json_check "kept_heap_malloc off" "j['kept_heap_malloc'] is False and j['vertices']==1839"

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

# ---- reconstruct: a far outlier is left out, far-apart objects each get a surface, any magnitude;
# the kitten's real handle (genus 1, its tail) is kept by the handle cut
awk 'NR<=5210' "$cloud" > "$work/kitten.xyz"
{ cat "$work/kitten.xyz"; echo "1000 0 0 1 0 0"; } > "$work/kitten_far.xyz"
expect 0 "reconstruct with a far outlier" -- "$bin" reconstruct "$work/kitten_far.xyz" "$work/far.ply" --max-level 6 --json
json_check "far outlier left out" "j['far_points']==1 and j['parts']==1 and j['components']==1 and j['closed'] and j['vertices']>500 and j['genus']==1 and j['handles_removed']==0 and j['parameters']['max_handle_loop']==10"
stderr_has "far outlier notice" "left out"
{ cat "$work/kitten.xyz"; awk '{printf "%.17g %s %s %s %s %s\n", $1+1000, $2, $3, $4, $5, $6}' "$work/kitten.xyz"; } > "$work/kittens.xyz"
expect 0 "reconstruct two far-apart objects" -- "$bin" reconstruct "$work/kittens.xyz" "$work/two.ply" --max-level 6 --json
json_check "two objects, two surfaces" "j['far_points']==0 and j['parts']==2 and j['components']==2 and j['closed']"
awk '{printf "%.17g %.17g %.17g %s %s %s\n", $1*1e200, $2*1e200, $3*1e200, $4, $5, $6}' "$work/kitten.xyz" > "$work/kitten_huge.xyz"
expect 0 "reconstruct at 1e200" -- "$bin" reconstruct "$work/kitten_huge.xyz" "$work/huge.ply" --max-level 6 --json
json_check "1e200: one closed surface" "j['components']==1 and j['closed'] and j['vertices']>500"
# ---- reconstruct --method rbf: defaults from RBFOctreeParams, one closed surface, the paper's evaluation
expect 0 "reconstruct --method rbf" -- "$bin" reconstruct "$work/kitten.xyz" "$work/rbf.ply" --method rbf --resolution 64 --json
json_check "rbf: closed surface and counts" "j['parameters']['method']=='rbf' and j['parameters']['n_max']==100 and abs(j['parameters']['overlap']-1.35)<1e-12 and abs(j['parameters']['activity']-1.05)<1e-12 and j['parameters']['smoothing']==0 and j['parameters']['blend'] is True and j['points']==5210 and j['live_cells']>0 and j['live_cells']+j['dead_cells']==j['cells'] and j['max_points_per_cell']<=120 and j['ill_conditioned_cells']==0 and j['capped_cells']==0 and j['capped_centres']==0 and j['padded_cells']<=j['live_cells'] and 0<=j['crease_offsets']<=2*j['points'] and j['components']==1 and j['closed'] and j['manifold'] and j['vertices']>1000 and 'rbf_solve' in j['timings']"
expect 0 "reconstruct --method rbf --no-blend --smoothing" -- "$bin" reconstruct "$work/kitten.xyz" "$work/rbf2.ply" --method rbf --resolution 48 --no-blend --smoothing 0.01 --n-max 60 --json
json_check "rbf: options reach the fit" "j['parameters']['blend'] is False and j['parameters']['smoothing']==0.01 and j['parameters']['n_max']==60 and j['max_points_per_cell']<=80 and j['closed']"
expect 0 "reconstruct --method rbf, normals estimated" -- "$bin" reconstruct "$mesh" "$work/rbf3.ply" --method rbf --resolution 32 --json
json_check "rbf: estimated normals" "j['normals_estimated'] is True and j['points']==1839 and j['faces']>0"
# Two unit spheres 1000 apart: at --resolution 32 a cube is about 31 wide and the RBF surface
# falls between its samples; an empty mesh is an error, not a result.
"$PY" -c "
import math
for c in (0, 1000):
    for i in range(400):
        z = 1 - 2 * (i + 0.5) / 400; r = math.sqrt(1 - z * z); t = i * 2.399963
        x, y = r * math.cos(t), r * math.sin(t)
        print(x + c, y, z, x, y, z)
" > "$work/two_spheres.xyz"
expect 1 "reconstruct --method rbf, surface between the cubes" -- "$bin" reconstruct "$work/two_spheres.xyz" "$work/rbf_empty.ply" --method rbf --resolution 32
stderr_has "rbf empty surface message" "no surface was found at --resolution 32"
if [ -e "$work/rbf_empty.ply" ]; then bad "rbf empty surface: an output file was written"; else ok; fi

# ---- upsample: surfels with a radius property; a filled set needs nothing more; bad radius
expect 0 "upsample --json" -- "$bin" upsample "$cloud" "$work/surfels.ply" --radius-rel 0.01 --json
json_check "upsample fields" "j['input_surfels']==5210 and j['surfels']>5210 and j['new_surfels']==j['surfels']-5210 and j['coverage_verified'] is True and j['level_counts']==[j['surfels']] and j['input_had_radii'] is False and j['uncovered_surfels']==[]"
if head -c 400 "$work/surfels.ply" | grep -q "property double radius"; then ok; else bad "upsample output has no radius property"; fi
expect 0 "upsample of a filled set" -- "$bin" upsample "$work/surfels.ply" "$work/surfels2.ply" --radius-rel 0.01 --json
json_check "filled set unchanged" "j['input_had_radii'] is True and j['new_surfels']==0 and j['coverage_verified'] is True"
expect 0 "upsample levels" -- "$bin" upsample "$cloud" "$work/lod.ply" --radius-rel 0.02 --levels 3 --json
json_check "upsample level counts" "len(j['level_counts'])==3 and j['level_counts'][0]<j['level_counts'][1]<j['level_counts'][2]==j['surfels']"
# an open surface (bun_zipper_res4's bottom holes): the border's surfels are listed, indices into OUT
expect 0 "normals for open upsample" -- "$bin" normals "$open_mesh" "$work/open_points.ply"
expect 0 "upsample open surface" -- "$bin" upsample "$work/open_points.ply" "$work/open_surfels.ply" --radius-rel 0.02 --json
json_check "upsample uncovered surfels" "j['coverage_verified'] is False and len(j['uncovered_surfels'])>0 and j['uncovered_surfels']==sorted(set(j['uncovered_surfels'])) and j['uncovered_surfels'][-1]<j['surfels']"
stderr_has "upsample uncovered notice" "uncovered_surfels"
expect 2 "upsample without a radius" -- "$bin" upsample "$cloud" "$work/u.ply"
stderr_has "upsample radius message" "radius"
expect 2 "upsample both radii" -- "$bin" upsample "$cloud" "$work/u.ply" --radius 0.1 --radius-rel 0.01
expect 2 "upsample negative radius" -- "$bin" upsample "$cloud" "$work/u.ply" --radius -1
expect 1 "upsample without normals" -- "$bin" upsample "$mesh" "$work/u.ply" --radius 0.1
stderr_has "upsample normals message" "no normals"
if [ ! -e "$work/u.ply" ]; then ok; else bad "failed upsample wrote a file"; fi

# ---- option values: checked while parsing, before any input is read; exit 2, the option named
missing=$work/no_such_input.ply
usage() {  # usage DESCRIPTION OPTION -- command...: exit 2, stderr names OPTION, within 20 s
  local what=$1 opt=$2; shift 3
  expect 2 "$what" -- timeout 20 "$@"
  stderr_has "$what names the option" "$opt"
}
usage "normals --k nan" "--k" -- "$bin" normals "$cloud" "$work/o.ply" --k nan
usage "normals --k -1" "--k" -- "$bin" normals "$cloud" "$work/o.ply" --k -1
usage "normals jet --k 3" "--k" -- "$bin" normals "$missing" "$work/o.ply" --method jet --k 3
stderr_has "jet message" "jet"
usage "reconstruct --epsilon nan" "--epsilon" -- "$bin" reconstruct "$missing" "$work/o.ply" --epsilon nan
usage "reconstruct --k nan" "--k" -- "$bin" reconstruct "$missing" "$work/o.ply" --k nan
usage "reconstruct --k inf" "--k" -- "$bin" reconstruct "$missing" "$work/o.ply" --k inf
usage "reconstruct --max-handle-loop -1" "--max-handle-loop" -- "$bin" reconstruct "$missing" "$work/o.ply" --max-handle-loop -1
usage "reconstruct rbf --max-handle-loop" "--max-handle-loop" -- "$bin" reconstruct "$missing" "$work/o.ply" --method rbf --max-handle-loop 5
usage "reconstruct --refine-spacing -1" "--refine-spacing" -- "$bin" reconstruct "$missing" "$work/o.ply" --refine-spacing -1
usage "reconstruct --refine-neighbors 3" "--refine-neighbors" -- "$bin" reconstruct "$missing" "$work/o.ply" --refine-neighbors 3
usage "reconstruct rbf --refine-spacing" "--refine-spacing" -- "$bin" reconstruct "$missing" "$work/o.ply" --method rbf --refine-spacing 1
usage "reconstruct --smoothing -1" "--smoothing" -- "$bin" reconstruct "$missing" "$work/o.ply" --smoothing -1
usage "reconstruct --max-level 1.5" "--max-level" -- "$bin" reconstruct "$missing" "$work/o.ply" --max-level 1.5
usage "reconstruct rbf --n-max 9" "--n-max" -- "$bin" reconstruct "$missing" "$work/o.ply" --method rbf --n-max 9
usage "reconstruct rbf --overlap 0.9" "--overlap" -- "$bin" reconstruct "$missing" "$work/o.ply" --method rbf --overlap 0.9
usage "reconstruct rbf --activity nan" "--activity" -- "$bin" reconstruct "$missing" "$work/o.ply" --method rbf --activity nan
usage "reconstruct rbf --resolution 4" "--resolution" -- "$bin" reconstruct "$missing" "$work/o.ply" --method rbf --resolution 4
usage "reconstruct rbf --max-level" "--max-level" -- "$bin" reconstruct "$missing" "$work/o.ply" --method rbf --max-level 6
stderr_has "option of the other method" "does not apply to --method rbf"
usage "reconstruct pu-graphcut --n-max" "--n-max" -- "$bin" reconstruct "$missing" "$work/o.ply" --n-max 100
usage "reconstruct pu-graphcut --smoothing 1.5" "--smoothing" -- "$bin" reconstruct "$missing" "$work/o.ply" --smoothing 1.5
usage "perturb --noise nan" "--noise" -- "$bin" perturb "$cloud" "$work/o.ply" --noise nan
usage "perturb --outliers nan" "--outliers" -- "$bin" perturb "$cloud" "$work/o.ply" --outliers nan
usage "perturb --seed -1" "--seed" -- "$bin" perturb "$cloud" "$work/o.ply" --seed -1
usage "smooth --a 0 (before reading)" "--a" -- "$bin" smooth "$missing" "$work/o.ply" --a 0
usage "smooth --d nan" "--d" -- "$bin" smooth "$missing" "$work/o.ply" --d nan
usage "smooth --edge-threshold 2" "--edge-threshold" -- "$bin" smooth "$missing" "$work/o.ply" --edge-threshold 2
usage "smooth --face-iterations -1" "--face-iterations" -- "$bin" smooth "$missing" "$work/o.ply" --face-iterations -1
usage "smooth --features with --no-features" "--features" -- "$bin" smooth "$missing" "$work/o.ply" --features "$work/f.ply" --no-features
usage "smooth --preset bogus" "--preset" -- "$bin" smooth "$missing" "$work/o.ply" --preset bogus
usage "smooth --lowpass-noise 2" "--lowpass-noise" -- "$bin" smooth "$missing" "$work/o.ply" --lowpass-noise 2
usage "smooth --lowpass-iterations -1" "--lowpass-iterations" -- "$bin" smooth "$missing" "$work/o.ply" --lowpass-iterations -1
usage "compare --samples 100000000" "--samples" -- "$bin" compare "$missing" "$missing" --samples 100000000
usage "compare --threshold nan" "--threshold" -- "$bin" compare "$missing" "$missing" --threshold nan
if [ ! -e "$work/o.ply" ]; then ok; else bad "a usage error wrote an output"; fi
expect 0 "perturb, largest seed" -- "$bin" perturb "$cloud" "$work/seed.xyz" --seed 18446744073709551615 --json
json_check "seed reported unwrapped" "j['parameters']['seed'] == 18446744073709551615"
# The help shows the library's defaults.
expect 0 "reconstruct --help" -- "$bin" reconstruct --help
if grep -Eq -- "--smoothing [^=]*=30( |$)" "$work/out" && grep -Eq -- "--epsilon [^=]*=0.004( |$)" "$work/out"; then ok; else bad "reconstruct help defaults: $(grep -- '--smoothing\|--epsilon' "$work/out")"; fi
if grep -Eq -- "--n-max [^=]*=100( |$)" "$work/out" && grep -Eq -- "--overlap [^=]*=1.35( |$)" "$work/out" && grep -Eq -- "--resolution [^=]*=256( |$)" "$work/out"; then ok; else bad "reconstruct rbf help defaults: $(grep -- '--n-max\|--overlap\|--resolution' "$work/out")"; fi

# ---- complete: bunny.off with one hole cut around vertex 300 (faces whose centroid is within 6 % of the diagonal)
"$PY" - "$mesh" "$work/holey.off" <<'PYEOF'
import sys, math
t = open(sys.argv[1]).read().split(); nv, nf = int(t[1]), int(t[2]); p = 4
V = [tuple(map(float, t[p + 3 * i:p + 3 * i + 3])) for i in range(nv)]; p += 3 * nv
F = [tuple(map(int, t[p + 4 * i + 1:p + 4 * i + 4])) for i in range(nf)]
diag = math.dist([min(v[j] for v in V) for j in range(3)], [max(v[j] for v in V) for j in range(3)])
keep = [f for f in F if math.dist([sum(V[i][j] for i in f) / 3 for j in range(3)], V[300]) >= 0.06 * diag]
used = sorted({i for f in keep for i in f}); m = {v: k for k, v in enumerate(used)}
with open(sys.argv[2], "w") as o:
    o.write("OFF\n%d %d 0\n" % (len(used), len(keep)))
    o.writelines("%r %r %r\n" % V[v] for v in used)
    o.writelines("3 %d %d %d\n" % tuple(m[i] for i in f) for f in keep)
PYEOF
expect 0 "info of the holey bunny" -- "$bin" info "$work/holey.off" --json
json_check "one hole cut" "j['boundary_loops']==1"
expect 0 "complete --json" -- "$bin" complete "$work/holey.off" "$work/completed.ply" --json
json_check "complete fields" "j['command']=='complete' and j['filled_holes']==1 and j['new_vertices']>10 and j['vertices']==1823+j['new_vertices'] and len(j['energy'])==3 and all(all(a>=b for a,b in zip(l,l[1:])) for l in j['energy']) and 'level 3' in j['timings']"
json_check "complete per-hole fields" "len(j['example_weight'])==1 and 0<=j['example_weight'][0]<=1 and j['hole_status']==['completed']"
expect 0 "completed mesh is closed" -- "$bin" info "$work/completed.ply" --json
json_check "completed topology" "j['closed'] is True and j['boundary_loops']==0 and j['non_manifold_edges']==0 and j['genus']==0"
expect 0 "complete, explosion guard forced" -- "$bin" complete "$work/holey.off" "$work/reverted.ply" --max-patch-growth 0.001 --json
json_check "guard reverts the hole" "j['filled_holes']==1 and j['hole_status']==['vertex_bound'] and j['example_weight']==[0] and j['new_vertices']>10"
expect 0 "reverted mesh is closed" -- "$bin" info "$work/reverted.ply" --json
json_check "reverted topology" "j['closed'] is True and j['boundary_loops']==0 and j['non_manifold_edges']==0 and j['genus']==0"
expect 0 "complete, hole too large for --max-hole-size" -- "$bin" complete "$work/holey.off" "$work/same.off" --max-hole-size 0.01 --json
json_check "nothing filled" "j['filled_holes']==0 and j['new_vertices']==0"
expect 1 "complete on a non-manifold mesh" -- "$bin" complete "$open_mesh" "$work/nm.ply"
stderr_has "non-manifold named" "complete_holes_example_based: .*non-manifold\\|complete_holes_example_based: .*more than two faces"
if [ ! -e "$work/nm.ply" ]; then ok; else bad "failed complete wrote its output"; fi
usage "complete --max-hole-size 0" "--max-hole-size" -- "$bin" complete "$missing" "$work/o.ply" --max-hole-size 0
usage "complete --initial disk" "--initial" -- "$bin" complete "$missing" "$work/o.ply" --initial disk
usage "complete --s 1" "--s" -- "$bin" complete "$missing" "$work/o.ply" --s 1

# ---- outputs are checked before any input is read (the error names the output)
expect 1 "unwritable output checked first" -- "$bin" normals "$missing" "/nonexistent-dir/x.ply"
stderr_has "unwritable output named" "/nonexistent-dir/x.ply"
expect 1 "mesh output extension checked first" -- "$bin" reconstruct "$missing" "$work/o.xyz"
stderr_has "extension message" "unsupported extension '.xyz' for a mesh"
expect 1 "features extension checked first" -- "$bin" smooth "$missing" "$work/o.ply" --features "$work/f.off"
stderr_has "features extension message" "f.off"

# ---- nothing is written when a command fails
ln -s /dev/full "$work/full.ply"
expect 1 "smooth, main output fails on write" -- "$bin" smooth "$mesh" "$work/full.ply" --features "$work/feat.ply" --face-iterations 1
stderr_has "disk full message" "full.ply"
if [ ! -e "$work/feat.ply" ]; then ok; else bad "failed smooth wrote its --features file"; fi
expect 0 "smooth with features" -- "$bin" smooth "$mesh" "$work/sm.off" --features "$work/feat.ply" --face-iterations 1 --json
if [ -s "$work/sm.off" ] && [ -s "$work/feat.ply" ]; then ok; else bad "smooth outputs missing"; fi
json_check "smooth: noise estimate and the values used in --json" "j['noise']['sigma']>0 and j['noise']['vertices_used']==1839 and j['noise']['quadric_sigma']>=j['noise']['sigma'] and j['noise']['difference_sigma']>=0 and j['parameters']['d_from_noise'] is True and j['parameters']['d']>=0.14 and j['parameters']['face_iterations']==1 and j['parameters']['face_iterations_from_noise'] is False and j['parameters']['normal_iterations']==3 and j['parameters']['normal_iterations_from_noise'] is True and j['parameters']['strong_noise'] is False and j['parameters']['detection_presmooth_iterations']==3 and j['parameters']['lowpass_noise']==0.2 and j['parameters']['lowpass_iterations_from_noise'] is True and j['noise']['after_lowpass']['sigma']<=j['noise']['sigma'] and j['parameters']['coplanar_creases'] is True and j['anchored_faces']>=0 and 0<=j['coplanar_sharp_edges']<=j['sharp_edges'] and j['parameters']['straight_creases'] is True and 0<=j['straight_sharp_edges']<=j['sharp_edges'] and j['held_vertices']>=0"
expect 0 "smooth --lowpass-iterations 3 --lowpass-noise 0" -- "$bin" smooth "$mesh" "$work/sm5.off" --lowpass-iterations 3 --lowpass-noise 0 --face-iterations 1 --json
json_check "smooth: the low-pass steps given" "j['parameters']['lowpass_iterations']==3 and j['parameters']['lowpass_iterations_from_noise'] is False and j['parameters']['lowpass_noise']==0"
expect 0 "smooth --no-coplanar-creases" -- "$bin" smooth "$mesh" "$work/sm6.off" --no-coplanar-creases --face-iterations 1 --json
json_check "smooth: the coplanar stage off" "j['parameters']['coplanar_creases'] is False and j['anchored_faces']==0 and j['coplanar_sharp_edges']==0 and j['held_vertices']==0"
expect 0 "smooth --no-straight-creases" -- "$bin" smooth "$mesh" "$work/sm7.off" --no-straight-creases --face-iterations 1 --json
json_check "smooth: the straight-crease detection off" "j['parameters']['straight_creases'] is False and j['straight_sharp_edges']==0"
expect 0 "smooth with explicit d and face iterations" -- "$bin" smooth "$mesh" "$work/sm2.off" --d 0.2 --face-iterations 2 --json
json_check "smooth: explicit values win, no estimate" "j['parameters']['d']==0.2 and j['parameters']['face_iterations']==2 and j['parameters']['d_from_noise'] is False and 'noise' not in j and j['parameters']['normal_iterations']==10 and j['parameters']['normal_iterations_from_noise'] is False"
expect 0 "smooth --preset paper" -- "$bin" smooth "$mesh" "$work/sm3.off" --preset paper --json
json_check "smooth: the paper's values, no estimate" "j['parameters']['preset']=='paper' and j['parameters']['a']==2 and j['parameters']['c']==2 and j['parameters']['d']==0.1 and j['parameters']['face_iterations']==2 and j['parameters']['edge_threshold']==0.251 and j['parameters']['normal_iterations']==1 and j['parameters']['lowpass_iterations']==0 and 'noise' not in j and j['parameters']['coplanar_creases'] is False and j['anchored_faces']==0 and j['parameters']['straight_creases'] is False and j['straight_sharp_edges']==0 and j['parameters']['risk_selection'] is False and 'risk_selection' not in j and j['parameters']['impulse_removal'] is False"
expect 0 "smooth --preset paper --c 1 --face-iterations 1" -- "$bin" smooth "$mesh" "$work/sm4.off" --preset paper --c 1 --face-iterations 1 --json
json_check "smooth: options given override the preset" "j['parameters']['preset']=='paper' and j['parameters']['c']==1 and j['parameters']['face_iterations']==1 and j['parameters']['d']==0.1"
# Noisy bunnies: SRC DST SEED FRACTION SIGMA moves each vertex (or, with FRACTION < 1, that
# fraction of them, drawn first) in a random direction by a seeded Gaussian amount of SIGMA |e|.
cat > "$work/noisy_mesh.py" <<'PYEOF'
import math, random, sys
tok = open(sys.argv[1]).read().split()
nv, nf = int(tok[1]), int(tok[2])
V = [[float(t) for t in tok[4 + 3 * i:7 + 3 * i]] for i in range(nv)]
F = [[int(t) for t in tok[4 + 3 * nv + 4 * j + 1:4 + 3 * nv + 4 * j + 4]] for j in range(nf)]
L = sum(math.dist(V[f[a]], V[f[(a + 1) % 3]]) for f in F for a in range(3)) / (3 * nf)
rng = random.Random(int(sys.argv[3]))
fraction, sigma = float(sys.argv[4]), float(sys.argv[5])
out = ["OFF", "%d %d 0" % (nv, nf)]
for p in V:
    d = [rng.gauss(0, 1) for _ in range(3)]
    n = math.sqrt(sum(x * x for x in d)) or 1
    s = rng.gauss(0, sigma * L) if fraction >= 1 or rng.random() < fraction else 0.0
    out.append(" ".join(repr(p[k] + s * d[k] / n) for k in range(3)))
out += ["3 %d %d %d" % tuple(f) for f in F]
open(sys.argv[2], "w").write("\n".join(out) + "\n")
PYEOF
# Risk selection: the bunny with Gaussian noise of 0.5|e| in random directions (a smooth
# shape: Taubin's result kept), the clean Twelve (exact planes hold vertices: not compared).
"$PY" "$work/noisy_mesh.py" "$mesh" "$work/noisy_bunny.off" 7 1 0.5
expect 0 "smooth --risk-selection (noisy bunny)" -- "$bin" smooth "$work/noisy_bunny.off" "$work/sm_risk.off" --risk-selection --json
json_check "smooth: risk selection keeps Taubin's result on the noisy bunny" "j['parameters']['risk_selection'] is True and j['risk_selection']['evaluated'] is True and j['risk_selection']['result']=='taubin' and j['risk_selection']['taubin_iterations']>0 and 0<j['risk_selection']['taubin_rms']**2<0.75*j['risk_selection']['filters_rms']**2 and 0<j['risk_selection']['sigma']<=1.1*j['noise']['sigma'] and j['risk_selection']['note']=='' and 'risk: Taubin sweep' in j['timings'] and j['risk_selection']['normal_veto'] is False and j['risk_selection']['normal_difference']<0.03 and 'normal_z' in j['risk_selection'] and j['risk_selection']['coarse'] is False and j['risk_selection']['recheck'] is False and j['risk_selection']['recheck_probes']==0"
expect 0 "smooth --risk-selection (clean Twelve)" -- "$bin" smooth "$data/twelve.obj" "$work/sm_risk2.off" --risk-selection --json
json_check "smooth: risk selection not compared on the clean Twelve (held vertices)" "j['risk_selection']['evaluated'] is False and j['risk_selection']['result']=='filters' and 'held' in j['risk_selection']['note'] and j['held_vertices']>0"
expect 0 "smooth (noisy bunny, defaults)" -- "$bin" smooth "$work/noisy_bunny.off" "$work/sm_risk3.off" --json
json_check "smooth: the risk selection runs by default" "j['parameters']['risk_selection'] is True and j['risk_selection']['result']=='taubin'"
json_check "smooth: noise in random directions unfolds folded faces first" "j['parameters']['untangle'] is True and j['untangle']['tangential_noise'] is True and j['untangle']['ratio']>1.2 and j['untangle']['folded_faces']>0 and j['untangle']['moved_vertices']>0 and j['untangle']['impulsive'] is False and 'reference_angle_deg' in j['untangle'] and 'untangle' in j['timings']"
expect 0 "smooth --no-untangle" -- "$bin" smooth "$work/noisy_bunny.off" "$work/sm_nountangle.off" --no-untangle --json
json_check "smooth: --no-untangle leaves the folds to the filters" "j['parameters']['untangle'] is False and 'untangle' not in j"
if cmp -s "$work/sm_risk3.off" "$work/sm_nountangle.off"; then bad "smooth: --no-untangle wrote the same mesh"; else ok; fi
if cmp -s "$work/sm_risk.off" "$work/sm_risk3.off"; then ok; else bad "smooth: defaults and --risk-selection wrote different meshes"; fi
expect 0 "smooth --no-risk-selection" -- "$bin" smooth "$work/noisy_bunny.off" "$work/sm_norisk.off" --no-risk-selection --json
json_check "smooth: --no-risk-selection keeps the filters" "j['parameters']['risk_selection'] is False and 'risk_selection' not in j"
if cmp -s "$work/sm_risk.off" "$work/sm_norisk.off"; then bad "smooth: --no-risk-selection wrote Taubin's result"; else ok; fi
expect 2 "smooth --risk-selection --no-risk-selection" -- "$bin" smooth "$work/noisy_bunny.off" "$work/sm_both.off" --risk-selection --no-risk-selection
if [ -e "$work/sm_both.off" ]; then bad "smooth: contradictory risk flags wrote a file"; else ok; fi
# Impulse removal: the bunny with one vertex in ten moved by |e| (put back; the rest held), and
# the same without the stage.
"$PY" "$work/noisy_mesh.py" "$mesh" "$work/impulsive_bunny.off" 11 0.1 1
expect 0 "smooth (impulsive bunny)" -- "$bin" smooth "$work/impulsive_bunny.off" "$work/sm_imp.off" --json
json_check "smooth: impulses put back, the rest held, the input's noise reported" "j['parameters']['impulse_removal'] is True and j['impulses']['impulsive'] is True and j['impulses']['put_back']>0 and j['impulses']['dense'] is False and j['held_vertices']>j['impulses']['put_back'] and j['impulses']['input_noise']['relative']>j['noise']['relative'] and 'impulses' in j['timings'] and 'impulsive' in j['risk_selection']['note'] and j['untangle']['moved_vertices']==0"
expect 0 "smooth --no-impulse-removal (impulsive bunny)" -- "$bin" smooth "$work/impulsive_bunny.off" "$work/sm_noimp.off" --no-impulse-removal --json
json_check "smooth: --no-impulse-removal leaves the impulses to the filters" "j['parameters']['impulse_removal'] is False and 'impulses' not in j"
if cmp -s "$work/sm_imp.off" "$work/sm_noimp.off"; then bad "smooth: --no-impulse-removal wrote the same mesh"; else ok; fi
expect 0 "smooth (noisy bunny, Gaussian): no impulses" -- "$bin" smooth "$work/noisy_bunny.off" "$work/sm_gimp.off" --json
json_check "smooth: Gaussian noise is not impulsive" "j['impulses']['impulsive'] is False and j['impulses']['put_back']==0 and j['impulses']['input_noise']['sigma']==j['noise']['sigma']"

# ---- output paths: symbolic links and devices written through, long names
mkdir -p "$work/real"
printf 'old' > "$work/real/target.ply"
ln -s real/target.ply "$work/link.ply"
expect 0 "output through a symlink" -- "$bin" normals "$cloud" "$work/link.ply" --k 10
if [ -L "$work/link.ply" ] && [ "$(head -c 3 "$work/real/target.ply")" = "ply" ]; then ok; else bad "symlink output replaced or target unchanged"; fi
ln -s /dev/null "$work/null.ply"
expect 0 "output to /dev/null through a symlink" -- "$bin" perturb "$cloud" "$work/null.ply"
if [ -L "$work/null.ply" ] && [ -c /dev/null ]; then ok; else bad "/dev/null symlink replaced"; fi
long=$(printf 'n%.0s' $(seq 246)).ply
expect 0 "250-character output name" -- "$bin" perturb "$cloud" "$work/$long"
if [ -s "$work/$long" ]; then ok; else bad "250-character output missing"; fi
if [ -z "$(find "$work" -name '*.tmp')" ]; then ok; else bad "temporary files left: $(find "$work" -name '*.tmp')"; fi

# ---- messages
expect 0 "reconstruct without normals" -- "$bin" reconstruct "$mesh" "$work/rec.ply" --max-level 6
if ! grep -q "kintsugi: kintsugi:" "$work/err"; then ok; else bad "doubled prefix: $(head -c 300 "$work/err")"; fi
stderr_has "normals notice" "has no normals; estimating"
esc=$(printf '\033')
expect 1 "control characters in a file name are escaped" -- "$bin" info "$work/bad${esc}[31mname.ply"
if ! grep -q "$esc" "$work/err"; then ok; else bad "raw escape byte echoed"; fi
stderr_has "escaped name" 'bad\\x1B\[31mname.ply'
printf 'OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n' > "$work/tri.off"
expect 1 "out of memory is named" -- bash -c "ulimit -v 600000; exec \"$bin\" compare \"$mesh\" \"$mesh\" --samples 10000000 --threads 1"
stderr_has "out of memory message" "out of memory while comparing"
if ! grep -q "bad_alloc" "$work/err"; then ok; else bad "bare bad_alloc"; fi

# ---- Ctrl-C and SIGTERM: exit 128 + signal soon, no output, no temporary file
# no_leftovers NAME: neither NAME nor a temporary file of it in $work
no_leftovers() {
  if [ ! -e "$work/$1" ] && [ -z "$(find "$work" -maxdepth 1 -name ".$1.*.tmp")" ]; then ok
  else bad "interrupted run left $(ls -a "$work" | grep -F "$1" | tr '\n' ' ')"; fi
}
# interrupt SIGNAL WHEN EXPECTED_EXIT DESCRIPTION -- command...
# WHEN: seconds to wait, or tmp:NAME to wait until NAME's temporary file exists (the write has begun)
interrupt() {
  local sig=$1 when=$2 code=$3 what=$4; shift 5
  "$@" >"$work/out" 2>"$work/err" &
  local pid=$! t0=$SECONDS
  case $when in
    # A shell glob, not find: polled every 10 ms without a fork, so that even a short
    # write is seen. If the command ends first, the test says so (it cannot interrupt).
    tmp:*) local seen=0
           for _ in $(seq 3000); do
             compgen -G "$work/.${when#tmp:}.*.tmp" >/dev/null && { seen=1; break; }
             kill -0 $pid 2>/dev/null || break
             sleep 0.01
           done
           [ $seen -eq 1 ] || bad "$what: the write's temporary file was never seen (the command ended or never wrote)" ;;
    *) sleep "$when" ;;
  esac
  kill -s "$sig" $pid 2>/dev/null
  wait $pid; local rc=$?
  if [ $rc -eq "$code" ]; then ok; else bad "$what: exit $rc, expected $code; stderr: $(head -c 300 "$work/err")"; fi
  if [ $((SECONDS - t0)) -le 15 ]; then ok; else bad "$what: took $((SECONDS - t0)) s to stop"; fi
}
"$bin" perturb "$cloud" "$work/big1.ply" --outliers 10 --seed 1 -q &&
  "$bin" perturb "$work/big1.ply" "$work/big.ply" --outliers 10 --seed 2 -q   # 630,410 points
interrupt INT 1 130 "Ctrl-C during reconstruct" -- "$bin" reconstruct "$work/big.ply" "$work/int_rec.ply" --max-level 9
stderr_has "interrupted message" "interrupted by SIGINT"
no_leftovers int_rec.ply
interrupt TERM 1 143 "SIGTERM during reconstruct" -- "$bin" reconstruct "$work/big.ply" "$work/term_rec.ply" --max-level 9
no_leftovers term_rec.ply
# perturb: 630K points -> 4.4M (0.4 s of loops, then a 528 MB XYZ written in about 1.3 s
# here): the signal lands in its loops, or in the write.
interrupt INT 0.4 130 "Ctrl-C during perturb" -- "$bin" perturb "$work/big.ply" "$work/int_pert.xyz" --outliers 6 --noise 0.01
no_leftovers int_pert.xyz
# The writes: a binary PLY (212 MB, about 0.3 s here) and an XYZ file, whose text takes
# about 1.3 s to format, so that the signal surely lands inside the write.
interrupt TERM tmp:term_pert.ply 143 "SIGTERM during perturb's write" -- "$bin" perturb "$work/big.ply" "$work/term_pert.ply" --outliers 6 --noise 0.01
stderr_has "SIGTERM message" "interrupted by SIGTERM"
no_leftovers term_pert.ply
interrupt INT tmp:int_write.xyz 130 "Ctrl-C during perturb's write" -- "$bin" perturb "$work/big.ply" "$work/int_write.xyz" --outliers 6
no_leftovers int_write.xyz
rm -f "$work/big1.ply" "$work/big.ply"

echo "cli: $pass passed, $fail failed"
[ $fail -eq 0 ]
