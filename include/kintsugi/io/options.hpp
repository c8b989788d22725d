// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file options.hpp
/// @brief Options and reports of the kintsugi readers and writers (included by
/// io/read.hpp and io/write.hpp).

#include <cstddef>
#include <string>
#include <vector>

namespace kintsugi {

class OutputBatch;

/// Options of read_mesh().
struct ReadOptions {
    /// Polygons with more than 3 vertices are split into fan triangles (v0, vi, vi+1) and
    /// counted in ReadInfo::polygons_triangulated. When false, such a face is an io_error.
    bool triangulate = true;
};

/// What a reader found in the file.
struct ReadInfo {
    /// "ply-ascii", "ply-binary-le", "ply-binary-be", "off", "obj", "xyz" or "pwn".
    std::string format;
    /// Number of vertices (points) read.
    std::size_t vertices = 0;
    /// Number of triangles produced (after triangulating polygons).
    std::size_t faces = 0;
    /// Whether every vertex has a normal (PLY nx ny nz, OFF NOFF, OBJ vn, XYZ 6 columns, PWN).
    bool has_normals = false;
    /// Whether every vertex has a PLY `radius` property (surfels).
    bool has_radii = false;
    /// Number of faces of the file with more than 3 vertices that were split into triangles.
    std::size_t polygons_triangulated = 0;
    /// What the file holds that the reader did not use, e.g. "vertex.confidence",
    /// "face.flags", "edge.vertex1" (PLY element.property), "vt", "usemtl" (OBJ statements),
    /// "vertex colors" (COFF). Each entry appears once, with bytes outside printable ASCII
    /// escaped as \xHH; after 64 entries the list ends with "...".
    std::vector<std::string> ignored_properties;
};

/// Options of the writers. Formats are chosen by the file extension (case-insensitive).
struct WriteOptions {
    /// PLY only: binary (default) or ascii. The text formats (OFF, OBJ, XYZ, PWN) ignore it.
    bool binary = true;
    /// PLY binary only: big-endian instead of little-endian.
    bool big_endian = false;
    /// When set, the finished file waits in the batch and appears only at
    /// batch->commit(), together with the batch's other files; a stop request on the
    /// batch's token interrupts the write (see OutputBatch).
    OutputBatch* batch = nullptr;
};

}  // namespace kintsugi
