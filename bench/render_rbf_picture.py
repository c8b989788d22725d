#!/usr/bin/python3
# This Source Code Form is subject to the terms of the Mozilla Public
# License, v. 2.0. If a copy of the MPL was not distributed with this
# file, You can obtain one at https://mozilla.org/MPL/2.0/.
"""The README picture of the octree RBF: input points and reconstructed meshes side by side,
rendered without a display (this machine has no EGL for Open3D's offscreen renderer): each
mesh is subdivided until its triangles are smaller than a pixel and drawn as shaded points
with a z-buffer in numpy; Open3D reads the meshes and writes the PNG.

Usage: /usr/bin/python3 bench/render_rbf_picture.py OUT.png INPUT_POINTS MESH [MESH ...]
"""
import sys

import numpy as np
import open3d as o3d

W, H = 520, 520


def view(points, rot):
    return points @ rot.T


def splat(img, zbuf, xy, z, colour):
    order = np.argsort(z)  # far (small z) first: nearer points overwrite
    xy, z, colour = xy[order], z[order], colour[order]
    for dx in (0, 1):
        for dy in (0, 1):
            x = np.clip(xy[:, 0] + dx, 0, W - 1)
            y = np.clip(xy[:, 1] + dy, 0, H - 1)
            nearer = z >= zbuf[y, x] - 1e-9
            img[y[nearer], x[nearer]] = colour[nearer]
            zbuf[y[nearer], x[nearer]] = z[nearer]


def panel(points, normals, rot, centre, scale, base):
    img = np.full((H, W, 3), 255, np.uint8)
    zbuf = np.full((H, W), -np.inf)
    p = view(points - centre, rot) * scale
    n = view(normals, rot)
    xy = np.stack([p[:, 0] + W / 2, H / 2 - p[:, 1]], 1).astype(int)
    light = np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8])
    shade = np.clip(np.abs(n @ light), 0.15, 1.0)
    colour = (np.outer(shade, base) * 255).astype(np.uint8)
    splat(img, zbuf, xy, p[:, 2], colour)
    return img


def main():
    out, points_file, meshes = sys.argv[1], sys.argv[2], sys.argv[3:]
    pcd = o3d.io.read_point_cloud(points_file, format="xyzn" if points_file.endswith(".xyz") else "auto")
    pts, nrm = np.asarray(pcd.points), np.asarray(pcd.normals)
    lo, hi = pts.min(0), pts.max(0)
    centre, scale = (lo + hi) / 2, 0.85 * W / np.linalg.norm(hi - lo)
    a, b = np.radians(-25), np.radians(15)
    rot = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    rot = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]]) @ rot
    panels = [panel(pts, nrm, rot, centre, scale, np.array([0.35, 0.55, 0.9]))]
    for f in meshes:
        m = o3d.io.read_triangle_mesh(f)
        while np.asarray(m.vertices).shape[0] < 1_500_000:
            m = m.subdivide_midpoint(1)
        m.compute_vertex_normals()
        panels.append(panel(np.asarray(m.vertices), np.asarray(m.vertex_normals), rot, centre, scale,
                            np.array([0.85, 0.7, 0.45])))
    o3d.io.write_image(out, o3d.geometry.Image(np.ascontiguousarray(np.hstack(panels))))


if __name__ == "__main__":
    main()
