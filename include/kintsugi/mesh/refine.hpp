// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file refine.hpp
/// @brief Split-and-flip refinement of a HalfedgeMesh: long edges split at their
/// midpoints, then edges flipped to the intrinsic Delaunay criterion, until no edge is
/// too long. The splitting half of isotropic remeshing (Botsch & Kobbelt, "A remeshing
/// approach to multiresolution modeling", SGP 2004), without collapses, so the
/// connectivity only gains vertices and the topology never changes. Shared by the hole
/// fill (mesh/holes.hpp: the patch refined to the surrounding density) and the
/// reconstruction (reconstruct/pu_graphcut.hpp: the cut's surface refined to the
/// samples' spacing).

#include <kintsugi/core/control.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/halfedge_mesh.hpp>

#include <cmath>
#include <cstddef>

namespace kintsugi::detail {

/// Whether the edge of h is locally Delaunay: the angles opposite it sum to at most pi.
inline bool is_locally_delaunay(const HalfedgeMesh& m, Index h) {
    const Index g = m.twin(h);
    if (g == HalfedgeMesh::invalid) return true;
    auto angle = [&](Index e) {
        const Vec3& o = m.position(m.opposite(e));
        const Vec3 u = m.position(m.source(e)) - o, v = m.position(m.target(e)) - o;
        return std::atan2(u.cross(v).norm(), u.dot(v));
    };
    return angle(h) + angle(g) <= Scalar(3.14159265358979323846) + Scalar(1e-12);
}

/// Whether flipping the edge of h would make a triangle with (nearly) collinear corners:
/// after a split at the midpoint, the two halves of the old edge are collinear, and a
/// flip that joins their far ends would make a zero-area triangle.
inline bool flip_degenerates(const HalfedgeMesh& m, Index h) {
    const Index g = m.twin(h);
    if (g == HalfedgeMesh::invalid) return true;
    const Vec3 &a = m.position(m.opposite(h)), &b = m.position(m.opposite(g));
    for (const Index end : {m.source(h), m.target(h)}) {
        const Vec3 u = b - a, v = m.position(end) - a;
        if (!(u.cross(v).norm() > Scalar(1e-9) * u.norm() * v.norm())) return true;
    }
    return false;
}

/// @brief Refines hm in rounds: flips the editable edges to Delaunay; then, per round,
/// splits every editable edge that is too long (each edge considered once per round,
/// halfedges from `first` on, in index order) and flips again; stops after a round
/// without a split or after max_rounds. Deterministic (sequential, index order).
/// @param editable  editable(h): whether the edge of interior halfedge h may be split
///                  or flipped (boundary edges never are)
/// @param too_long  too_long(h, length): whether the edge of h needs a split
/// @param split     split(h): splits the edge of h (hm.split(h, 0.5) plus whatever
///                  per-face or per-vertex data the caller keeps in step)
/// @param progress  polled between sweeps; reports from + (to - from) x round / max_rounds
///                  of the running stage
/// @return the number of splits
template <class Editable, class TooLong, class Split>
std::size_t split_and_flip(HalfedgeMesh& hm, Index first, Editable&& editable, TooLong&& too_long, Split&& split,
                           std::size_t max_rounds, Progress& progress, double from = 0, double to = 1) {
    auto flip_pass = [&]() {
        for (std::size_t sweep = 0; sweep < 100; ++sweep) {
            bool any = false;
            for (Index h = first; h < hm.halfedge_capacity(); ++h) {
                const Index g = hm.twin(h);
                if (g == HalfedgeMesh::invalid || g < h || !editable(h)) continue;
                if (!is_locally_delaunay(hm, h) && !flip_degenerates(hm, h) && hm.flip(h)) any = true;
            }
            progress.check();
            if (!any) break;
        }
    };
    flip_pass();
    std::size_t splits = 0;
    for (std::size_t round = 0; round < max_rounds; ++round) {
        progress.update(from + (to - from) * static_cast<double>(round) / static_cast<double>(max_rounds));
        bool split_any = false;
        const Index end = hm.halfedge_capacity();
        for (Index h = first; h < end; ++h) {
            const Index g = hm.twin(h);
            if (g == HalfedgeMesh::invalid || g < h || !editable(h)) continue;
            const Scalar len = (hm.position(hm.target(h)) - hm.position(hm.source(h))).norm();
            if (!too_long(h, len)) continue;
            split(h);
            ++splits;
            split_any = true;
        }
        if (!split_any) break;
        flip_pass();
    }
    return splits;
}

}  // namespace kintsugi::detail
