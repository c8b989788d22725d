// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file write.hpp
/// @brief Writing meshes, point clouds and polylines: PLY (binary little-endian by
/// default, big-endian or ascii on request), OFF, OBJ, XYZ, PWN, chosen by the file
/// extension (case-insensitive).
///
/// Every writer first checks its input (finite coordinates, indices in range), then writes
/// a temporary file in the target directory and renames it over the target: a failure
/// leaves no partial output and no temporary file behind. Text numbers are written in
/// the shortest form that reads back to the same double (std::to_chars), so ascii
/// round trips are exact too; binary PLY stores doubles.

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/io/detail/common.hpp>
#include <kintsugi/io/detail/obj.hpp>
#include <kintsugi/io/detail/off.hpp>
#include <kintsugi/io/detail/output_file.hpp>
#include <kintsugi/io/detail/ply.hpp>
#include <kintsugi/io/detail/xyz.hpp>
#include <kintsugi/io/options.hpp>

#include <array>
#include <cmath>
#include <filesystem>
#include <string>
#include <type_traits>
#include <vector>

namespace kintsugi {

namespace detail::io {

inline void check_finite_for_write(const std::vector<Vec3>& v, const char* function, const char* what) {
    for (std::size_t i = 0; i < v.size(); ++i)
        if (!all_finite(v[i]))
            throw invalid_input(std::string(function) + ": " + what + " " + std::to_string(i) +
                                " is not finite (NaN or Inf); remove or fix it before writing");
}

inline void check_mesh_for_write(const IndexedMesh& m, const char* function) {
    check_finite_for_write(m.vertices, function, "vertex");
    if (!m.normals.empty()) {
        if (m.normals.size() != m.vertices.size())
            throw invalid_input(std::string(function) + ": the mesh has " + std::to_string(m.normals.size()) +
                                " normals for " + std::to_string(m.vertices.size()) +
                                " vertices; give one normal per vertex or none");
        check_finite_for_write(m.normals, function, "normal");
    }
    const std::size_t nv = m.vertices.size();
    for (std::size_t f = 0; f < m.faces.size(); ++f)
        for (const Index v : m.faces[f])
            if (v >= nv)
                throw invalid_input(std::string(function) + ": face " + std::to_string(f) + " uses vertex " +
                                    std::to_string(v) + ", out of range (the mesh has " + std::to_string(nv) +
                                    " vertices)");
}

inline void check_cloud_for_write(const PointCloud& c, const char* function) {
    check_finite_for_write(c.points, function, "point");
    if (!c.normals.empty()) {
        if (c.normals.size() != c.points.size())
            throw invalid_input(std::string(function) + ": " + std::to_string(c.normals.size()) + " normals for " +
                                std::to_string(c.points.size()) + " points; give one normal per point or none");
        check_finite_for_write(c.normals, function, "normal");
    }
    if (!c.radii.empty()) {
        if (c.radii.size() != c.points.size())
            throw invalid_input(std::string(function) + ": " + std::to_string(c.radii.size()) + " radii for " +
                                std::to_string(c.points.size()) + " points; give one radius per point or none");
        for (std::size_t i = 0; i < c.radii.size(); ++i)
            if (!std::isfinite(c.radii[i]))
                throw invalid_input(std::string(function) + ": radius " + std::to_string(i) +
                                    " is not finite; fix it before writing");
    }
}

inline void write_indexed_mesh(const std::filesystem::path& path, const IndexedMesh& m, const WriteOptions& options) {
    const std::string ext = lower_extension(path);
    if (ext != ".ply" && ext != ".off" && ext != ".obj")
        throw io_error(path.string(), "unsupported extension '" + path.extension().string() +
                                          "' for a mesh; kintsugi writes meshes as .ply, .off or .obj");
    check_mesh_for_write(m, "kintsugi::write_mesh");
    AtomicOutputFile out(path);
    if (ext == ".ply") {
        PlyWriteData d;
        d.vertices = &m.vertices;
        d.normals = &m.normals;
        d.faces = &m.faces;
        write_ply(out, d, options.binary, options.big_endian);
    } else if (ext == ".off") {
        write_off(out, m.vertices, &m.normals, &m.faces);
    } else {
        write_obj(out, m.vertices, &m.normals, &m.faces);
    }
    out.commit();
}

inline void write_cloud(const std::filesystem::path& path, const PointCloud& c, const WriteOptions& options) {
    const std::string ext = lower_extension(path);
    if (ext != ".ply" && ext != ".off" && ext != ".obj" && ext != ".xyz" && ext != ".pwn")
        throw io_error(path.string(), "unsupported extension '" + path.extension().string() +
                                          "' for a point cloud; kintsugi writes .ply, .xyz, .pwn, .off or .obj");
    check_cloud_for_write(c, "kintsugi::write_point_cloud");
    if (ext == ".pwn" && c.normals.empty() && !c.points.empty())
        throw invalid_input("kintsugi::write_point_cloud: a .pwn file needs normals and the point set has none; "
                            "estimate them first (kintsugi::estimate_normals) or write .xyz");
    AtomicOutputFile out(path);
    if (ext == ".ply") {
        PlyWriteData d;
        d.vertices = &c.points;
        d.normals = &c.normals;
        d.radii = &c.radii;
        write_ply(out, d, options.binary, options.big_endian);
    } else if (ext == ".off") {
        write_off(out, c.points, &c.normals, nullptr);
    } else if (ext == ".obj") {
        write_obj(out, c.points, &c.normals, nullptr);
    } else {
        write_xyz(out, c.points, &c.normals);
    }
    out.commit();
}

}  // namespace detail::io

/// @brief Writes a triangle mesh.
/// @tparam M a TriangleMesh (IndexedMesh, Eigen V/F view, CGAL::Surface_mesh, ...).
/// @param path    .ply (binary little-endian unless `options` says otherwise), .off or .obj.
/// @param mesh    the mesh; for IndexedMesh the vertex normals are written when present.
/// @param options WriteOptions::binary / big_endian (PLY only).
/// @pre finite coordinates and normals; face indices below the vertex count.
/// @throws invalid_input (kintsugi::write_mesh: ...) when the precondition fails, before
///         anything is written; io_error for an unsupported extension or when the file
///         cannot be written (missing or unwritable directory, disk full). No partial
///         or temporary file is left behind.
template <TriangleMesh M>
void write_mesh(const std::filesystem::path& path, const M& mesh, const WriteOptions& options = {}) {
    if constexpr (std::is_same_v<M, IndexedMesh>) {
        detail::io::write_indexed_mesh(path, mesh, options);
    } else {
        detail::io::write_indexed_mesh(path, to_indexed_mesh(mesh), options);
    }
}

/// @brief Writes a point cloud.
/// @tparam P a PointSet (PointCloud, std::vector<Eigen::Vector3d>, with_normals view,
///         CGAL::Point_set_3, project_points view, ...).
/// @param path    .ply (x y z [nx ny nz] [radius] as doubles), .xyz (x y z [nx ny nz]),
///                .pwn (x y z nx ny nz: normals required), .off (NOFF with normals, no
///                faces) or .obj (v [vn]). Radii are written to PLY only.
/// @param points  the points; normals and radii are written when the set has them.
/// @param options WriteOptions::binary / big_endian (PLY only).
/// @pre finite coordinates, normals and radii.
/// @throws invalid_input before writing when the precondition fails or .pwn is asked
///         without normals; io_error for an unsupported extension or a write failure.
///         No partial or temporary file is left behind.
template <PointSet P>
void write_point_cloud(const std::filesystem::path& path, const P& points, const WriteOptions& options = {}) {
    if constexpr (std::is_same_v<P, PointCloud>) {
        detail::io::write_cloud(path, points, options);
    } else {
        detail::io::write_cloud(path, to_point_cloud(points), options);
    }
}

/// @brief Writes polylines (curves, e.g. boundary loops) as points + edges.
/// @param path    .ply (element vertex x y z + element edge vertex1 vertex2) or .obj (`l a b`).
/// @param points  the vertices.
/// @param edges   pairs of indices into `points`.
/// @param options WriteOptions::binary / big_endian (PLY only).
/// @pre finite points; edge indices below points.size().
/// @throws invalid_input before writing when the precondition fails; io_error for an
///         unsupported extension or a write failure.
inline void write_polylines(const std::filesystem::path& path, const std::vector<Vec3>& points,
                            const std::vector<std::array<Index, 2>>& edges, const WriteOptions& options = {}) {
    const std::string ext = detail::io::lower_extension(path);
    if (ext != ".ply" && ext != ".obj")
        throw io_error(path.string(), "unsupported extension '" + path.extension().string() +
                                          "' for polylines; kintsugi writes them as .ply or .obj");
    detail::io::check_finite_for_write(points, "kintsugi::write_polylines", "point");
    for (std::size_t e = 0; e < edges.size(); ++e)
        for (const Index v : edges[e])
            if (v >= points.size())
                throw invalid_input("kintsugi::write_polylines: edge " + std::to_string(e) + " uses point " +
                                    std::to_string(v) + ", out of range (there are " +
                                    std::to_string(points.size()) + " points)");
    detail::io::AtomicOutputFile out(path);
    if (ext == ".ply") {
        detail::io::PlyWriteData d;
        d.vertices = &points;
        d.edges = &edges;
        detail::io::write_ply(out, d, options.binary, options.big_endian);
    } else {
        detail::io::write_obj(out, points, nullptr, nullptr, &edges);
    }
    out.commit();
}

}  // namespace kintsugi
