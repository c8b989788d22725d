// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file vertex_subset.hpp
/// @brief What the operations that move a chosen subset of a mesh's vertices share
/// (smooth_taubin, fair_biharmonic, the hole fill): reading the positions with the
/// finite-coordinate check, checking the per-vertex flags, writing the moved vertices back.

#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/types.hpp>

#include <cstdint>
#include <string>
#include <vector>

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

}  // namespace kintsugi::detail
