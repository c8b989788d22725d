// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file vertex_subset.hpp
/// @brief What the operations that move a chosen subset of a mesh's vertices share
/// (smooth_taubin, fair_biharmonic, the hole fill): their result, reading the positions
/// with the finite-coordinate check, checking the per-vertex flags, writing the moved
/// vertices back.

#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/topology.hpp>

#include <limits>

#include <cstdint>
#include <string>
#include <vector>

namespace kintsugi {

/// Result of an operation that moves a chosen subset of a mesh's vertices
/// (fair_biharmonic: FairResult, smooth_taubin: TaubinResult).
struct VertexSubsetResult {
    /// ok, or cancelled (through the parameters' RunControl; the mesh is then untouched).
    Status status = Status::ok;
    /// The chosen vertices that have a neighbour: those the operation moves. 0 when
    /// nothing moved: cancelled, or fair_biharmonic's system could not be factorised.
    std::size_t moved_vertices = 0;
    std::vector<StageTiming> timings;  ///< fair_biharmonic: "topology", "solve"; smooth_taubin: "taubin"
};

}  // namespace kintsugi

namespace kintsugi::detail {

/// The positions of every vertex of `mesh`; throws invalid_input (prefixed with `fn`,
/// e.g. "kintsugi::fair_biharmonic: ") naming the first vertex with a NaN or infinite coordinate.
template <TriangleMesh M>
std::vector<Vec3> finite_vertex_positions(const M& mesh, const std::string& fn) {
    std::vector<Vec3> x(kintsugi::num_vertices(mesh));
    for (Index v = 0; v < x.size(); ++v) {
        x[v] = kintsugi::vertex_position(mesh, v);
        if (!x[v].allFinite())
            throw invalid_input(fn + "vertex " + std::to_string(v) + " has a NaN or infinite coordinate; remove it");
    }
    return x;
}

/// Throws invalid_input unless `flags` has one entry per vertex (or is empty, when
/// `empty_means_all`): "<fn><name> has 3 entries for 441 vertices; ...".
inline void check_vertex_flags(const std::vector<std::uint8_t>& flags, std::size_t nv, const std::string& fn,
                               const char* name, bool empty_means_all) {
    if (flags.size() == nv || (empty_means_all && flags.empty())) return;
    throw invalid_input(fn + name + " has " + std::to_string(flags.size()) + " entries for " + std::to_string(nv) +
                        " vertices; give one flag per vertex" + (empty_means_all ? " or leave it empty" : ""));
}

/// Writes x[v] into `mesh` for every vertex with flags[v] != 0 (every vertex when flags is empty).
template <MutableTriangleMesh M>
void write_flagged_positions(M& mesh, const std::vector<Vec3>& x, const std::vector<std::uint8_t>& flags) {
    for (Index v = 0; v < x.size(); ++v)
        if (flags.empty() || flags[v] != 0) kintsugi::set_vertex_position(mesh, v, x[v]);
}

/// The unknowns of a vertex-subset operation: the vertices with flags[v] != 0 (every
/// vertex when flags is empty) that have a neighbour, increasing, and each vertex's
/// column among them (`none` for the others).
struct MovableVertices {
    static constexpr Index none = std::numeric_limits<Index>::max();
    std::vector<Index> vertices;
    std::vector<Index> column;
};

inline MovableVertices movable_vertices(const MeshTopology& topo, std::size_t nv,
                                        const std::vector<std::uint8_t>& flags) {
    MovableVertices m;
    m.column.assign(nv, MovableVertices::none);
    for (Index v = 0; v < nv; ++v)
        if ((flags.empty() || flags[v] != 0) && !topo.vertex_neighbors(v).empty()) {
            m.column[v] = m.vertices.size();
            m.vertices.push_back(v);
        }
    return m;
}

/// Marks `vertices` and their neighbours (n flags): the rows of an operator that reads a
/// one-ring (a Laplacian) and involves one of the vertices.
inline std::vector<std::uint8_t> rows_near(const MeshTopology& topo, const std::vector<Index>& vertices,
                                           std::size_t n) {
    std::vector<std::uint8_t> row(n, 0);
    for (const Index v : vertices) {
        row[v] = 1;
        for (const Index u : topo.vertex_neighbors(v)) row[u] = 1;
    }
    return row;
}

}  // namespace kintsugi::detail
