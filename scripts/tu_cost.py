#!/usr/bin/env python3
"""Compile time and peak memory of every translation unit of a configured build.

Usage: scripts/tu_cost.py BUILD_DIR [--filter SUBSTRING] [--limit-s 60] [--limit-mb 2048] [-j N]

Reads BUILD_DIR/compile_commands.json (CMAKE_EXPORT_COMPILE_COMMANDS is on for the main
project), recompiles each TU once without ccache into /dev/null-like scratch objects, one
at a time (-j N: N at a time; CPU seconds stay comparable, memory bandwidth is shared),
under /usr/bin/time, and prints CPU seconds and peak resident memory, largest
first. Exits 1 when a TU exceeds the limits (issue 11: one public method header in one
TU must compile in at most 60 s and 2 GB on the 2-core CI machine).
"""
import argparse, concurrent.futures, json, os, re, shlex, subprocess, sys, tempfile

ap = argparse.ArgumentParser()
ap.add_argument("build_dir")
ap.add_argument("--filter", default="")
ap.add_argument("--limit-s", type=float, default=60.0)
ap.add_argument("--limit-mb", type=float, default=2048.0)
ap.add_argument("-j", type=int, default=1, help="TUs compiled at once")
a = ap.parse_args()

cc = json.load(open(os.path.join(a.build_dir, "compile_commands.json")))
rows = []
root = os.path.dirname(os.path.abspath(a.build_dir + "/../.."))


def measure(i, e, tmp):
    src = e["file"]
    args = shlex.split(e["command"]) if "command" in e else list(e["arguments"])
    if os.path.basename(args[0]) == "ccache":
        args = args[1:]
    # Write the object to scratch so the build tree is untouched.
    if "-o" in args:
        args[args.index("-o") + 1] = os.path.join(tmp, f"tu{i}.o")
    args = [x for x in args if not x.startswith("-MD") and x not in ("-MF",)]
    # CPU seconds (user + system): a compile is one thread, so this equals the wall
    # time on an idle machine and stays comparable when other jobs share the cores.
    cmd = ["/usr/bin/time", "-f", "%U %S %M"] + args
    p = subprocess.run(cmd, cwd=e["directory"], capture_output=True, text=True)
    last = p.stderr.strip().splitlines()[-1] if p.stderr.strip() else "0 0 0"
    m = re.match(r"([\d.]+) ([\d.]+) (\d+)", last)
    sec, kb = (float(m.group(1)) + float(m.group(2)), int(m.group(3))) if m else (0.0, 0)
    if p.returncode != 0:
        print(p.stderr[-2000:], file=sys.stderr)
    return sec, kb / 1024.0, os.path.relpath(src, root) + ("" if p.returncode == 0 else " (FAILED)")


with tempfile.TemporaryDirectory() as tmp, concurrent.futures.ThreadPoolExecutor(a.j) as pool:
    jobs = [pool.submit(measure, i, e, tmp) for i, e in enumerate(cc) if a.filter in e["file"]]
    for f in concurrent.futures.as_completed(jobs):
        rows.append(f.result())
        sec, mb, src = rows[-1]
        print(f"{sec:7.1f} s {mb:7.0f} MB  {src}", flush=True)

rows.sort(reverse=True)
print("\nlargest first:")
bad = 0
for sec, mb, src in rows:
    flag = ""
    if sec > a.limit_s or mb > a.limit_mb:
        flag, bad = "  <-- over the limit", bad + 1
    print(f"{sec:7.1f} s {mb:7.0f} MB  {src}{flag}")
print(f"\n{len(rows)} TUs, {sum(r[0] for r in rows):.0f} s in all, {bad} over {a.limit_s:.0f} s / {a.limit_mb:.0f} MB")
sys.exit(1 if bad else 0)
