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
///
/// Several files that must appear together (a mesh and its feature lines) go through
/// an OutputBatch; check_writable() tells before a long computation whether a path can
/// be written; remove_temporary_outputs() is for a program's SIGINT/SIGTERM handling.

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
#include <stop_token>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace kintsugi {

/// @brief Output files that appear together, and writes that can be interrupted. A
/// write given `WriteOptions::batch = &batch` leaves its finished file (a temporary
/// file in the target's directory) in the batch; commit() renames them all into
/// place, in the order written. Destroying the batch without commit() removes them,
/// so a failure anywhere leaves none of the targets changed. A stop request on the
/// batch's token makes a write under way throw io_error ("interrupted") at its next
/// 1 MB block. A character device or FIFO target is written at once, not batched.
class OutputBatch {
public:
    /// @param stop interrupts the batch's writes (empty: never).
    explicit OutputBatch(std::stop_token stop = {}) : stop_(std::move(stop)) {}
    OutputBatch(const OutputBatch&) = delete;
    OutputBatch& operator=(const OutputBatch&) = delete;
    ~OutputBatch() { discard(); }

    /// Renames every file into place. @throws io_error naming the file a rename failed
    /// for; the files not yet renamed are removed.
    void commit() {
        for (std::size_t i = 0; i < pending_.size(); ++i) {
            std::error_code ec;
            detail::io::temporary_files().rename(pending_[i].temporary, pending_[i].target, ec);
            if (ec) {
                const std::string name = pending_[i].name;
                pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(i));
                discard();
                throw io_error(name, "cannot rename the temporary file into place: " + ec.message());
            }
        }
        pending_.clear();
    }
    /// Removes the files written so far; no target changes.
    void discard() noexcept {
        for (const auto& p : pending_) {
            std::error_code ec;
            std::filesystem::remove(p.temporary, ec);
            detail::io::temporary_files().forget(p.temporary);
        }
        pending_.clear();
    }
    /// Number of files waiting for commit().
    [[nodiscard]] std::size_t size() const { return pending_.size(); }
    /// The token that interrupts the batch's writes.
    [[nodiscard]] const std::stop_token& stop_token() const { return stop_; }

    /// Used by the writers: finishes `out` and keeps it for commit().
    void adopt(detail::io::AtomicOutputFile& out) {
        detail::io::PendingOutput p = out.finish();
        if (!p.temporary.empty()) pending_.push_back(std::move(p));
    }

private:
    std::stop_token stop_;
    std::vector<detail::io::PendingOutput> pending_;
};

/// @brief Removes the temporary files of every write under way in this process; their
/// targets stay as they were. For a program that handles SIGINT/SIGTERM: call it from
/// an ordinary thread (one waiting in sigwait, say) before exiting, not from a signal
/// handler (it takes a lock). Writes still running afterwards fail with io_error.
/// @return the number of files removed.
inline std::size_t remove_temporary_outputs() { return detail::io::temporary_files().remove_all(); }

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

/// The stop token of the options' batch (none without a batch).
inline std::stop_token write_stop(const WriteOptions& options) {
    return options.batch ? options.batch->stop_token() : std::stop_token{};
}

/// Commits `out` now, or leaves it in the options' batch.
inline void finish_output(AtomicOutputFile& out, const WriteOptions& options) {
    if (options.batch)
        options.batch->adopt(out);
    else
        out.commit();
}

/// Throws io_error unless `path` has an extension the writers of `kind` support.
inline void check_extension(const std::filesystem::path& path, const std::string& kind) {
    const std::string ext = lower_extension(path);
    bool ok = false;
    const char* list = "";
    const char* what = "";
    if (kind == "mesh") {
        ok = ext == ".ply" || ext == ".off" || ext == ".obj";
        list = "meshes as .ply, .off or .obj";
        what = "a mesh";
    } else if (kind == "point cloud") {
        ok = ext == ".ply" || ext == ".off" || ext == ".obj" || ext == ".xyz" || ext == ".pwn";
        list = "point clouds as .ply, .xyz, .pwn, .off or .obj";
        what = "a point cloud";
    } else {
        ok = ext == ".ply" || ext == ".obj";
        list = "polylines as .ply or .obj";
        what = "polylines";
    }
    if (!ok)
        throw io_error(path.string(), "unsupported extension '" + detail::printable(path.extension().string()) + "' for " + what +
                                          "; kintsugi writes " + list);
}

/// `x` itself when it is already an `Internal` (no copy), else copy(x).
template <class Internal, class T, class Copy>
decltype(auto) as_internal(const T& x, Copy&& copy) {
    if constexpr (std::is_same_v<T, Internal>)
        return (x);
    else
        return copy(x);
}

/// Writes `d` in the format of `path`'s (checked) extension: PLY with everything `d` holds,
/// OFF with normals and faces, OBJ with normals, faces and edges, XYZ/PWN with normals; then commits it or leaves it in
/// the options' batch.
inline void write_by_extension(const std::filesystem::path& path, const PlyWriteData& d, const WriteOptions& options) {
    const std::string ext = lower_extension(path);
    AtomicOutputFile out(path, write_stop(options));
    if (ext == ".ply")
        write_ply(out, d, options.binary, options.big_endian);
    else if (ext == ".off")
        write_off(out, *d.vertices, d.normals, d.faces);
    else if (ext == ".obj")
        write_obj(out, *d.vertices, d.normals, d.faces, d.edges);
    else
        write_xyz(out, *d.vertices, d.normals);
    finish_output(out, options);
}

inline void write_indexed_mesh(const std::filesystem::path& path, const IndexedMesh& m, const WriteOptions& options) {
    check_extension(path, "mesh");
    check_mesh_for_write(m, "kintsugi::write_mesh");
    write_by_extension(path, {.vertices = &m.vertices, .normals = &m.normals, .faces = &m.faces}, options);
}

inline void write_cloud(const std::filesystem::path& path, const PointCloud& c, const WriteOptions& options) {
    check_extension(path, "point cloud");
    check_cloud_for_write(c, "kintsugi::write_point_cloud");
    if (lower_extension(path) == ".pwn" && c.normals.empty() && !c.points.empty())
        throw invalid_input("kintsugi::write_point_cloud: a .pwn file needs normals and the point set has none; "
                            "estimate them first (kintsugi::estimate_normals) or write .xyz");
    write_by_extension(path, {.vertices = &c.points, .normals = &c.normals, .radii = &c.radii}, options);
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
    detail::io::write_indexed_mesh(path, detail::io::as_internal<IndexedMesh>(mesh, to_indexed_mesh<M>), options);
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
    detail::io::write_cloud(path, detail::io::as_internal<PointCloud>(points, to_point_cloud<P>), options);
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
    detail::io::check_extension(path, "polylines");
    detail::io::check_finite_for_write(points, "kintsugi::write_polylines", "point");
    for (std::size_t e = 0; e < edges.size(); ++e)
        for (const Index v : edges[e])
            if (v >= points.size())
                throw invalid_input("kintsugi::write_polylines: edge " + std::to_string(e) + " uses point " +
                                    std::to_string(v) + ", out of range (there are " +
                                    std::to_string(points.size()) + " points)");
    detail::io::write_by_extension(path, {.vertices = &points, .edges = &edges}, options);
}

/// What an output file will hold, for check_writable().
enum class OutputKind { mesh, point_cloud, polylines };

/// @brief Checks, before a long computation, that `path` can be written as `kind`: a
/// supported extension, an existing writable directory (or a character device / FIFO),
/// a file name short enough. Creates and removes a temporary file in the directory;
/// the target itself is not touched.
/// @throws io_error naming `path` and the problem (the message the write would give).
inline void check_writable(const std::filesystem::path& path, OutputKind kind) {
    detail::io::check_extension(path, kind == OutputKind::mesh          ? "mesh"
                                      : kind == OutputKind::point_cloud ? "point cloud"
                                                                        : "polylines");
    std::error_code ec;
    const std::filesystem::file_status st = std::filesystem::status(path, ec);
    // A device or FIFO is opened only by the write itself (opening a FIFO blocks).
    if (std::filesystem::is_character_file(st) || std::filesystem::is_fifo(st)) return;
    const detail::io::AtomicOutputFile probe(path);  // its temporary file is removed unwritten
}

}  // namespace kintsugi
