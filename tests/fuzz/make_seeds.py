#!/usr/bin/env python3
# Cuts the fuzzing seed corpus (tests/fuzz/corpus/<reader>/) from the real files in
# tests/data: a few faces of each mesh with the vertices they use (renumbered), a few
# points of the point cloud, then variants of each (other line endings, a UTF-8 BOM,
# normals, polygons, the other byte order). Deterministic; rerun after changing it:
#   python3 tests/fuzz/make_seeds.py
import os
import struct

here = os.path.dirname(os.path.abspath(__file__))
data = os.path.join(here, "..", "data")
out = os.path.join(here, "corpus")


def write(reader, name, content):
    d = os.path.join(out, reader)
    os.makedirs(d, exist_ok=True)
    if isinstance(content, str):
        content = content.encode("latin-1")
    with open(os.path.join(d, name), "wb") as f:
        f.write(content)


def cut(vertices, faces, n_faces):
    """The first n_faces faces and the vertices they use, renumbered in order of use."""
    remap, vs, fs = {}, [], []
    for f in faces[:n_faces]:
        for v in f:
            if v not in remap:
                remap[v] = len(vs)
                vs.append(vertices[v])
        fs.append([remap[v] for v in f])
    return vs, fs


def variants(reader, stem, text):
    """LF, CRLF, CR and BOM copies of a text file."""
    write(reader, stem + "_lf", text)
    write(reader, stem + "_crlf", text.replace("\n", "\r\n"))
    write(reader, stem + "_cr", text.replace("\n", "\r"))
    write(reader, stem + "_bom", "\xef\xbb\xbf" + text)


def read_off(path):
    lines = [l for l in open(path).read().split("\n") if l.strip() and not l.startswith("#")]
    nv, nf = map(int, lines[1].split()[:2])
    vs = [l.split()[:3] for l in lines[2:2 + nv]]
    fs = [list(map(int, l.split()[1:])) for l in lines[2 + nv:2 + nv + nf]]
    return vs, fs


# ---- OFF: eight.off and bunny.off
for stem, src, n in (("eight", "eight.off", 24), ("bunny", "bunny.off", 16)):
    vs, fs = read_off(os.path.join(data, src))
    vs, fs = cut(vs, fs, n)
    body = "".join(" ".join(v) + "\n" for v in vs) + "".join("3 " + " ".join(map(str, f)) + "\n" for f in fs)
    variants("off", stem, "OFF\n# cut from tests/data/%s\n%d %d 0\n" % (src, len(vs), len(fs)) + body)
vs, fs = cut(*read_off(os.path.join(data, "eight.off")), 6)
write("off", "eight_noff_quad",
      "NOFF %d %d 0\n" % (len(vs), len(fs) + 1) + "".join(" ".join(v) + " 0 0 1\n" for v in vs) +
      "".join("3 " + " ".join(map(str, f)) + "\n" for f in fs) + "4 0 1 2 3\n")
write("off", "eight_coff",
      "COFF\n%d %d 0\n" % (len(vs), len(fs)) + "".join(" ".join(v) + " 255 0 0 255\n" for v in vs) +
      "".join("3 " + " ".join(map(str, f)) + " 10 20 30\n" for f in fs))

# ---- OBJ: twelve.obj
lines = open(os.path.join(data, "twelve.obj")).read().split("\n")
vs = [l.split()[1:4] for l in lines if l.startswith("v ")]
fs = [[int(c.split("/")[0]) - 1 for c in l.split()[1:]] for l in lines if l.startswith("f ")]
vs, fs = cut(vs, fs, 20)
head = "# cut from tests/data/twelve.obj (OBJ written by MeshLab)\n"
variants("obj", "twelve", head + "".join("v " + " ".join(v) + "\n" for v in vs) +
         "".join("f " + " ".join(str(i + 1) for i in f) + "\n" for f in fs))
vs6, fs6 = vs[:8], [f for f in fs if max(f) < 8]
write("obj", "twelve_vn",
      "o twelve\n" + "".join("v " + " ".join(v) + "\n" for v in vs6) + "".join("vn 0 0 1\n" for v in vs6) +
      "vt 0 0\ng part\nusemtl m\n" +
      "".join("f " + " ".join("%d/1/%d" % (i + 1, i + 1) for i in f) + "\n" for f in fs6) +
      "f -1//1 -2//2 -3//3 -4//4\nl 1 2\n")

# ---- PLY ascii: bun_zipper_res4.ply (extra vertex properties confidence, intensity)
text = open(os.path.join(data, "bun_zipper_res4.ply")).read()
header, body = text.split("end_header\n", 1)
rows = body.split("\n")
nv = 453
vs = [r.split() for r in rows[:nv]]
fs = [list(map(int, r.split()[1:])) for r in rows[nv:nv + 948]]
vs, fs = cut(vs, fs, 16)
ascii_ply = ("ply\nformat ascii 1.0\ncomment cut from tests/data/bun_zipper_res4.ply\nelement vertex %d\n"
             "property float x\nproperty float y\nproperty float z\nproperty float confidence\n"
             "property float intensity\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n"
             % (len(vs), len(fs)) +
             "".join(" ".join(v) + "\n" for v in vs) + "".join("3 " + " ".join(map(str, f)) + "\n" for f in fs))
variants("ply", "bunny_ascii", ascii_ply)

# ---- PLY binary: bun000_part.ply (float x y z nx ny nz, list uchar int)
raw = open(os.path.join(data, "bun000_part.ply"), "rb").read()
hend = raw.index(b"end_header\n") + len(b"end_header\n")
p = hend
vs = [struct.unpack_from("<6f", raw, p + 24 * i) for i in range(8000)]
p += 24 * 8000
fs = []
for _ in range(15313):
    n = raw[p]
    fs.append(list(struct.unpack_from("<%di" % n, raw, p + 1)))
    p += 1 + 4 * n
vs, fs = cut(vs, fs, 24)


def binary_ply(order, name, with_normals=True, face_first=False, extra=""):
    fmt = "binary_little_endian" if order == "<" else "binary_big_endian"
    props = "property float x\nproperty float y\nproperty float z\n"
    if with_normals:
        props += "property float nx\nproperty float ny\nproperty float nz\n"
    velem = "element vertex %d\n%s" % (len(vs), props)
    felem = "element face %d\nproperty list uchar int vertex_indices\n" % len(fs)
    h = ("ply\nformat %s 1.0\ncomment cut from tests/data/bun000_part.ply\n" % fmt +
         (felem + velem if face_first else velem + felem) + extra + "end_header\n")
    vb = b"".join(struct.pack(order + ("6f" if with_normals else "3f"), *(v if with_normals else v[:3])) for v in vs)
    fb = b"".join(struct.pack(order + "B3i", 3, *f) for f in fs)
    write("ply", name, h.encode() + (fb + vb if face_first else vb + fb))


binary_ply("<", "bun000_le")
binary_ply(">", "bun000_be")
binary_ply("<", "bun000_le_xyz_faces_first", with_normals=False, face_first=True)

# ---- XYZ / PWN: kitten.xyz (x y z nx ny nz)
rows = open(os.path.join(data, "kitten.xyz")).read().split("\n")[:40]
variants("xyz", "kitten6", "\n".join(rows) + "\n")
write("xyz", "kitten3_count", "20\n# x y z only\n" + "".join(" ".join(r.split()[:3]) + "\n" for r in rows[:20]))

# ---- PLY: the other property kinds (double, small integers, radius, vertex_index, an
# extra element with a list) on the same vertices
h = ("ply\nformat %s 1.0\nelement vertex %d\nproperty double x\nproperty double y\nproperty double z\n"
     "property short nx\nproperty short ny\nproperty short nz\nproperty float radius\nproperty uchar red\n"
     "element face %d\nproperty list ushort uint vertex_index\nproperty uchar flags\n"
     "element edge 2\nproperty int vertex1\nproperty int vertex2\nproperty list uchar float w\nend_header\n")
nv, nf = 8, 4
pts = vs[:nv]
tris = [[0, 1, 2], [1, 2, 3], [4, 5, 6, 7], [2, 3, 4]]
write("ply", "types_ascii",
      h % ("ascii", nv, nf) + "".join("%r %r %r 0 0 1 0.001 200\n" % tuple(p[:3]) for p in pts) +
      "".join("%d %s 7\n" % (len(t), " ".join(map(str, t))) for t in tris) + "0 1 1 0.5\n1 2 0\n")
write("ply", "types_le",
      (h % ("binary_little_endian", nv, nf)).encode() +
      b"".join(struct.pack("<3d3hfB", *p[:3], 0, 0, 1, 0.001, 200) for p in pts) +
      b"".join(struct.pack("<H%dIB" % len(t), len(t), *t, 7) for t in tris) +
      struct.pack("<iiBf", 0, 1, 1, 0.5) + struct.pack("<iiB", 1, 2, 0))
