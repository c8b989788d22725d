#!/usr/bin/env python3
"""Renders meshes and point clouds to PNG for the README (numpy z-buffer, no GPU).

usage: render.py OUT.png [--size W H] [--view azimuth elevation] INPUT [INPUT ...]
                 [--row [--view azimuth elevation] INPUT ...]
Several inputs are drawn side by side, each framed on its own; --row starts a new row
below (its own --view, else the previous one). A mesh is drawn
with Lambert shading; a point cloud (or a mesh file without faces) as dots.
Reads PLY (ascii/binary), OFF and XYZ. Needs only numpy (Debian python3-numpy).
"""
import struct, sys, zlib
import numpy as np

PLY_TYPES = {'char': 'b', 'int8': 'b', 'uchar': 'B', 'uint8': 'B', 'short': 'h', 'int16': 'h',
             'ushort': 'H', 'uint16': 'H', 'int': 'i', 'int32': 'i', 'uint': 'I', 'uint32': 'I',
             'float': 'f', 'float32': 'f', 'double': 'd', 'float64': 'd'}


def read_ply(path):
    data = open(path, 'rb').read()
    end = data.index(b'end_header') + len('end_header')
    while data[end:end + 1] in (b'\r', b'\n'):
        end += 1
        if data[end - 1:end] == b'\n':
            break
    header = data[:end].decode('ascii', 'replace').split('\n')
    fmt = 'ascii'
    elements = []
    for line in header:
        t = line.split()
        if not t:
            continue
        if t[0] == 'format':
            fmt = t[1]
        elif t[0] == 'element':
            elements.append([t[1], int(t[2]), []])
        elif t[0] == 'property':
            elements[-1][2].append(t[1:])
    body = data[end:]
    V = np.zeros((0, 3)); F = np.zeros((0, 3), int)
    if fmt == 'ascii':
        tokens = body.split(); pos = 0
        for name, count, props in elements:
            rows = []
            for _ in range(count):
                row = []
                for p in props:
                    if p[0] == 'list':
                        n = int(tokens[pos]); pos += 1
                        row.append([float(x) for x in tokens[pos:pos + n]]); pos += n
                    else:
                        row.append(float(tokens[pos])); pos += 1
                rows.append(row)
            if name == 'vertex':
                names = [p[-1] for p in props]
                V = np.array([[r[names.index(c)] for c in 'xyz'] for r in rows], float)
            elif name == 'face':
                F = triangulate([r[0] for r in rows])
        return V, F
    end_char = '<' if fmt == 'binary_little_endian' else '>'
    pos = 0
    for name, count, props in elements:
        if all(p[0] != 'list' for p in props):
            dt = np.dtype([(p[1], end_char + PLY_TYPES[p[0]]) for p in props])
            arr = np.frombuffer(body, dt, count, pos); pos += dt.itemsize * count
            if name == 'vertex':
                V = np.stack([arr['x'], arr['y'], arr['z']], 1).astype(float)
        else:
            polys = []
            for _ in range(count):
                row = None
                for p in props:
                    if p[0] == 'list':
                        ct, it = PLY_TYPES[p[1]], PLY_TYPES[p[2]]
                        n = struct.unpack_from(end_char + ct, body, pos)[0]; pos += struct.calcsize(ct)
                        vals = struct.unpack_from(end_char + it * n, body, pos); pos += struct.calcsize(it) * n
                        if row is None:
                            row = vals
                    else:
                        pos += struct.calcsize(PLY_TYPES[p[0]])
                polys.append(row)
            if name == 'face':
                F = triangulate(polys)
    return V, F


def triangulate(polys):
    tris = [(p[0], p[i], p[i + 1]) for p in polys for i in range(1, len(p) - 1)]
    return np.array(tris, int).reshape(-1, 3)


def read_off(path):
    tok = [t for line in open(path) for t in line.split('#')[0].split()]
    assert tok[0].endswith('OFF')
    nv, nf = int(tok[1]), int(tok[2]); pos = 4
    V = np.array(tok[pos:pos + 3 * nv], float).reshape(nv, 3); pos += 3 * nv
    polys = []
    for _ in range(nf):
        n = int(tok[pos]); polys.append([int(x) for x in tok[pos + 1:pos + 1 + n]]); pos += 1 + n
    return V, triangulate(polys)


def read_any(path):
    if path.lower().endswith('.ply'):
        return read_ply(path)
    if path.lower().endswith('.off'):
        return read_off(path)
    pts = np.loadtxt(path, comments='#', ndmin=2)
    return pts[:, :3], np.zeros((0, 3), int)


def rotation(az, el):
    a, e = np.radians(az), np.radians(el)
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, np.cos(e), -np.sin(e)], [0, np.sin(e), np.cos(e)]])
    return Rx @ Rz


def render(V, F, W, H, R, color):
    img = np.full((H, W, 3), 255.0)
    z = np.full((H, W), -np.inf)
    P = V @ R.T
    lo, hi = P.min(0), P.max(0)
    s = 0.9 * min(W / max(hi[0] - lo[0], 1e-12), H / max(hi[1] - lo[1], 1e-12))
    c = (lo + hi) / 2
    X = (P[:, 0] - c[0]) * s + W / 2
    Y = H / 2 - (P[:, 1] - c[1]) * s
    Z = P[:, 2]
    col = np.array(color, float)
    if len(F) == 0:
        xi, yi = np.round(X).astype(int), np.round(Y).astype(int)
        order = np.argsort(Z)
        for dx in (0, 1):
            for dy in (0, 1):
                xx, yy = xi[order] + dx, yi[order] + dy
                ok = (xx >= 0) & (xx < W) & (yy >= 0) & (yy < H)
                img[yy[ok], xx[ok]] = col * 0.8
        return img
    n = np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-300
    light = np.array([0.3, 0.4, 0.87]); light /= np.linalg.norm(light)
    shade = 0.25 + 0.75 * np.abs(n @ light)
    for t in np.argsort(-np.abs(n[:, 2]) * 0):
        i, j, k = F[t]
        xs, ys = np.array([X[i], X[j], X[k]]), np.array([Y[i], Y[j], Y[k]])
        x0, x1 = max(int(np.floor(xs.min())), 0), min(int(np.ceil(xs.max())), W - 1)
        y0, y1 = max(int(np.floor(ys.min())), 0), min(int(np.ceil(ys.max())), H - 1)
        if x0 > x1 or y0 > y1:
            continue
        gx, gy = np.meshgrid(np.arange(x0, x1 + 1) + 0.5, np.arange(y0, y1 + 1) + 0.5)
        d = (ys[1] - ys[2]) * (xs[0] - xs[2]) + (xs[2] - xs[1]) * (ys[0] - ys[2])
        if abs(d) < 1e-12:
            continue
        l0 = ((ys[1] - ys[2]) * (gx - xs[2]) + (xs[2] - xs[1]) * (gy - ys[2])) / d
        l1 = ((ys[2] - ys[0]) * (gx - xs[2]) + (xs[0] - xs[2]) * (gy - ys[2])) / d
        l2 = 1 - l0 - l1
        inside = (l0 >= -1e-6) & (l1 >= -1e-6) & (l2 >= -1e-6)
        if not inside.any():
            continue
        zz = l0 * Z[i] + l1 * Z[j] + l2 * Z[k]
        sub = z[y0:y1 + 1, x0:x1 + 1]
        upd = inside & (zz > sub)
        sub[upd] = zz[upd]
        img[y0:y1 + 1, x0:x1 + 1][upd] = col * shade[t]
    return img


def write_png(path, img):
    a = np.clip(img, 0, 255).astype(np.uint8)
    H, W, _ = a.shape
    raw = b''.join(b'\x00' + a[y].tobytes() for y in range(H))
    def chunk(tag, data):
        return struct.pack('>I', len(data)) + tag + data + struct.pack('>I', zlib.crc32(tag + data) & 0xffffffff)
    png = b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', W, H, 8, 2, 0, 0, 0))
    png += chunk(b'IDAT', zlib.compress(raw, 9)) + chunk(b'IEND', b'')
    open(path, 'wb').write(png)


def main(argv):
    out, W, H, view = None, 400, 400, (0.0, 0.0)
    rows = [[view, []]]
    i = 0
    while i < len(argv):
        if argv[i] == '--size':
            W, H = int(argv[i + 1]), int(argv[i + 2]); i += 3
        elif argv[i] == '--view':
            view = (float(argv[i + 1]), float(argv[i + 2])); rows[-1][0] = view; i += 3
        elif argv[i] == '--row':
            rows.append([view, []]); i += 1
        elif out is None:
            out = argv[i]; i += 1
        else:
            rows[-1][1].append(argv[i]); i += 1
    rows = [r for r in rows if r[1]]
    if out is None or not rows:
        print(__doc__); return 2
    palette = [(200, 170, 110), (120, 160, 210), (150, 200, 140), (210, 130, 130)]
    width = max(len(r[1]) for r in rows)
    strips = []
    for (az, el), inputs in rows:
        R = rotation(az, el)
        panels = []
        for n, spec in enumerate(inputs):
            V, F = read_any(spec.split(':')[0])
            panels.append(render(V, F, W, H, R, palette[n % len(palette)]))
        panels += [np.full((H, W, 3), 255.0)] * (width - len(panels))
        strips.append(np.concatenate(panels, axis=1))
    write_png(out, np.concatenate(strips, axis=0))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
