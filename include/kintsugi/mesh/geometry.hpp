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
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/topology.hpp>

#include <Eigen/Geometry>

#include <cmath>
#include <cstddef>
#include <string>
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

/// (b - a) x (c - a) of face f: its direction is the normal, its norm twice the area.
inline Vec3 face_cross(const IndexedMesh& m, Index f) {
    const Face& t = m.faces[f];
    const Vec3& a = m.vertices[t[0]];
    return (m.vertices[t[1]] - a).cross(m.vertices[t[2]] - a);
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
    const Vec3 c = detail::face_cross(m, f);
    const Scalar n = c.norm();
    return n > 0 && std::isfinite(n) ? Vec3(c / n) : Vec3::Zero();
}

/// @brief Unit normals of all faces (zero for degenerate faces).
/// @throws invalid_input if a face uses a vertex index out of range.
[[nodiscard]] inline std::vector<Vec3> face_normals(const IndexedMesh& m) {
    detail::check_face_indices(m, "kintsugi::face_normals");
    std::vector<Vec3> out(m.faces.size());
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
        const Vec3 c = detail::face_cross(m, f);
        const Scalar n = c.norm();
        out[f] = n > 0 && std::isfinite(n) ? Vec3(c / n) : Vec3::Zero();
    }
    return out;
}

/// @brief Areas of all faces, in squared mesh units.
/// @throws invalid_input if a face uses a vertex index out of range.
[[nodiscard]] inline std::vector<Scalar> face_areas(const IndexedMesh& m) {
    detail::check_face_indices(m, "kintsugi::face_areas");
    std::vector<Scalar> out(m.faces.size());
    for (std::size_t f = 0; f < m.faces.size(); ++f) out[f] = detail::face_cross(m, f).norm() / 2;
    return out;
}

/// @brief Area-weighted vertex normals: the normalised sum of the incident faces'
/// normals weighted by their areas (i.e. of their un-normalised cross products).
/// @return one unit normal per vertex; zero for isolated vertices and vertices whose
/// faces cancel out or are all degenerate.
/// @throws invalid_input if a face uses a vertex index out of range.
[[nodiscard]] inline std::vector<Vec3> vertex_normals(const IndexedMesh& m) {
    detail::check_face_indices(m, "kintsugi::vertex_normals");
    std::vector<Vec3> out(m.vertices.size(), Vec3::Zero());
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
        const Vec3 c = detail::face_cross(m, f);
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

/// @brief Mean length of the mesh's unique undirected edges (each counted once), in
/// mesh units; 0 for a mesh without faces. Self edges of faces with a repeated vertex
/// index count with length 0.
/// @throws invalid_input if a face uses a vertex index out of range.
[[nodiscard]] inline Scalar mean_edge_length(const IndexedMesh& m) {
    detail::check_face_indices(m, "kintsugi::mean_edge_length");
    if (m.faces.empty()) return 0;
    const MeshTopology topo(m.vertices.size(), m.faces);
    Scalar sum = 0;
    for (const auto& e : topo.edges()) sum += (m.vertices[e[0]] - m.vertices[e[1]]).norm();
    return sum / static_cast<Scalar>(topo.num_edges());
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
    Scalar v = 0;
    for (const Face& t : m.faces) v += m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]]));
    return v / 6;
}

}  // namespace kintsugi
