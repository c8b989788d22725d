// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file read.hpp
/// @brief Reading meshes and point clouds: PLY (ascii, binary little/big endian), OFF
/// (incl. NOFF/COFF), OBJ, XYZ and PWN, chosen by the file extension (case-insensitive).
///
/// Text (OBJ, OFF, XYZ, PWN, the PLY header and ascii body) may start with a UTF-8
/// byte-order mark and use LF, CRLF or old-Mac CR line endings; UTF-16/32 text is refused.
/// Only regular files are read (a FIFO or a device, also through a symbolic link, is
/// refused: it may never end).
///
/// Every failure throws kintsugi::io_error whose message starts with the file name and
/// says what is wrong: missing or empty file, malformed header, truncated body, NaN/Inf
/// coordinates or normals, a face index out of range (with the face number), a face with
/// fewer than 3 vertices, or a polygon when ReadOptions::triangulate is false. Header
/// counts are checked against the file size before anything is allocated. The output
/// argument of the template overloads is left untouched when reading fails. File content
/// quoted in a message is escaped (bytes outside printable ASCII as \xHH).
/// The parsers are kintsugi's own (io/detail/, see common.hpp for the measured reasons).

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/io/detail/common.hpp>
#include <kintsugi/io/detail/obj.hpp>
#include <kintsugi/io/detail/off.hpp>
#include <kintsugi/io/detail/ply.hpp>
#include <kintsugi/io/detail/xyz.hpp>
#include <kintsugi/io/options.hpp>

#include <filesystem>
#include <string>
#include <type_traits>
#include <utility>

namespace kintsugi {

namespace detail::io {

/// Reads any supported file into the raw layout (dispatch on the extension).
inline RawGeometry read_any(const std::filesystem::path& path, const ReadOptions& options) {
    const std::string name = path.string();
    const std::string ext = lower_extension(path);
    if (ext != ".ply" && ext != ".off" && ext != ".obj" && ext != ".xyz" && ext != ".pwn")
        throw io_error(name, "unsupported file extension " + quote(path.extension().string()) +
                                 "; kintsugi reads .ply, .off, .obj, .xyz and .pwn");
    const FileBuffer buf = FileBuffer::read(path);
    if (ext == ".ply") return read_ply(buf, options, name);
    if (ext == ".off") return read_off(buf, options, name);
    if (ext == ".obj") return read_obj(buf, options, name);
    return read_xyz(buf, ext == ".pwn", name);
}

}  // namespace detail::io

/// @brief Reads a triangle mesh (or the vertices of a point file, with no faces).
/// @param path    .ply, .off, .obj (faces and vertex normals), .xyz or .pwn (points only:
///                the mesh has vertices and no faces).
/// @param options ReadOptions::triangulate: split polygons into fan triangles (default)
///                or reject them.
/// @param info    optional; receives the format, counts, whether normals/radii were
///                found, how many polygons were triangulated and what was ignored.
/// @return the mesh; `normals` holds one normal per vertex when the file has them.
/// @throws io_error naming the file and what is wrong (see the file comment).
[[nodiscard]] inline IndexedMesh read_mesh(const std::filesystem::path& path, const ReadOptions& options = {},
                                           ReadInfo* info = nullptr) {
    detail::io::RawGeometry g = detail::io::read_any(path, options);
    if (info) *info = std::move(g.info);
    return {.vertices = std::move(g.vertices), .faces = std::move(g.faces), .normals = std::move(g.normals)};
}

/// @brief Reads a point cloud; a mesh file gives its vertices (and vertex normals).
/// @param path .ply (x y z, optional nx ny nz and `radius`), .xyz, .pwn, .off, .obj.
/// @param info optional; see read_mesh(). Faces are still parsed and checked.
/// @return points, normals (empty when the file has none), radii (empty when none).
/// @throws io_error naming the file and what is wrong.
[[nodiscard]] inline PointCloud read_point_cloud(const std::filesystem::path& path, ReadInfo* info = nullptr) {
    detail::io::RawGeometry g = detail::io::read_any(path, ReadOptions{});
    if (info) *info = std::move(g.info);
    return {.points = std::move(g.vertices), .normals = std::move(g.normals), .radii = std::move(g.radii)};
}

/// @brief Reads a triangle mesh into any TopologyMutableMesh (cleared first).
/// @tparam M a TopologyMutableMesh (IndexedMesh, CGAL::Surface_mesh, a user type).
///         Vertex normals are kept only for IndexedMesh.
/// @param path, options, info as read_mesh() above.
/// @param out  replaced by the file's mesh; untouched when an exception is thrown.
/// @throws io_error naming the file and what is wrong, including when `out`'s type
///         rejects a face (e.g. CGAL::Surface_mesh refuses non-manifold faces).
template <TopologyMutableMesh M>
void read_mesh(const std::filesystem::path& path, M& out, const ReadOptions& options = {}, ReadInfo* info = nullptr) {
    ReadInfo local;
    IndexedMesh m = read_mesh(path, options, &local);
    if constexpr (std::is_same_v<M, IndexedMesh>) {
        out = std::move(m);
    } else if constexpr (std::is_default_constructible_v<M> && std::is_move_assignable_v<M>) {
        M tmp;
        try {
            assign_mesh(tmp, m);
        } catch (const invalid_input& e) {
            throw io_error(path.string(), std::string("the output mesh type rejects the file's faces: ") + e.what());
        }
        out = std::move(tmp);
    } else {
        try {
            assign_mesh(out, m);
        } catch (const invalid_input& e) {
            throw io_error(path.string(), std::string("the output mesh type rejects the file's faces: ") + e.what());
        }
    }
    if (info) *info = std::move(local);
}

/// @brief Reads a point cloud into any GrowablePointSet (cleared first).
/// @tparam P a GrowablePointSet (PointCloud, std::vector<Eigen::Vector3d>,
///         CGAL::Point_set_3, a user type). Normals go through
///         point_set_traits<P>::push_back (zero vectors when the file has none; a type
///         with `remove_normal_map()`, like CGAL::Point_set_3, then gets its normal map
///         removed). Radii are kept for a GrowableSurfelSet (PointCloud, a
///         project_surfels view) when the file has them.
/// @param out  replaced by the file's points; untouched when an exception is thrown.
/// @throws io_error naming the file and what is wrong.
template <GrowablePointSet P>
void read_point_cloud(const std::filesystem::path& path, P& out, ReadInfo* info = nullptr) {
    ReadInfo local;
    PointCloud c = read_point_cloud(path, &local);
    if constexpr (std::is_same_v<P, PointCloud>) {
        out = std::move(c);
    } else {
        point_set_traits<P>::clear(out);
        const bool normals = local.has_normals;
        for (std::size_t i = 0; i < c.points.size(); ++i) {
            const Vec3 n = normals ? c.normals[i] : Vec3::Zero();
            if constexpr (GrowableSurfelSet<P>) {
                if (local.has_radii) {
                    point_set_traits<P>::push_back(out, c.points[i], n, c.radii[i]);
                    continue;
                }
            }
            point_set_traits<P>::push_back(out, c.points[i], n);
        }
        if constexpr (requires { out.remove_normal_map(); })
            if (!normals) out.remove_normal_map();
    }
    if (info) *info = std::move(local);
}

}  // namespace kintsugi
