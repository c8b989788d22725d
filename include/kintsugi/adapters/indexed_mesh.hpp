// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file indexed_mesh.hpp
/// @brief The built-in aggregates `kintsugi::PointCloud` and `kintsugi::IndexedMesh`,
/// and conversions from any PointSet / TriangleMesh into them.

#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/types.hpp>

#include <vector>

namespace kintsugi {

/// A point cloud: positions, optional per-point normals and radii (surfels).
/// `normals` and `radii` are either empty or as long as `points`. It is a
/// GrowableSurfelSet: append_surfel(cloud, p, n, r) appends to all three vectors.
struct PointCloud {
    std::vector<Vec3> points;
    std::vector<Vec3> normals;
    std::vector<Scalar> radii;
};

/// An indexed triangle mesh with optional per-vertex normals (empty or one per vertex).
struct IndexedMesh {
    std::vector<Vec3> vertices;
    std::vector<Face> faces;
    std::vector<Vec3> normals;
};

template <>
struct point_set_traits<PointCloud> {
    static std::size_t size(const PointCloud& c) { return c.points.size(); }
    static Vec3 point(const PointCloud& c, std::size_t i) { return c.points[i]; }
    static Vec3 normal(const PointCloud& c, std::size_t i) { return c.normals[i]; }
    static bool has_normals(const PointCloud& c) { return !c.points.empty() && c.normals.size() == c.points.size(); }
    static Scalar radius(const PointCloud& c, std::size_t i) { return c.radii[i]; }
    static bool has_radii(const PointCloud& c) { return !c.points.empty() && c.radii.size() == c.points.size(); }
    static void prepare_normals(PointCloud& c) { c.normals.resize(c.points.size(), Vec3::Zero()); }
    static void set_normal(PointCloud& c, std::size_t i, const Vec3& n) { c.normals[i] = n; }
    static void clear(PointCloud& c) {
        c.points.clear();
        c.normals.clear();
        c.radii.clear();
    }
    /// Appends a point without a radius (the cloud then has none: has_radii is false).
    static void push_back(PointCloud& c, const Vec3& p, const Vec3& n) {
        c.points.push_back(p);
        c.normals.push_back(n);
    }
    /// Appends a surfel. @pre the cloud is empty or already has one radius per point
    static void push_back(PointCloud& c, const Vec3& p, const Vec3& n, Scalar r) {
        c.points.push_back(p);
        c.normals.push_back(n);
        c.radii.push_back(r);
    }
};

template <>
struct mesh_traits<IndexedMesh> {
    static std::size_t num_vertices(const IndexedMesh& m) { return m.vertices.size(); }
    static std::size_t num_faces(const IndexedMesh& m) { return m.faces.size(); }
    static Vec3 position(const IndexedMesh& m, Index v) { return m.vertices[v]; }
    static Face face(const IndexedMesh& m, Index f) { return m.faces[f]; }
    static void set_position(IndexedMesh& m, Index v, const Vec3& p) { m.vertices[v] = p; }
    static void clear(IndexedMesh& m) {
        m.vertices.clear();
        m.faces.clear();
        m.normals.clear();
    }
    static void reserve(IndexedMesh& m, std::size_t nv, std::size_t nf) {
        m.vertices.reserve(nv);
        m.faces.reserve(nf);
    }
    static Index add_vertex(IndexedMesh& m, const Vec3& p) {
        m.vertices.push_back(p);
        return m.vertices.size() - 1;
    }
    static void add_face(IndexedMesh& m, const Face& f) { m.faces.push_back(f); }
};

/// Copies any TriangleMesh into an IndexedMesh (the internal layout).
template <TriangleMesh M>
[[nodiscard]] IndexedMesh to_indexed_mesh(const M& m) {
    if constexpr (std::is_same_v<M, IndexedMesh>) {
        return m;
    } else {
        IndexedMesh out;
        const std::size_t nv = kintsugi::num_vertices(m), nf = kintsugi::num_faces(m);
        out.vertices.resize(nv);
        out.faces.resize(nf);
        for (std::size_t v = 0; v < nv; ++v) out.vertices[v] = kintsugi::vertex_position(m, v);
        for (std::size_t f = 0; f < nf; ++f) out.faces[f] = kintsugi::face_at(m, f);
        return out;
    }
}

/// Copies any PointSet into a PointCloud (positions, normals and radii when present).
template <PointSet P>
[[nodiscard]] PointCloud to_point_cloud(const P& p) {
    if constexpr (std::is_same_v<P, PointCloud>)
        return p;
    else
        return {kintsugi::gather_points(p), kintsugi::gather_normals(p), kintsugi::gather_radii(p)};
}

/// Replaces the contents of any TopologyMutableMesh with `src`.
template <TopologyMutableMesh M>
void assign_mesh(M& dst, const IndexedMesh& src) {
    if constexpr (std::is_same_v<M, IndexedMesh>) {
        dst = src;
    } else {
        mesh_traits<M>::clear(dst);
        if constexpr (requires { mesh_traits<M>::reserve(dst, std::size_t{}, std::size_t{}); })
            mesh_traits<M>::reserve(dst, src.vertices.size(), src.faces.size());
        for (const Vec3& p : src.vertices) mesh_traits<M>::add_vertex(dst, p);
        for (const Face& f : src.faces) mesh_traits<M>::add_face(dst, f);
    }
}

}  // namespace kintsugi
