// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file holes.hpp
/// @brief Holes of a triangle mesh: its boundary loops with their length, area and
/// extent, the rule that tells the outer border of an open scan from a hole, and the
/// thin-plate hole fill (triangulate, refine to the surrounding density, fair).
///
/// @code
/// auto loops = kintsugi::find_boundary_loops(mesh);          // any TriangleMesh
/// std::vector<std::vector<kintsugi::Index>> holes;
/// for (const auto& l : loops.loops) if (!l.outer) holes.push_back(l.vertices);
/// auto r = kintsugi::fill_holes(mesh, holes);                // any TopologyMutableMesh
/// @endcode

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/disjoint_sets.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/fair.hpp>
#include <kintsugi/mesh/halfedge_mesh.hpp>
#include <kintsugi/mesh/refine.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/mesh/vertex_subset.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

/// One boundary loop of a mesh.
struct BoundaryLoop {
    /// The loop's vertices, in the direction of MeshTopology::boundary_loops(): the
    /// faces along the loop run vertices[i+1] -> vertices[i], so a face
    /// (vertices[i], vertices[i+1], x) fills the hole with its neighbours' orientation.
    std::vector<Index> vertices;
    Scalar length = 0;   ///< sum of its edge lengths
    /// Area of the loop projected on the plane where that area is largest: the norm of
    /// the vector area ½ Σ p_i × p_{i+1} (exact for a planar loop; a lower bound of the
    /// area of any patch that fills it).
    Scalar area = 0;
    Vec3 normal = Vec3::Zero();  ///< unit vector area (the hole's mean normal); zero if area is 0
    Scalar extent = 0;           ///< diagonal of the loop's bounding box
    Index component = 0;         ///< connected component (of faces sharing an edge) it bounds
    bool outer = false;          ///< the outer border of an open scan (see HoleParams)
};

/// Parameters of find_boundary_loops.
struct HoleParams {
    /// Outer-border rule. A loop is the outer border of an open scan when (1) the surface
    /// along it turns away from it: the vector area of the faces with a vertex on the loop
    /// points against the loop's own vector area (around a hole both point the same way),
    /// and (2) its extent (bounding-box diagonal) is at least this fraction of the
    /// diagonal of its component (faces sharing an edge). Every other loop is a hole.
    /// Range [0, inf), default 0.75; above 1 no loop is ever outer (a closed object with
    /// holes). Why: on the nine Stanford bunny range scans the rule agrees with the
    /// scanner's view (a loop is outer when its vector area points away from the scanner)
    /// on 499 of 515 loops (the largest extent alone: 431); every loop that (1) calls
    /// outer there spans at least 0.75 of its component (grid 1.0, hemisphere rim 0.94),
    /// and (2) keeps a rim that turns the surface around but spans little of it a hole. See
    /// docs/methods/mesh_editing.md.
    Scalar outer_border_extent = 0.75;
};

/// Result of find_boundary_loops.
struct BoundaryLoops {
    std::vector<BoundaryLoop> loops;  ///< in the order of MeshTopology::boundary_loops()
    std::size_t components = 0;       ///< connected components of faces (sharing an edge)
    /// Indices into loops of the holes (the loops that are not outer), increasing.
    [[nodiscard]] std::vector<Index> holes() const {
        std::vector<Index> h;
        for (Index i = 0; i < loops.size(); ++i)
            if (!loops[i].outer) h.push_back(i);
        return h;
    }
};

namespace detail {

/// find_boundary_loops on the positions `x` (finite) and the topology of the mesh: one
/// non-template body that every mesh type shares (the template checks and reads).
inline BoundaryLoops boundary_loops_indexed(const std::vector<Vec3>& x, const MeshTopology& topo,
                                            const HoleParams& params) {
    const std::size_t nv = x.size();
    const auto& faces = topo.faces();
    // Components of faces sharing an edge (union-find over faces): a patch that touches
    // the rest at one vertex only is a component of its own, with its own border.
    DisjointSets<Index> sets(faces.size());
    for (Index e = 0; e < topo.num_edges(); ++e) {
        const auto ef = topo.edge_faces(e);
        for (std::size_t k = 1; k < ef.size(); ++k) sets.unite(ef[0], ef[k]);
    }
    std::vector<Index> comp(faces.size(), HalfedgeMesh::invalid);
    std::vector<Vec3> face_area(faces.size());  // vector area: normal times area, doubled
    BoundaryLoops out;
    std::vector<BoundingBox> boxes;
    for (Index f = 0; f < faces.size(); ++f) {
        const Index r = sets.find(f);
        if (comp[r] == HalfedgeMesh::invalid) {
            comp[r] = out.components++;
            boxes.emplace_back();
        }
        comp[f] = comp[r];
        for (const Index v : faces[f]) boxes[comp[f]].extend(x[v]);
        face_area[f] = (x[faces[f][1]] - x[faces[f][0]]).cross(x[faces[f][2]] - x[faces[f][0]]);
    }
    std::vector<Index> seen(nv, HalfedgeMesh::invalid);  // per vertex: last loop that visited it
    std::vector<Index> face_seen(faces.size(), HalfedgeMesh::invalid);
    for (auto& lv : topo.boundary_loops()) {
        const Index li = out.loops.size();
        BoundaryLoop l;
        BoundingBox box;
        Vec3 va = Vec3::Zero();
        for (std::size_t i = 0; i < lv.size(); ++i) {
            const Vec3& p = x[lv[i]];
            const Vec3& q = x[lv[(i + 1) % lv.size()]];
            l.length += (q - p).norm();
            va += p.cross(q) / 2;
            box.extend(p);
        }
        l.area = va.norm();
        if (l.area > 0) l.normal = va / l.area;
        l.extent = box.diagonal();
        // The component of the face on the loop's first edge.
        const auto e0 = topo.find_edge(lv[0], lv[1 % lv.size()]);
        l.component = e0 && !topo.edge_faces(*e0).empty() ? comp[topo.edge_faces(*e0)[0]] : 0;
        // Which way the surface along the loop faces: the vector area of the faces with
        // a vertex on the loop. Around a hole it faces like the loop's vector area (the
        // loop runs against its faces); along the outer border of a scan it faces the
        // other way (the patch lies inside the loop, its faces turn the loop around).
        Vec3 around = Vec3::Zero();
        for (const Index v : lv) {
            if (seen[v] == li) continue;
            seen[v] = li;
            for (const Index f : topo.vertex_faces(v))
                if (face_seen[f] != li) {
                    face_seen[f] = li;
                    around += face_area[f];
                }
        }
        l.outer = va.dot(around) < 0 && l.component < boxes.size() &&
                  l.extent >= params.outer_border_extent * boxes[l.component].diagonal();
        l.vertices = std::move(lv);
        out.loops.push_back(std::move(l));
    }
    return out;
}

}  // namespace detail

/// @brief Boundary loops of any triangle mesh with their length, projected area, extent,
/// and the outer-border rule of HoleParams.
/// @tparam M a TriangleMesh (IndexedMesh, Eigen V/F view, CGAL::Surface_mesh, ...).
/// @param mesh   any combinatorics (see MeshTopology::boundary_loops for non-manifold cases)
/// @param params the outer-border rule
/// @throws invalid_input for a face index out of range, a NaN/Inf coordinate or
///         outer_border_extent < 0 / NaN.
template <TriangleMesh M>
[[nodiscard]] BoundaryLoops find_boundary_loops(const M& mesh, const HoleParams& params = {}) {
    const std::string fn = "kintsugi::find_boundary_loops: ";
    if (!(params.outer_border_extent >= 0))
        throw invalid_input(fn + "outer_border_extent = " + std::to_string(params.outer_border_extent) +
                            " must be >= 0 (default 0.75; above 1 disables the outer border)");
    const std::vector<Vec3> x = detail::finite_vertex_positions(mesh, fn);
    const MeshTopology topo(mesh);
    return detail::boundary_loops_indexed(x, topo, params);
}

/// Parameters of fill_holes.
struct FillParams {
    /// Refinement: a patch edge longer than this factor times the hole's target length
    /// is split, in [1, 4], default 4/3 (the usual isotropic-remeshing bound: edges end
    /// between 2/3 and 4/3 of the target). The target length of a hole is the mean
    /// length of the mesh edges at its loop's vertices (the surrounding density).
    Scalar split_factor = Scalar(4) / 3;
    /// Largest number of split-and-flip rounds, >= 1 (default 30: each round halves the
    /// longest patch edges, 30 reaches a 10^9 ratio of hole size to density).
    std::size_t max_rounds = 30;
    /// false: keep the refined, flat (minimal-area) patch, skip the thin-plate fairing.
    bool fair = true;
    /// Pull of the new vertices to their unfaired positions in the least-squares
    /// fairing, used only when the bi-Laplace system is singular: FairParams::delta
    /// (finite, >= 0, default 1e-8).
    Scalar fair_delta = detail::default_fair_delta;
    /// Progress callback and stop token (default: none); a cancelled run leaves the mesh untouched.
    RunControl control{};
};

/// Result of fill_holes.
struct FillResult {
    Status status = Status::ok;
    std::size_t filled_holes = 0;          ///< loops closed
    std::vector<Index> unfilled_holes;     ///< indices into the given loops that could not be
                                           ///< triangulated without a duplicate edge
    std::size_t new_vertices = 0;          ///< appended after the existing vertices
    std::size_t new_faces = 0;             ///< appended after the existing faces
    std::vector<StageTiming> timings;      ///< triangulate, refine, fair, write
};

namespace detail {

/// Minimum-area triangulation of a closed polygon (Barequet and Sharir 1995; the first
/// step of Liepa 2003), O(n^3) time, O(n^2) memory, by dynamic programming over the
/// sub-polygons. A chord (i, j) for which forbidden(i, j) holds is never used (an edge
/// already in the mesh). Returns triangles (i, k, j), i < k < j, in loop indices; empty
/// when no triangulation avoids the forbidden chords.
template <class Forbidden>
std::vector<std::array<Index, 3>> min_area_triangulation(const std::vector<Vec3>& p, Forbidden forbidden,
                                                         Progress& progress) {
    const std::size_t n = p.size();
    constexpr Scalar inf = std::numeric_limits<Scalar>::infinity();
    std::vector<Scalar> w(n * n, inf);
    std::vector<Index> arg(n * n, 0);
    for (Index i = 0; i + 1 < n; ++i) w[i * n + i + 1] = 0;
    std::vector<std::uint8_t> ok(n * n, 1);
    for (Index i = 0; i < n; ++i)
        for (Index j = i + 2; j < n; ++j)
            if (!(i == 0 && j == n - 1) && forbidden(i, j)) ok[i * n + j] = 0;
    for (Index len = 2; len < n; ++len) {
        progress.update(static_cast<double>(len) / static_cast<double>(n));
        for (Index i = 0; i + len < n; ++i) {
            const Index j = i + len;
            if (!ok[i * n + j]) continue;
            Scalar best = inf;
            Index bk = 0;
            for (Index k = i + 1; k < j; ++k) {
                const Scalar c = w[i * n + k] + w[k * n + j];
                if (!(c < inf)) continue;
                const Scalar a = (p[k] - p[i]).cross(p[j] - p[i]).norm() / 2;
                if (c + a < best) {
                    best = c + a;
                    bk = k;
                }
            }
            w[i * n + j] = best;
            arg[i * n + j] = bk;
        }
    }
    std::vector<std::array<Index, 3>> tris;
    if (!(w[n - 1] < inf)) return tris;
    std::vector<std::pair<Index, Index>> stack{{0, n - 1}};
    while (!stack.empty()) {
        const auto [i, j] = stack.back();
        stack.pop_back();
        if (j < i + 2) continue;
        const Index k = arg[i * n + j];
        tris.push_back({i, k, j});
        stack.emplace_back(i, k);
        stack.emplace_back(k, j);
    }
    return tris;
}

/// Loops up to this many vertices are triangulated by the O(n^3) dynamic programme
/// whole (200: 1.3M steps, 0.7 MB); longer ones are cut first (hole_triangulation).
inline constexpr std::size_t min_area_whole_loop = 200;

/// Triangulation of a closed polygon of any length in O(n^2) time and O(n) memory beyond
/// the pieces: while a piece has more than min_area_whole_loop vertices it is cut along
/// its shortest chord that leaves at least a quarter of the piece's vertices on each side
/// (never a forbidden one), then each piece gets the minimum-area triangulation. Up to
/// min_area_whole_loop vertices this is min_area_triangulation itself. Returns triangles
/// (i, k, j) in loop indices, oriented like the loop (i < k < j within each piece's own
/// order); empty when a piece cannot avoid the forbidden chords.
template <class Forbidden>
std::vector<std::array<Index, 3>> hole_triangulation(const std::vector<Vec3>& p, Forbidden forbidden,
                                                     Progress& progress) {
    const std::size_t n = p.size();
    if (n <= min_area_whole_loop) return min_area_triangulation(p, forbidden, progress);
    std::vector<std::array<Index, 3>> tris;
    std::vector<std::vector<Index>> stack(1);
    stack[0].resize(n);
    std::iota(stack[0].begin(), stack[0].end(), Index{0});
    std::size_t done = 0;
    while (!stack.empty()) {
        const std::vector<Index> q = std::move(stack.back());
        stack.pop_back();
        const std::size_t m = q.size();
        if (m <= min_area_whole_loop) {
            std::vector<Vec3> pq(m);
            for (std::size_t i = 0; i < m; ++i) pq[i] = p[q[i]];
            const auto t = min_area_triangulation(pq, [&](Index a, Index b) { return forbidden(q[a], q[b]); }, progress);
            if (t.empty()) return {};
            for (const auto& f : t) tris.push_back({q[f[0]], q[f[1]], q[f[2]]});
            done += m;
            progress.update(static_cast<double>(done) / static_cast<double>(2 * n));
            continue;
        }
        // Shortest admissible chord (a, b), a < b, both sides keeping >= m/4 vertices.
        const std::size_t side = m / 4;
        Scalar best = std::numeric_limits<Scalar>::infinity();
        std::size_t ba = 0, bb = 0;
        for (std::size_t a = 0; a < m; ++a) {
            for (std::size_t b = a + side; b + side <= a + m && b < m; ++b) {
                const Scalar d = (p[q[b]] - p[q[a]]).squaredNorm();
                if (d < best && !forbidden(q[a], q[b])) {
                    best = d;
                    ba = a;
                    bb = b;
                }
            }
            progress.check();
        }
        if (!(best < std::numeric_limits<Scalar>::infinity())) return {};
        // Pieces q[ba..bb] and q[bb..m) + q[0..ba], each closed by the chord; the first
        // and last vertex of a piece are the chord's ends, so the piece's own closing
        // edge (0, last) is the chord.
        stack.emplace_back(q.begin() + static_cast<std::ptrdiff_t>(ba), q.begin() + static_cast<std::ptrdiff_t>(bb) + 1);
        std::vector<Index> other(q.begin() + static_cast<std::ptrdiff_t>(bb), q.end());
        other.insert(other.end(), q.begin(), q.begin() + static_cast<std::ptrdiff_t>(ba) + 1);
        stack.push_back(std::move(other));
    }
    return tris;
}

/// Appends a patch's vertices and faces (indices already past the existing vertices) to
/// any TopologyMutableMesh; an IndexedMesh with one normal per vertex gets area-weighted
/// normals for the new vertices. Shared by the hole fillers.
template <TopologyMutableMesh M>
void append_patch(M& mesh, const std::vector<Vec3>& new_pos, const std::vector<Face>& new_faces) {
    const std::size_t nv0 = kintsugi::num_vertices(mesh), nf0 = kintsugi::num_faces(mesh);
    if constexpr (requires { mesh_traits<M>::reserve(mesh, std::size_t{}, std::size_t{}); })
        mesh_traits<M>::reserve(mesh, nv0 + new_pos.size(), nf0 + new_faces.size());
    for (const Vec3& p : new_pos) mesh_traits<M>::add_vertex(mesh, p);
    for (const Face& f : new_faces) mesh_traits<M>::add_face(mesh, f);
    if constexpr (std::is_same_v<M, IndexedMesh>) {
        if (mesh.normals.size() == nv0 && nv0 > 0 && !new_pos.empty()) {
            mesh.normals.resize(mesh.vertices.size(), Vec3::Zero());
            for (const Face& f : new_faces) {
                const Vec3 n = (mesh.vertices[f[1]] - mesh.vertices[f[0]]).cross(mesh.vertices[f[2]] - mesh.vertices[f[0]]);
                for (const Index v : f)
                    if (v >= nv0) mesh.normals[v] += n;
            }
            for (Index v = nv0; v < mesh.vertices.size(); ++v)
                if (mesh.normals[v].norm() > 0) mesh.normals[v].normalize();
        }
    }
}

/// The reach of a hole: the bounding box of its loop (vertices `loop` of `pos`) grown by
/// the box's diagonal on every side. A patch vertex outside it, or not finite, has left its
/// hole: fill_holes refuses such a fairing, complete_holes_example_based reverts such a
/// patch to the thin-plate fill.
inline BoundingBox hole_reach(const std::vector<Index>& loop, const std::vector<Vec3>& pos) {
    BoundingBox b;
    for (const Index v : loop) b.extend(pos[v]);
    const Scalar grow = b.diagonal();
    b.min.array() -= grow;
    b.max.array() += grow;
    return b;
}

/// Whether q is finite and inside the reach (hole_reach) of its hole.
inline bool within_reach(const BoundingBox& reach, const Vec3& q) {
    return q.allFinite() && !(q.array() < reach.min.array()).any() && !(q.array() > reach.max.array()).any();
}

/// fill_holes on the working copy (positions `pos`, faces `faces`, the mesh's own):
/// checks and orients the loops, triangulates, refines and fairs them, and gives the
/// patch in new_pos and new_faces (indices past the existing vertices). One non-template
/// body that every mesh type shares (the template checks the parameters, reads and appends).
inline FillResult fill_holes_indexed(const std::vector<Vec3>& pos, std::vector<Face> faces,
                                     const std::vector<std::vector<Index>>& loops, const FillParams& params,
                                     const std::string& fn, std::vector<Vec3>& new_pos, std::vector<Face>& new_faces) {
    const std::size_t nv0 = pos.size(), nf0 = faces.size();
    HalfedgeMesh base;
    try {
        base = HalfedgeMesh::from_faces(pos, faces);
    } catch (const invalid_input& e) {
        throw invalid_input(fn + e.what());
    }
    // Check the loops and orient them: face (l[i+1], l[i], x) must close each edge.
    std::vector<std::vector<Index>> oriented(loops.size());
    std::vector<Index> in_loop(nv0, HalfedgeMesh::invalid);
    for (Index li = 0; li < loops.size(); ++li) {
        const auto& l = loops[li];
        const std::string which = "loop " + std::to_string(li);
        if (l.size() < 3)
            throw invalid_input(fn + which + " has " + std::to_string(l.size()) +
                                " vertices; a boundary loop has at least 3 (take them from find_boundary_loops)");
        for (const Index v : l) {
            if (v >= nv0)
                throw invalid_input(fn + which + " uses vertex " + std::to_string(v) + " but the mesh has " +
                                    std::to_string(nv0) + " vertices");
            if (in_loop[v] != HalfedgeMesh::invalid)
                throw invalid_input(fn + which + " passes vertex " + std::to_string(v) + " already in loop " +
                                    std::to_string(in_loop[v]) + "; give each hole once, as a simple loop");
            in_loop[v] = li;
        }
        bool forward = true, backward = true;
        for (std::size_t i = 0; i < l.size(); ++i) {
            const Index a = l[i], b = l[(i + 1) % l.size()];
            const Index hb = base.find_halfedge(b, a), hf = base.find_halfedge(a, b);
            forward = forward && hb != HalfedgeMesh::invalid && base.is_boundary_halfedge(hb);
            backward = backward && hf != HalfedgeMesh::invalid && base.is_boundary_halfedge(hf);
            if (!forward && !backward)
                throw invalid_input(fn + which + ": vertices " + std::to_string(a) + " and " + std::to_string(b) +
                                    " are not joined by a boundary edge; pass loops from find_boundary_loops");
        }
        oriented[li] = l;
        if (!forward) std::reverse(oriented[li].begin(), oriented[li].end());
    }

    return run_cancellable<FillResult>(params.control, [&](Progress& progress) {
        FillResult res;
        // 1. Triangulate every loop; target edge length from the edges at the loop.
        progress.stage("triangulate", 0.0, 0.3);
        std::vector<Scalar> target;
        std::vector<Index> filled, patch_hole;
        std::vector<Index> ring;
        for (Index li = 0; li < oriented.size(); ++li) {
            const auto& l = oriented[li];
            std::vector<Vec3> p(l.size());
            for (std::size_t i = 0; i < l.size(); ++i) p[i] = pos[l[i]];
            auto forbidden = [&](Index i, Index j) {
                return base.find_halfedge(l[i], l[j]) != HalfedgeMesh::invalid ||
                       base.find_halfedge(l[j], l[i]) != HalfedgeMesh::invalid;
            };
            const auto tris = hole_triangulation(p, forbidden, progress);
            if (tris.empty()) {
                res.unfilled_holes.push_back(li);
                continue;
            }
            for (const auto& t : tris) faces.push_back({l[t[0]], l[t[1]], l[t[2]]});
            Scalar sum = 0;
            std::size_t cnt = 0;
            for (const Index v : l) {
                base.vertex_ring(v, ring);
                for (const Index u : ring) {
                    sum += (pos[u] - pos[v]).norm();
                    ++cnt;
                }
            }
            target.push_back(cnt ? sum / static_cast<Scalar>(cnt) : 0);
            filled.push_back(li);
            patch_hole.insert(patch_hole.end(), tris.size(), filled.size() - 1);
        }
        // 2. Refine: split long patch edges, flip patch edges to Delaunay, until stable.
        progress.stage("refine", 0.3, 0.7);
        HalfedgeMesh hm = HalfedgeMesh::from_faces(pos, faces);
        std::vector<Index> patch(nf0, HalfedgeMesh::invalid);  // per face: its hole (in filled), if a patch face
        patch.insert(patch.end(), patch_hole.begin(), patch_hole.end());
        auto interior_patch_edge = [&](Index h) {
            const Index g = hm.twin(h);
            return g != HalfedgeMesh::invalid && patch[HalfedgeMesh::face(h)] != HalfedgeMesh::invalid &&
                   patch[HalfedgeMesh::face(g)] != HalfedgeMesh::invalid;
        };
        detail::split_and_flip(
            hm, 3 * static_cast<Index>(nf0), interior_patch_edge,
            [&](Index h, Scalar len) { return len > params.split_factor * target[patch[HalfedgeMesh::face(h)]]; },
            [&](Index h) {
                const Index hole = patch[HalfedgeMesh::face(h)];
                hm.split(h, 0.5);
                patch.resize(hm.face_capacity(), hole);
            },
            params.max_rounds, progress);
        // 3. Fair the new vertices.
        progress.stage("fair", 0.7, 0.95);
        // Each hole's reach: the box of its loop grown by the box's diagonal.
        std::vector<BoundingBox> reach(filled.size());
        for (std::size_t k = 0; k < filled.size(); ++k) reach[k] = hole_reach(oriented[filled[k]], pos);
        auto patch_within_reach = [&](const std::vector<Vec3>& y) {
            for (Index f = nf0; f < hm.face_capacity(); ++f) {
                if (hm.is_removed_face(f) || patch[f] == HalfedgeMesh::invalid) continue;
                for (int c = 0; c < 3; ++c) {
                    const Index v = hm.face_vertex(f, c);
                    if (v >= nv0 && !within_reach(reach[patch[f]], y[v])) return false;
                }
            }
            return true;
        };
        std::vector<Vec3> x(hm.vertex_capacity());
        for (Index v = 0; v < x.size(); ++v) x[v] = hm.position(v);
        std::vector<Face> all(hm.face_capacity());
        for (Index f = 0; f < all.size(); ++f) all[f] = {hm.face_vertex(f, 0), hm.face_vertex(f, 1), hm.face_vertex(f, 2)};
        if (params.fair && x.size() > nv0) {
            std::vector<std::uint8_t> free(x.size(), 0);
            std::fill(free.begin() + static_cast<std::ptrdiff_t>(nv0), free.end(), 1);
            const MeshTopology topo(x.size(), all);
            progress.check();
            // The cotangent system is non-symmetric and can be near-singular on needle
            // triangles of the refined patch: a solution that leaves its hole's reach (the
            // loop's box grown by its diagonal on every side) is refused, and the uniform
            // thin-plate system (symmetric positive definite) fairs the patch instead.
            // Only the new vertices move; keep them to restore.
            const std::vector<Vec3> before(x.begin() + static_cast<std::ptrdiff_t>(nv0), x.end());
            if (bilaplacian_fill(x, topo, free) == 0 || !patch_within_reach(x)) {
                std::copy(before.begin(), before.end(), x.begin() + static_cast<std::ptrdiff_t>(nv0));
                biharmonic_fill(x, topo, free, params.fair_delta);
            }
        }
        progress.check();
        new_pos.assign(x.begin() + static_cast<std::ptrdiff_t>(nv0), x.end());
        new_faces.assign(all.begin() + static_cast<std::ptrdiff_t>(nf0), all.end());
        res.filled_holes = filled.size();
        progress.stage("write", 0.95, 1.0);
        res.timings = progress.finish();
        return res;
    });
}

}  // namespace detail

/// @brief Closes the given boundary loops with thin-plate patches (Liepa, "Filling holes
/// in meshes", SGP 2003): triangulation of each loop (minimum area; a loop longer than
/// detail::min_area_whole_loop vertices is first cut along short chords, so the cost
/// stays O(n^2) in the loop length), refinement by edge
/// splits and Delaunay flips until the patch edges are no longer than split_factor times
/// the surrounding edge length, then the bi-Laplace fairing of the new vertices
/// (cotangent weights over vertex areas, L²x = 0 on the new vertices, as CGAL's
/// triangulate_refine_and_fair_hole), which continues the position and slope of the
/// surface around the hole. The existing vertices and faces are not changed; the new
/// ones are appended.
///
/// @tparam M a TopologyMutableMesh (IndexedMesh, CGAL::Surface_mesh, ...). An
///         IndexedMesh with normals receives normals for the new vertices (area-weighted).
/// @param mesh   an oriented 2-manifold, possibly with boundary
/// @param loops  loops to close, each as from find_boundary_loops (either direction):
///               consecutive vertices joined by boundary edges
/// @param params refinement, fairing, cancellation
/// @throws invalid_input (mesh untouched) when the mesh is not an oriented manifold
///         (naming the edge or vertex), a loop is shorter than 3 vertices, uses a vertex
///         out of range, is not a boundary loop (naming the loop and the edge), a vertex is
///         in two loops, or a parameter is out of range.
/// @return Status::ok (a loop that cannot be triangulated without duplicating an
///         existing edge is listed in unfilled_holes, the others are filled);
///         Status::cancelled: the mesh is untouched.
template <TopologyMutableMesh M>
FillResult fill_holes(M& mesh, const std::vector<std::vector<Index>>& loops, const FillParams& params = {}) {
    const std::string fn = "kintsugi::fill_holes: ";
    if (!(params.split_factor >= 1 && params.split_factor <= 4))
        throw invalid_input(fn + "split_factor = " + std::to_string(params.split_factor) +
                            " must lie in [1, 4] (default 4/3)");
    if (params.max_rounds < 1) throw invalid_input(fn + "max_rounds must be >= 1 (default 30)");
    detail::check_fair_delta(params.fair_delta, fn, "fair_delta");
    const std::size_t nv0 = kintsugi::num_vertices(mesh), nf0 = kintsugi::num_faces(mesh);
    std::vector<Face> faces(nf0);
    for (Index f = 0; f < nf0; ++f) faces[f] = face_at(mesh, f);
    std::vector<Vec3> pos(nv0);
    for (Index v = 0; v < nv0; ++v) pos[v] = vertex_position(mesh, v);
    std::vector<Vec3> new_pos;
    std::vector<Face> new_faces;
    FillResult out = detail::fill_holes_indexed(pos, std::move(faces), loops, params, fn, new_pos, new_faces);
    if (out.status == Status::cancelled) return out;
    // 4. Append (the existing vertices and faces are untouched).
    detail::append_patch(mesh, new_pos, new_faces);
    out.new_vertices = new_pos.size();
    out.new_faces = new_faces.size();
    return out;
}

/// One loop: fill_holes(mesh, {loop}, params).
template <TopologyMutableMesh M>
FillResult fill_hole(M& mesh, const std::vector<Index>& loop, const FillParams& params = {}) {
    return fill_holes(mesh, std::vector<std::vector<Index>>{loop}, params);
}

}  // namespace kintsugi
