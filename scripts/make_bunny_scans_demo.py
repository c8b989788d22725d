#!/usr/bin/env python3
# This Source Code Form is subject to the terms of the Mozilla Public
# License, v. 2.0. If a copy of the MPL was not distributed with this
# file, You can obtain one at https://mozilla.org/MPL/2.0/.
"""Builds data/bunny_scans_100k.ply from the 9 registered Stanford bunny range scans.

How data/bunny_scans_100k.ply was made (run once; the output is shipped in the repo):
    python3 scripts/make_bunny_scans_demo.py ../shared/data/stanford_bunny/scans data/bunny_scans_100k.ply

1. Read the vertices (x y z nx ny nz, float32) of the 9 scans, in alphabetical file
   order, every vertex in file order; the triangle lists are ignored.
2. Keep 100,000 of the 327,000 points, drawn without replacement by Python's
   random.Random(20091109).sample (Mersenne Twister, fixed seed), in original order.
3. Write them as binary little-endian PLY, float32 x y z nx ny nz.
Standard library only (no numpy).
"""
import os
import random
import struct
import sys


def read_scan(path):
    with open(path, "rb") as fh:
        header = []
        while True:
            line = fh.readline().decode("ascii").strip()
            header.append(line)
            if line == "end_header":
                break
        nv = 0
        props = []
        in_vertex = False
        for line in header:
            parts = line.split()
            if parts[:2] == ["element", "vertex"]:
                nv = int(parts[2])
                in_vertex = True
            elif parts[:1] == ["element"]:
                in_vertex = False
            elif in_vertex and parts[:1] == ["property"]:
                props.append((parts[1], parts[2]))
        if props != [("float", n) for n in ("x", "y", "z", "nx", "ny", "nz")]:
            raise SystemExit(f"{path}: unexpected vertex properties {props}")
        data = fh.read(nv * 24)
        return [data[i * 24:(i + 1) * 24] for i in range(nv)]


def main():
    scans_dir, out = sys.argv[1], sys.argv[2]
    names = sorted(n for n in os.listdir(scans_dir) if n.endswith(".ply"))
    if len(names) != 9:
        raise SystemExit(f"expected 9 scans in {scans_dir}, found {len(names)}")
    records = []
    for n in names:
        records.extend(read_scan(os.path.join(scans_dir, n)))
    keep = sorted(random.Random(20091109).sample(range(len(records)), 100000))
    with open(out, "wb") as fh:
        fh.write(("ply\nformat binary_little_endian 1.0\n"
                  "comment 9 registered Stanford bunny range scans (bun000 bun045 bun090 bun180 bun270 "
                  "chin ear_back top2 top3), merged, 100000 of " + str(len(records)) +
                  " points drawn with seed 20091109; see data/README.md\n"
                  "element vertex 100000\n"
                  "property float x\nproperty float y\nproperty float z\n"
                  "property float nx\nproperty float ny\nproperty float nz\n"
                  "end_header\n").encode("ascii"))
        for i in keep:
            fh.write(records[i])
    print(f"{out}: 100000 of {len(records)} points from {len(names)} scans")


if __name__ == "__main__":
    main()
