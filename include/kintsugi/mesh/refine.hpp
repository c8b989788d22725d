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
#include <cstdint>
#include <vector>

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
/// halfedges from `first` on, in index order) and flips again around the new vertices;
/// stops after a round without a split or after max_rounds. The flips run from a work
/// queue (an edge is rechecked only when a flip or split changed a face beside it), so
/// a round costs its splits, not the mesh: sweeping every edge until none flipped took
/// 15 s of a 38 s refinement at 1.2M vertices. Deterministic (sequential, FIFO order).
/// @param editable  editable(h): whether the edge of interior halfedge h may be split
///                  or flipped (boundary edges never are)
/// @param too_long  too_long(h, length): whether the edge of h needs a split
/// @param split     split(h): splits the edge of h (hm.split(h, 0.5) plus whatever
///                  per-face or per-vertex data the caller keeps in step)
/// @param progress  polled between rounds and every 2^16 flips; reports from + (to -
///                  from) x round / max_rounds of the running stage
/// @return the number of splits
template <class Editable, class TooLong, class Split>
std::size_t split_and_flip(HalfedgeMesh& hm, Index first, Editable&& editable, TooLong&& too_long, Split&& split,
                           std::size_t max_rounds, Progress& progress, double from = 0, double to = 1) {
    // The queue holds each edge once, by its smaller halfedge.
    std::vector<Index> queue;
    std::vector<std::uint8_t> queued;
    auto push = [&](Index h) {
        const Index g = hm.twin(h);
        if (g == HalfedgeMesh::invalid) return;
        const Index e = g < h ? g : h;
        if (e < first) return;
        if (queued.size() < hm.halfedge_capacity()) queued.resize(hm.halfedge_capacity(), 0);
        if (queued[e] || !editable(e)) return;
        queued[e] = 1;
        queue.push_back(e);
    };
    // Flips until the queue is empty; each flip queues the four edges of its quad. At
    // most 20 flips per edge queued (extrinsic flips on a curved mesh need not end).
    auto flip_queue = [&]() {
        const std::size_t budget = 20 * queue.size() + 1024;
        std::size_t flips = 0;
        for (std::size_t i = 0; i < queue.size(); ++i) {
            const Index h = queue[i];
            queued[h] = 0;
            if (hm.twin(h) == HalfedgeMesh::invalid || !editable(h)) continue;
            if (is_locally_delaunay(hm, h) || flip_degenerates(hm, h) || !hm.flip(h)) continue;
            if (++flips > budget) break;
            if ((flips & 0xFFFF) == 0) progress.check();
            const Index g = hm.twin(h);
            for (const Index e : {HalfedgeMesh::next(h), HalfedgeMesh::prev(h), HalfedgeMesh::next(g),
                                  HalfedgeMesh::prev(g)})
                push(e);
        }
        for (const Index h : queue) queued[h] = 0;
        queue.clear();
        progress.check();
    };
    for (Index h = first; h < hm.halfedge_capacity(); ++h) push(h);
    flip_queue();
    std::size_t splits = 0;
    std::vector<Index> around;
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
            // The faces around the new vertex (h now ends there): their spokes and rims.
            hm.outgoing_halfedges(hm.target(h), around);
            for (const Index e : around) {
                push(e);
                push(HalfedgeMesh::next(e));
            }
        }
        if (!split_any) break;
        flip_queue();
    }
    return splits;
}

}  // namespace kintsugi::detail
