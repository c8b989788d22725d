// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file geometry.hpp
/// @brief Per-face and per-vertex geometry of an IndexedMesh: normals, areas, edge
/// lengths, bounding box, enclosed volume.
///
/// These work on the internal layout (IndexedMesh); convert any TriangleMesh with
/// `to_indexed_mesh` first. Every function that loops over all faces checks the
/// vertex indices once and throws `invalid_input` when one is out of range.

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/topology.hpp>

#include <Eigen/Geometry>

#include <cmath>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

namespace detail {

/// Throws invalid_input naming `function` if a face of m uses a vertex index out of range.
inline void check_face_indices(const IndexedMesh& m, const char* function) {
    const std::size_t nv = m.vertices.size();
    for (std::size_t f = 0; f < m.faces.size(); ++f)
        for (int k = 0; k < 3; ++k)
            if (m.faces[f][k] >= nv)
                throw invalid_input(std::string(function) + ": face " + std::to_string(f) + " uses vertex " +
                                    std::to_string(m.faces[f][k]) + " but the mesh has " + std::to_string(nv) +
                                    " vertices; fix or remove the face");
}

/// Throws invalid_input naming `function` if a vertex of m has a NaN or infinite coordinate
/// (the first one) or a face uses a vertex index out of range.
inline void check_mesh_values(const IndexedMesh& m, const char* function) {
    for (std::size_t v = 0; v < m.vertices.size(); ++v)
        if (!m.vertices[v].allFinite())
            throw invalid_input(std::string(function) + ": vertex " + std::to_string(v) +
                                " has a NaN or infinite coordinate; remove or fix it first");
    check_face_indices(m, function);
}

/// (b - a) x (c - a) of face f: its direction is the normal, its norm twice the area.
inline Vec3 face_cross(const IndexedMesh& m, Index f) {
    const Face& t = m.faces[f];
    const Vec3& a = m.vertices[t[0]];
    return (m.vertices[t[1]] - a).cross(m.vertices[t[2]] - a);
}

/// (b − a) × (c − a) computed on the corners scaled by 2^-shift, where shift brings the
/// longest edge component near 1, so that neither the products overflow (coordinates
/// above ~1e154) nor underflow (below ~1e-154). The true cross product is the result
/// times 2^(2 shift); its direction is exact.
inline Vec3 triangle_cross_scaled(const Vec3& a, const Vec3& b, const Vec3& c, int& shift) {
    const Vec3 u = b / 2 - a / 2, v = c / 2 - a / 2;  // halved: b - a may overflow
    const Scalar big = std::max(u.cwiseAbs().maxCoeff(), v.cwiseAbs().maxCoeff());
    shift = big > 0 && std::isfinite(big) ? std::ilogb(big) + 1 : 0;
    const Scalar s = std::ldexp(Scalar(1), -shift);
    // u, v halved: the cross product is 4 times too small; folded into the shift.
    const Vec3 us = u * s, vs = v * s;
    shift += 1;
    return us.cross(vs);
}

/// triangle_cross_scaled of face f's corners.
inline Vec3 face_cross_scaled(const IndexedMesh& m, Index f, int& shift) {
    const Face& t = m.faces[f];
    return triangle_cross_scaled(m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]], shift);
}

/// Unit normal of the triangle (a, b, c) (right-hand rule), at any magnitude; the zero
/// vector when it is degenerate or not finite.
inline Vec3 unit_triangle_normal(const Vec3& a, const Vec3& b, const Vec3& c) {
    int shift = 0;
    const Vec3 x = triangle_cross_scaled(a, b, c, shift);
    const Scalar n = x.norm();
    return n > 0 && std::isfinite(n) ? Vec3(x / n) : Vec3::Zero();
}

}  // namespace detail

/// @brief Unit normal of face f, following its orientation (right-hand rule).
/// @param m mesh; @param f face index
/// @return the unit normal; the zero vector for a degenerate (zero-area) face.
/// @throws invalid_input if f or one of its vertex indices is out of range.
[[nodiscard]] inline Vec3 face_normal(const IndexedMesh& m, Index f) {
    if (f >= m.faces.size())
        throw invalid_input("kintsugi::face_normal: face " + std::to_string(f) + " out of range (the mesh has " +
                            std::to_string(m.faces.size()) + " faces)");
    for (int k = 0; k < 3; ++k)
        if (m.faces[f][k] >= m.vertices.size())
            throw invalid_input("kintsugi::face_normal: face " + std::to_string(f) + " uses vertex " +
                                std::to_string(m.faces[f][k]) + " but the mesh has " +
                                std::to_string(m.vertices.size()) + " vertices; fix the face");
    const Face& t = m.faces[f];
    return detail::unit_triangle_normal(m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]);
}

/// @brief Unit normals of all faces (zero for degenerate faces).
/// @throws invalid_input if a face uses a vertex index out of range.
[[nodiscard]] inline std::vector<Vec3> face_normals(const IndexedMesh& m) {
    detail::check_face_indices(m, "kintsugi::face_normals");
    std::vector<Vec3> out(m.faces.size());
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
        const Face& t = m.faces[f];
        out[f] = detail::unit_triangle_normal(m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]);
    }
    return out;
}

/// @brief Areas of all faces, in squared mesh units.
/// @throws invalid_input if a face uses a vertex index out of range.
[[nodiscard]] inline std::vector<Scalar> face_areas(const IndexedMesh& m) {
    detail::check_face_indices(m, "kintsugi::face_areas");
    std::vector<Scalar> out(m.faces.size());
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
        int shift = 0;
        const Scalar twice = detail::face_cross_scaled(m, f, shift).norm();
        out[f] = std::ldexp(twice, 2 * shift - 1);  // +inf when the true area exceeds double's range
    }
    return out;
}

/// @brief Area-weighted vertex normals: the normalised sum of the incident faces'
/// normals weighted by their areas (i.e. of their un-normalised cross products).
/// @return one unit normal per vertex; zero for isolated vertices and vertices whose
/// faces cancel out or are all degenerate.
/// @throws invalid_input if a face uses a vertex index out of range.
[[nodiscard]] inline std::vector<Vec3> vertex_normals(const IndexedMesh& m) {
    detail::check_face_indices(m, "kintsugi::vertex_normals");
    // Any magnitude: the crosses of a copy rescaled by a power of two (same ratios).
    const detail::ScaleFrame frame = detail::scale_frame(m.vertices);
    IndexedMesh local;
    if (!frame.identity()) {
        local.vertices = m.vertices;
        frame.to_local(local.vertices);
        local.faces = m.faces;
    }
    const IndexedMesh& mm = frame.identity() ? m : local;
    std::vector<Vec3> out(m.vertices.size(), Vec3::Zero());
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
        const Vec3 c = detail::face_cross(mm, f);
        const Face& t = m.faces[f];
        out[t[0]] += c;
        if (t[1] != t[0]) out[t[1]] += c;
        if (t[2] != t[0] && t[2] != t[1]) out[t[2]] += c;
    }
    for (Vec3& n : out) {
        const Scalar len = n.norm();
        n = len > 0 && std::isfinite(len) ? Vec3(n / len) : Vec3::Zero();
    }
    return out;
}

namespace detail {
/// Mean length of the unique edges of `topo` over positions `V`, summed in fixed chunks
/// (the same whatever the thread count); an edge of a face with a repeated vertex index
/// (a self edge) counts with length 0 when `self_edges`, else not at all. 0 without edges.
inline Scalar mean_edge_length(const std::vector<Vec3>& V, const MeshTopology& topo, bool self_edges) {
    const auto& E = topo.edges();
    using Sum = std::pair<Scalar, std::size_t>;
    const Sum sum = parallel_reduce(
        0, E.size(), Sum{0, 0},
        [&](std::size_t first, std::size_t last, Sum acc) {
            for (std::size_t e = first; e < last; ++e)
                if (E[e][0] != E[e][1]) {
                    acc.first += (V[E[e][0]] - V[E[e][1]]).norm();
                    ++acc.second;
                } else if (self_edges) {
                    ++acc.second;
                }
            return acc;
        },
        [](Sum x, Sum y) { return Sum{x.first + y.first, x.second + y.second}; });
    return sum.second ? sum.first / static_cast<Scalar>(sum.second) : Scalar(0);
}

/// Length of every edge of `topo` over positions `V`, in the order of topo.edges().
inline std::vector<Scalar> edge_lengths(const std::vector<Vec3>& V, const MeshTopology& topo) {
    const auto& E = topo.edges();
    std::vector<Scalar> len(E.size());
    for (std::size_t e = 0; e < E.size(); ++e) len[e] = (V[E[e][0]] - V[E[e][1]]).norm();
    return len;
}

/// The upper median of `v` (element n/2 in sorted order). @pre v not empty.
inline Scalar upper_median(std::vector<Scalar> v) {
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

/// The median over the interior edges (two faces) of the angle between the two faces' unit
/// normals `n` (kintsugi::face_normals, indexed as topo's faces), in radians; 0 when no such
/// edge has two non-degenerate faces. Degenerate faces (zero normals) are left out.
inline Scalar median_dihedral_angle(const std::vector<Vec3>& n, const MeshTopology& topo) {
    std::vector<Scalar> angles;
    angles.reserve(topo.num_edges());
    for (std::size_t e = 0; e < topo.num_edges(); ++e) {
        const auto ef = topo.edge_faces(static_cast<Index>(e));
        if (ef.size() != 2) continue;
        const Vec3& a = n[ef[0]];
        const Vec3& b = n[ef[1]];
        if (a.squaredNorm() == 0 || b.squaredNorm() == 0) continue;
        // atan2 of |a×b| and a·b: accurate near 0 and π, orientation-free for consistent faces.
        angles.push_back(std::atan2(a.cross(b).norm(), a.dot(b)));
    }
    return angles.empty() ? Scalar(0) : upper_median(std::move(angles));
}
}  // namespace detail

/// @brief Mean length of the mesh's unique undirected edges (each counted once), in
/// mesh units; 0 for a mesh without faces. Self edges of faces with a repeated vertex
/// index count with length 0.
/// @throws invalid_input if a face uses a vertex index out of range.
[[nodiscard]] inline Scalar mean_edge_length(const IndexedMesh& m) {
    detail::check_face_indices(m, "kintsugi::mean_edge_length");
    if (m.faces.empty()) return 0;
    const MeshTopology topo(m.vertices.size(), m.faces);
    // Any magnitude: the lengths in a frame scaled by a power of two, where neither a
    // difference nor a square leaves double's range.
    const detail::ScaleFrame frame = detail::scale_frame(m.vertices);
    if (frame.identity()) return detail::mean_edge_length(m.vertices, topo, /*self_edges=*/true);
    std::vector<Vec3> local = m.vertices;
    frame.to_local(local);
    return frame.to_world(detail::mean_edge_length(local, topo, /*self_edges=*/true));
}

/// @brief Axis-aligned bounding box of a set of points (empty box for no points).
[[nodiscard]] inline BoundingBox bounding_box(const std::vector<Vec3>& points) {
    BoundingBox box;
    for (const Vec3& p : points) box.extend(p);
    return box;
}

/// @brief Signed volume enclosed by the mesh, in cubed mesh units: the sum over faces
/// of a·(b×c)/6. Positive for a closed, outward-oriented mesh; for an open mesh it is
/// the volume of the cone from the origin and depends on where the origin is.
/// @throws invalid_input if a face uses a vertex index out of range.
[[nodiscard]] inline Scalar signed_volume(const IndexedMesh& m) {
    detail::check_face_indices(m, "kintsugi::signed_volume");
    // Any magnitude: summed on the copy rescaled by 2^-shift, then times 2^(3 shift)
    // (+-inf when the true volume exceeds double's range).
    const detail::ScaleFrame frame = detail::scale_frame(m.vertices);
    Scalar v = 0;
    for (const Face& t : m.faces)
        v += frame.to_local(m.vertices[t[0]]).dot(frame.to_local(m.vertices[t[1]]).cross(frame.to_local(m.vertices[t[2]])));
    return std::ldexp(v / 6, 3 * frame.shift);
}

}  // namespace kintsugi
