// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file pu_graphcut_steps.hpp
/// @brief Steps 4–7 of the PU + graph-cut reconstruction (Nagai, Ohtake, Suzuki
/// 2011) on the internal layout: regular triangulation of the supports, the graph
/// of eq. 8–10 and its minimum cut, marching tetrahedra, selective smoothing
/// (the thin-plate fill of step 7 is mesh/fair.hpp).
/// Not templated on the user's types; included by reconstruct/pu_graphcut.hpp.
///
/// Uses CGAL's Regular_triangulation_3 (GPL-3.0-or-later, Triangulation_3 package).

#include <kintsugi/core/control.hpp>
#include <kintsugi/core/disjoint_sets.hpp>
#include <kintsugi/core/memory.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/stages.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/field/edge_root.hpp>
#include <kintsugi/field/point_set_surface.hpp>
#include <kintsugi/graph/st_cut.hpp>
#include <kintsugi/mesh/fair.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/mesh/halfedge_mesh.hpp>
#include <kintsugi/mesh/marching_tetrahedra.hpp>
#include <kintsugi/mesh/refine.hpp>
#include <kintsugi/mesh/taubin.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/metrics/topology_report.hpp>
#include <kintsugi/reconstruct/pu_field.hpp>
#include <kintsugi/spatial/kd_tree.hpp>
#include <kintsugi/spatial/morton.hpp>


#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <optional>
#include <stop_token>
#include <utility>
#include <vector>

namespace kintsugi::detail {

/// The tetrahedral mesh of step 4: the non-hidden supports plus the outer layer.
struct PUTetMesh {
    std::vector<Vec3> vertices;
    /// Positively oriented, in 32 bits (the graph cut takes at most 2^32 - 1 nodes): 48
    /// MB less through the graph cut for the 3M tets of the 2M bench input; widened to
    /// Tet for the marching tetrahedra (widened_tets).
    std::vector<std::array<std::uint32_t, 4>> tets;
    std::vector<std::array<Index, 2>> edges;   ///< unique, a < b
    std::vector<Index> site;                   ///< per vertex: input site index
};

/// Regular triangulation of weighted sites (centre, weight = radius²) with CGAL.
/// Sites with radius 0 are plain points. Reports progress in [p0, p1]. The tets come in
/// CGAL's storage order: canonical_tet_order makes their order depend on the
/// triangulation alone (the pipeline runs it beside the graph cut, which reads only the
/// edges). Defined in pu_triangulation.ipp (kintsugi/core/stages.hpp).
KINTSUGI_STAGE PUTetMesh regular_tet_mesh(const std::vector<Vec3>& centers, const std::vector<Scalar>& radii,
                                          Progress& progress, double p0, double p1);

/// Each tet rotated to its smallest vertex first (orientation kept: even permutations),
/// then the tets sorted: the output mesh then depends only on the triangulation itself.
/// The tets are distinct, so the order is the same whatever the threads.
inline void canonical_tet_order(std::vector<std::array<std::uint32_t, 4>>& tets) {
    parallel_for(0, tets.size(), [&](std::size_t i) {
        auto& t = tets[i];
        const int m = static_cast<int>(std::min_element(t.begin(), t.end()) - t.begin());
        const auto p = even_permutation(m);
        t = {t[static_cast<std::size_t>(p[0])], t[static_cast<std::size_t>(p[1])], t[static_cast<std::size_t>(p[2])],
             t[static_cast<std::size_t>(p[3])]};
    }, 8192);
    sort_maybe_parallel(tets);
}

/// tm.tets as Tet (the marching tetrahedra's type); tm.tets is freed.
inline std::vector<Tet> widened_tets(PUTetMesh& tm) {
    std::vector<Tet> out = huge_vector<Tet>(tm.tets.size());
    parallel_for(0, out.size(), [&](std::size_t i) {
        for (std::size_t k = 0; k < 4; ++k) out[i][k] = tm.tets[i][k];
    }, 8192);
    std::vector<std::array<std::uint32_t, 4>>().swap(tm.tets);
    return out;
}

/// Points on the surface of `box` on a grid with `per_side` intervals per side
/// (corners and edges included once): the outer layer labelled outside.
inline std::vector<Vec3> box_surface_points(const BoundingBox& box, int per_side) {
    std::vector<Vec3> out;
    const Vec3 ext = box.extent();
    for (int k = 0; k <= per_side; ++k)
        for (int j = 0; j <= per_side; ++j)
            for (int i = 0; i <= per_side; ++i) {
                if (i != 0 && i != per_side && j != 0 && j != per_side && k != 0 && k != per_side) continue;
                const Vec3 t(static_cast<Scalar>(i) / per_side, static_cast<Scalar>(j) / per_side,
                             static_cast<Scalar>(k) / per_side);
                out.push_back(box.min + Vec3(t.array() * ext.array()));
            }
    return out;
}

/// Step 5: the graph of eq. 8–10 over the tet mesh and its minimum cut.
/// f_edge: field values for the edge capacities (eq. 10); f_terminal: values for the
/// terminal links (eq. 8, 9); both > 0 inside. forced_out: vertices tied to the sink
/// (the outer layer). Returns labels (1 = inside) and fills the cut value. tm.edges is
/// lent to the graph for the cut (no copy) and given back.
inline std::vector<std::uint8_t> graphcut_labels(PUTetMesh& tm, const std::vector<Scalar>& f_edge,
                                                 const std::vector<Scalar>& f_terminal,
                                                 const std::vector<std::uint8_t>& forced_out, Scalar k,
                                                 Scalar& cut_value, const RunControl& control) {
    const std::size_t nv = tm.vertices.size();
    StCutGraph g;
    g.num_nodes = nv;
    g.capacities = huge_vector<Scalar>(tm.edges.size());
    std::vector<Scalar> len_sum(nv, 0);
    std::vector<std::uint32_t> deg(nv, 0);
    for (std::size_t e = 0; e < tm.edges.size(); ++e) {
        if ((e & 0xFFFF) == 0 && control.stop.stop_requested()) throw cancelled_exception{};
        const auto [a, b] = tm.edges[e];
        const Scalar len = (tm.vertices[a] - tm.vertices[b]).norm();
        len_sum[a] += len;
        len_sum[b] += len;
        ++deg[a];
        ++deg[b];
        g.capacities[e] = len > 0 ? std::abs(f_edge[a] + f_edge[b]) / len : Scalar(0);  // eq. 10
    }
    g.source_capacities.assign(nv, 0);
    g.sink_capacities.assign(nv, 0);
    for (std::size_t v = 0; v < nv; ++v) {
        if (forced_out[v]) {
            g.sink_capacities[v] = std::numeric_limits<Scalar>::infinity();
            continue;
        }
        if (deg[v] == 0) continue;
        const Scalar ave = len_sum[v] / deg[v];
        const Scalar w = ave > 0 ? k * std::abs(f_terminal[v]) / ave : Scalar(0);
        if (f_terminal[v] >= 0) g.source_capacities[v] = w;  // eq. 8
        else g.sink_capacities[v] = w;              // eq. 9
    }
    StCutParams sp;
    sp.control = control;
    sp.control.progress = nullptr;  // the caller reports around this stage
    g.edges = std::move(tm.edges);
    const StCutResult cut = st_min_cut(g, sp);
    tm.edges = std::move(g.edges);
    if (cut.status == Status::cancelled) throw cancelled_exception{};
    cut_value = cut.cut_value;
    std::vector<std::uint8_t> inside(nv);
    for (std::size_t v = 0; v < nv; ++v) inside[v] = cut.labels[v] == StSide::source;
    return inside;
}

/// Relabels unsupported specks: a connected set (over the tet edges) of inside
/// vertices, or of outside vertices not connected to the outer layer (a cavity), is
/// flipped when it has fewer than `fraction` x the vertices of the largest inside set
/// and is not supported: fewer than `min_trusted` of its vertices are flagged in
/// `trusted` (supports trusted to tell inside from outside), or they are fewer than
/// half of its vertices. A small supported region is data (a small second object, a
/// real cavity) and stays. Returns the number of regions relabelled.
inline std::size_t remove_small_regions(const PUTetMesh& tm, const std::vector<std::uint8_t>& forced_out,
                                        std::vector<std::uint8_t>& inside, Scalar fraction,
                                        const std::vector<std::uint8_t>& trusted, std::size_t min_trusted,
                                        const std::stop_token& stop = {}) {
    const std::size_t nv = tm.vertices.size();
    // The regions: union-find over the edges whose ends carry the same label (an
    // adjacency list and a flood fill built 69 MB of lists at 2M points). A region's id
    // follows its smallest vertex, as a flood fill from each vertex in turn numbers them.
    // (32-bit: the pipeline refuses 2^32 - 3 supports or more.)
    DisjointSets<std::uint32_t> sets(nv);
    for (std::size_t e = 0; e < tm.edges.size(); ++e) {
        if ((e & 0xFFFF) == 0 && stop.stop_requested()) throw cancelled_exception{};
        const auto [a, b] = tm.edges[e];
        if (inside[a] == inside[b]) sets.unite(static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b));
    }
    std::vector<std::uint32_t> region(nv);  // set at each vertex in turn (a root's before its set's others)
    std::vector<std::size_t> size, supported;
    std::vector<std::uint8_t> label, touches_outer;
    for (std::size_t v = 0; v < nv; ++v) {
        const std::uint32_t root = sets.find(static_cast<std::uint32_t>(v));
        if (root == v) {  // the region's smallest vertex: a new id
            region[v] = static_cast<std::uint32_t>(size.size());
            size.push_back(0);
            supported.push_back(0);
            label.push_back(inside[v]);
            touches_outer.push_back(0);
        }
        const std::uint32_t id = region[v] = region[root];
        ++size[id];
        supported[id] += trusted[v] != 0;
        if (forced_out[v]) touches_outer[id] = 1;
    }
    std::size_t largest = 0;
    for (std::size_t r = 0; r < size.size(); ++r)
        if (label[r]) largest = std::max(largest, size[r]);
    const auto limit = static_cast<std::size_t>(fraction * static_cast<Scalar>(largest));
    std::vector<std::uint8_t> flip(size.size(), 0);
    std::size_t flipped = 0;
    for (std::size_t r = 0; r < size.size(); ++r)
        if (size[r] < limit && (supported[r] < min_trusted || 2 * supported[r] < size[r]) &&
            (label[r] || !touches_outer[r])) {
            flip[r] = 1;
            ++flipped;
        }
    for (std::size_t v = 0; v < nv; ++v)
        if (flip[region[v]]) inside[v] = !inside[v];
    return flipped;
}

/// Step 6, vertex placement on the field itself: the paper puts the vertex of a mixed
/// edge where f(x) = 0. Marching tetrahedra interpolates f linearly between the two
/// ends; here the zero is found on the PU field along the edge by find_edge_root
/// (field/edge_root.hpp): `samples` + 1 samples from the inside end, the first inside
/// to outside change refined by the Illinois method; NaN counts as 0. Edges on which f
/// never changes sign keep the same-sign placement. The parameter stays in
/// [min_fraction, 1 - min_fraction] (no coincident vertices). `field(x)` (kintsugi's
/// sign, < 0 inside) must be thread-safe; `f` holds the paper's values (> 0 inside) at
/// the tet vertices. Returns the number of vertices whose edge turned out to have a
/// sign change after all.
template <class Field>
std::size_t place_on_zero_set(const Field& field, const std::vector<Vec3>& tet_vertices,
                              const std::vector<Scalar>& f, MarchingTetrahedraResult& mt, Scalar min_fraction,
                              int samples, Progress& progress) {
    const std::size_t n = mt.mesh.vertices.size();
    std::vector<std::uint8_t> found(n, 0);
    const std::size_t block = 4096;
    const EdgeRootParams rp{.samples = samples};
    // The vertices in Morton order of their marching-tetrahedra positions (they come in the
    // order of the tets, whose vertices are numbered by support, in the cover's random
    // order): nearby searches read nearby memory of the field.
    const std::vector<Index> along = morton_order(mt.mesh.vertices);
    for (std::size_t b0 = 0; b0 < n; b0 += 16 * block) {
        progress.update(static_cast<double>(b0) / static_cast<double>(std::max<std::size_t>(n, 1)));
        const std::size_t b1 = std::min(n, b0 + 16 * block);
        parallel_for(b0, b1, [&](std::size_t j) {
            const std::size_t i = along[j];
            // Plain variables, not a structured binding: the nested lambda below
            // captures them, which clang before 16 rejects for bindings.
            const Index a = mt.vertex_edges[i][0], b = mt.vertex_edges[i][1];
            if (a == b) return;
            const Vec3& pa = tet_vertices[a];
            const Vec3 d = tet_vertices[b] - pa;
            const auto root = find_edge_root([&](Scalar t) {
                if (t <= 0) return -f[a];
                if (t >= 1) return -f[b];
                const Scalar v = field(Vec3(pa + t * d));
                // Where no support ball covers the point (past a face at the side of the
                // field's cube), the end values' interpolation: 0 there put a "root" at
                // the edge of the coverage, a dome up to 4 % of the diagonal above the
                // Block's flat top.
                return std::isnan(v) ? -((1 - t) * f[a] + t * f[b]) : v;
            }, rp);
            if (!root) return;
            mt.mesh.vertices[i] = pa + std::clamp(*root, min_fraction, 1 - min_fraction) * d;
            found[i] = 1;
        }, 256);
    }
    std::size_t turned = 0;
    for (std::size_t i = 0; i < n; ++i) {
        if (found[i] && mt.same_sign[i]) {
            mt.same_sign[i] = 0;
            --mt.same_sign_vertices;
            ++turned;
        }
    }
    return turned;
}

/// Marks the points farther than `fraction` x r_i from the centre c_i of every support
/// listed in `ids`. The supports are searched in bands of radii within a factor 2, so a
/// query meets only supports of one size at a time.
inline void mark_unsupported(const std::vector<Vec3>& x, const std::vector<PUSupport>& sup,
                             const std::vector<Index>& ids, Scalar fraction, std::vector<std::uint8_t>& out,
                             const std::stop_token& stop = {}) {
    out.assign(x.size(), 1);
    if (ids.empty() || !(fraction > 0)) return;
    // Band b holds the radii in [2^b, 2^(b+1)).
    std::vector<std::pair<int, Index>> by_band;
    by_band.reserve(ids.size());
    for (const Index i : ids)
        if (sup[i].radius > 0) by_band.emplace_back(static_cast<int>(std::floor(std::log2(sup[i].radius))), i);
    std::sort(by_band.begin(), by_band.end());
    const std::vector<Index> along = morton_order(x);  // nearby queries, nearby memory
    std::size_t b0 = 0;
    while (b0 < by_band.size()) {
        if (stop.stop_requested()) throw cancelled_exception{};
        std::size_t b1 = b0;
        while (b1 < by_band.size() && by_band[b1].first == by_band[b0].first) ++b1;
        std::vector<Vec3> centres;
        std::vector<Scalar> reach;  // fraction x r_i
        for (std::size_t k = b0; k < b1; ++k) {
            centres.push_back(sup[by_band[k].second].center);
            reach.push_back(fraction * sup[by_band[k].second].radius);
        }
        const Scalar rmax = fraction * std::ldexp(Scalar(1), by_band[b0].first + 1);
        const auto tree = KdTree::adopt(std::move(centres));
        parallel_for(0, x.size(), [&](std::size_t j) {
            const std::size_t i = along[j];
            if (!out[i]) return;
            thread_local std::vector<Neighbor> nb;
            tree.radius_search_squared(x[i], rmax * rmax, nb, false);
            for (const auto& q : nb)
                if (q.squared_distance < reach[q.index] * reach[q.index]) {
                    out[i] = 0;
                    return;
                }
        }, 256);
        b0 = b1;
    }
}

/// What refine_to_samples did.
struct RefineStats {
    std::size_t projected = 0;  ///< vertices moved onto the data
    Scalar noise_ratio = 0;     ///< estimated noise (standard deviation) / median spacing of the inliers
    std::size_t neighbors = 0;  ///< neighbours of the MLS fit (k, or more for noisy dense data)
    bool budget_reached = false;  ///< the splits stopped at refine_vertex_budget
};

/// @brief Oriented samples averaged in groups of nearby ones with about the same normal:
/// each sample goes to the column of its normal's dominant signed axis a (the other two
/// coordinates in cells of side h; points and normals of the same surface layer), and a
/// column's samples, sorted along a, are split where two consecutive ones are more than
/// 4 h apart (separate layers). Each group gives its mean position and normalised mean
/// normal.
///
/// Columns rather than cubes: a cube cuts a noisy layer's slab unevenly (how much of the
/// slab above and below the surface falls inside depends on where the cube cuts it), so a
/// cube's mean is biased along the normal; a column along an axis not parallel to the
/// surface holds, for every offset along the normal, the same area of the surface
/// (measured on bunny00 at 2M points, 0.1 % noise: step 8's mean distance 0.0130 % of the
/// diagonal with cubes, 0.0093 % with columns, against 0.0089 % for the fit over the raw
/// samples). The two sides of a thin wall have opposite normals and stay apart.
/// Deterministic: the groups depend on the samples alone (sorted by column, position
/// and index). About 1.3 (h / s)^2 samples per group at spacing s.
/// @param min_count groups with fewer samples are dropped (>= 1)
/// @param subset when given, only these samples (increasing indices into pts) are grouped
/// @return the means and their unit normals, in column order; groups whose normals
///         cancel or that hold fewer than min_count samples are dropped
inline std::pair<std::vector<Vec3>, std::vector<Vec3>> column_means(const std::vector<Vec3>& pts,
                                                                      const std::vector<Vec3>& normals, Scalar h,
                                                                      std::size_t min_count = 1,
                                                                      const std::vector<Index>* subset = nullptr) {
    const std::size_t n = subset ? subset->size() : pts.size();
    auto member = [&](std::size_t j) -> std::size_t { return subset ? (*subset)[j] : j; };
    BoundingBox box;
    for (std::size_t j = 0; j < n; ++j) box.extend(pts[member(j)]);
    // Cell coordinates must fit in 64 bits: otherwise (h below 2^-50 of the extent) every
    // sample is its own group.
    if (!(h > 0) || !(box.extent().maxCoeff() / h < Scalar(1125899906842624))) {
        std::pair<std::vector<Vec3>, std::vector<Vec3>> all{{}, {}};
        if (min_count > 1) return all;
        for (std::size_t j = 0; j < n; ++j) {
            const std::size_t i = member(j);
            if (normals[i].squaredNorm() > 0) {
                all.first.push_back(pts[i]);
                all.second.push_back(normals[i].normalized());
            }
        }
        return all;
    }
    struct Keyed {
        std::array<std::int64_t, 3> column;  // signed axis, then the two cell coordinates
        Scalar along;                        // the coordinate along the axis
        Index i;
        // Field by field (std::array's comparisons are slower), so that the sort of the 2M
        // inliers of the bench input takes less of step 8's data side.
        bool operator<(const Keyed& o) const {
            if (column[0] != o.column[0]) return column[0] < o.column[0];
            if (column[1] != o.column[1]) return column[1] < o.column[1];
            if (column[2] != o.column[2]) return column[2] < o.column[2];
            return along != o.along ? along < o.along : i < o.i;
        }
    };
    std::vector<Keyed> keyed(n);
    parallel_for(0, n, [&](std::size_t j) {
        const std::size_t i = member(j);
        const Vec3 g = ((pts[i] - box.min) / h).array().floor();
        const Vec3& nr = normals[i];
        int axis = 0;
        nr.cwiseAbs().maxCoeff(&axis);
        const int u = (axis + 1) % 3, v = (axis + 2) % 3;
        keyed[j] = {{2 * axis + (nr[axis] < 0 ? 1 : 0), static_cast<std::int64_t>(g[u]), static_cast<std::int64_t>(g[v])},
                    pts[i][axis],
                    static_cast<Index>(i)};
    }, 4096);
    sort_maybe_parallel(keyed);  // (column, position, index): total and unique
    const Scalar gap = 4 * h;
    std::pair<std::vector<Vec3>, std::vector<Vec3>> out;
    for (std::size_t a = 0; a < keyed.size();) {
        std::size_t b = a;
        Vec3 ps = Vec3::Zero(), ns = Vec3::Zero();
        for (; b < keyed.size() && keyed[b].column == keyed[a].column &&
               (b == a || keyed[b].along - keyed[b - 1].along <= gap);
             ++b) {
            ps += pts[keyed[b].i];
            ns += normals[keyed[b].i].normalized();
        }
        if (ns.squaredNorm() > 0 && b - a >= min_count) {
            out.first.push_back(ps / static_cast<Scalar>(b - a));
            out.second.push_back(ns.normalized());
        }
        a = b;
    }
    return out;
}

/// @brief Step 8 (ours): the cut's surface, whose vertices lie on the edges of the
/// support triangulation (few and long where the surface is smooth), refined to the
/// samples' spacing and moved onto the data. The labelling keeps the topology: edges
/// are only split and flipped (detail::split_and_flip), never collapsed.
///
/// 1. Inliers: the input points within `band` of the zero set of `field` (|f| / |∇f|)
///    whose normal agrees with ∇f (the outliers' random positions and normals rarely
///    pass both).
/// 2. Spacing s(q) of each inlier: the radius of its 8 nearest inliers x sqrt(π/8) (the
///    mean spacing of 8 points on a disk of that radius); s at a mesh vertex is that of
///    its nearest inlier, interpolated along split edges. The noise sigma, from the
///    inliers' offsets to their neighbours' centroid: where a fit must span more than k
///    samples, (20 sigma / s)^2 (data denser than their noise), the inliers are replaced
///    by the means of groups of that / k of them (column_means) and s is their spacing.
/// 3. Every edge longer than 4/3 x spacing x s is split at its midpoint, then edges are
///    flipped to Delaunay, until no edge is too long.
/// 4. Each vertex first takes Newton steps onto the zero set of `field` (at most 4 band
///    in all: same-sign and hole-fill vertices can lie off it). Where an inlier lies
///    within 2 s (and, where step 7 found no trusted support within fill_fraction x
///    r_i, the data surround it rather than lie on one side: a hole's rim), it is then
///    projected onto the MLS surface (APSS, kintsugi::PointSetSurface, k neighbours)
///    of the inliers. A projection that moves it by more than `band` or turns its
///    normal (a fit that failed: across a sharp crease the sphere snaps onto the crease
///    line) is refused, and the vertex keeps its converged Newton position (exact on
///    flat parts). Where the field is undefined (outside its cube) the projection
///    starts from the vertex and may move it by 4 band.
/// 5. The other new vertices (hole fills) take bi-Laplacian positions (bilaplacian_fill)
///    between the projected ones and the coarse ones left where step 7 put them.
/// 6. A triangle made degenerate has its corners put back (see the end).
/// Steps 1-2 need no mesh: refine_data chooses the fit's samples while the triangulation
/// runs, refine_fit builds their MLS surface and spacing while the graph cut runs; steps
/// 3-6 are refine_to_samples.
///
/// The data side of step 8: the inliers' MLS surface, their spacing and the noise.
struct RefineData {
    std::optional<PointSetSurface> mls;  ///< the fit's samples and surface; empty: too few inliers
    std::vector<Scalar> spacing;         ///< s of each of mls's samples (its tree's order)
    RefineStats stats;                   ///< noise_ratio and neighbors (projected 0)
};

/// Step 8's spacing at a sample: the radius of its refine_ring nearest neighbours (itself
/// included: refine_ring + 1) x sqrt(π / refine_ring), the mean spacing of refine_ring
/// points on a disk of that radius.
inline constexpr std::size_t refine_ring = 8;
inline Scalar refine_spacing_of(Scalar ring_radius) {
    return ring_radius * std::sqrt(Scalar(3.14159265358979323846) / static_cast<Scalar>(refine_ring));
}

/// What refine_data chose for the fit: its samples (the inliers, or the means of groups
/// of them), before refine_fit builds their MLS surface.
struct RefineSamples {
    std::vector<Vec3> points, normals;  ///< empty: too few inliers
    std::size_t k = 0;                  ///< neighbours of each fit
    std::vector<Scalar> spacing;        ///< s of each sample when the estimates read all of them, else empty
    RefineStats stats;                  ///< noise_ratio and neighbors (projected 0)
};

/// @brief The sites of step 4's triangulation once the far ones are thinned
/// (PUGraphcutParams::far_site_band): every trusted support, every untrusted one whose
/// terminal value lies within the band, the outer layer, and of the untrusted supports
/// beyond the band the first (lowest index: the cover's seeded order) in each cell of a
/// grid of half the band's width.
/// @param sites        the supports' centres (the first ns), then the outer layer
/// @param value        the terminal value of each untrusted site (read for those only)
/// @param trusted_site per support, whether it is trusted
/// @param band_factor  the band's half-width over the trusted supports' median radius;
///                     0 (or no trusted support) keeps every site
/// @param low          a corner below every site: the grid's origin
/// @param[out] thinned the sites left out
/// @return the kept sites' indices, increasing
inline std::vector<Index> pu_thinned_sites(const std::vector<Vec3>& sites, std::size_t ns,
                                           const std::vector<Scalar>& value,
                                           const std::vector<std::uint8_t>& trusted_site, Scalar band_factor,
                                           const std::vector<PUSupport>& sup, const Vec3& low, std::size_t& thinned) {
    thinned = 0;
    std::vector<Index> kept;
    std::vector<Scalar> radius;
    for (std::size_t i = 0; i < ns; ++i)
        if (trusted_site[i]) radius.push_back(sup[i].radius);
    Scalar band = 0;
    if (band_factor > 0 && !radius.empty()) {
        const auto mid = radius.begin() + static_cast<std::ptrdiff_t>(radius.size() / 2);
        std::nth_element(radius.begin(), mid, radius.end());
        band = band_factor * *mid;
    }
    const Scalar cell = band / 2;
    if (!(cell > 0) || !std::isfinite(cell)) {
        kept.resize(sites.size());
        std::iota(kept.begin(), kept.end(), Index{0});
        return kept;
    }
    // 21 bits per axis: a box more than 2^21 cells wide shares its last cells (only the
    // thinning gets coarser there).
    constexpr Scalar top = (1 << 21) - 1;
    std::vector<std::pair<std::uint64_t, Index>> far;
    kept.reserve(sites.size());
    for (std::size_t i = 0; i < sites.size(); ++i) {
        if (i < ns && !trusted_site[i] && std::abs(value[i]) > band) {
            const Vec3 q = ((sites[i] - low) / cell).cwiseMax(Vec3::Zero()).cwiseMin(Vec3::Constant(top));
            const std::uint64_t key = (static_cast<std::uint64_t>(q.x()) << 42) |
                                      (static_cast<std::uint64_t>(q.y()) << 21) | static_cast<std::uint64_t>(q.z());
            far.push_back({key, static_cast<Index>(i)});
        } else {
            kept.push_back(static_cast<Index>(i));
        }
    }
    std::sort(far.begin(), far.end());
    for (std::size_t j = 0; j < far.size(); ++j)
        if (j == 0 || far[j].first != far[j - 1].first)
            kept.push_back(far[j].second);
        else
            ++thinned;
    std::sort(kept.begin(), kept.end());
    return kept;
}

/// @brief Steps 1-2 of step 8 (see refine_to_samples), up to the fit's samples. Polls
/// `stop` only, reports no progress: it runs beside the triangulation, off the calling
/// thread.
/// @param outward_normals the input normals, pointing outward
/// @return points empty when fewer than max(2 k, 16) points are inliers
inline RefineSamples refine_data(const PUField& field, const std::vector<Vec3>& pts,
                                 const std::vector<Vec3>& outward_normals, std::size_t k, Scalar band,
                                 const std::stop_token& stop) {
    RefineSamples data;
    RefineStats& stats = data.stats;
    auto check = [&] {
        if (stop.stop_requested()) throw cancelled_exception{};
    };
    // 1. Inliers.
    // In Morton order (the input's own order can be anything): nearby evaluations read
    // nearby memory of the field.
    std::vector<std::uint8_t> near(pts.size(), 0);
    std::vector<Index> along = morton_order(pts);
    parallel_for(0, pts.size(), [&](std::size_t j) {
        const std::size_t i = along[j];
        Vec3 g;
        const Scalar v = field.value_and_gradient(pts[i], g);
        const Scalar gn = g.norm();
        near[i] = std::isfinite(v) && gn > 0 && std::abs(v) <= band * gn && g.dot(outward_normals[i]) > 0;
    }, 1024);
    // The inliers by index, and their positions in a kd-tree that holds them (no other
    // copy of them: this runs beside the triangulation, whose memory is the stage's
    // largest; the grouping below reads the input through the indices).
    // A point given several times (merged scans, a repeated export) counts once: the spacing
    // below is the radius of its 8 nearest inliers, which copies bring to 0, and the
    // refinement's edges with it (the kitten with each point 10 times grew past 23 GB).
    // Equal positions are neighbours along the Morton order (ties by index): the first
    // inlier of each run is kept. Inputs without exact duplicates are unchanged.
    for (std::size_t j = 0; j < along.size();) {
        std::size_t e = j + 1;
        while (e < along.size() && pts[along[e]] == pts[along[j]]) ++e;
        bool kept = false;
        for (std::size_t t = j; t < e; ++t)
            if (near[along[t]]) {
                if (kept) near[along[t]] = 0;
                kept = true;
            }
        j = e;
    }
    std::vector<Index> sel;
    sel.reserve(static_cast<std::size_t>(std::count(near.begin(), near.end(), std::uint8_t{1})));
    for (std::size_t i = 0; i < pts.size(); ++i)
        if (near[i]) sel.push_back(static_cast<Index>(i));
    if (sel.size() < std::max<std::size_t>(2 * k, 16)) return data;
    auto selected = [&](const std::vector<Vec3>& all) {
        std::vector<Vec3> out(sel.size());
        for (std::size_t j = 0; j < sel.size(); ++j) out[j] = all[sel[j]];
        return out;
    };
    // The tree holds them in Morton order, and the estimates below query it in Morton
    // order: in the input's order (any order) each query read scattered memory (2M
    // bench input, random order: 262K queries 1.21 s, the tree 0.55 s). The estimates
    // are those of a tree in the input's order, except where two inliers lie at the same
    // distance from a sample (duplicates): a tie is then broken by the Morton rank.
    // mo[t]: the t-th inlier (index into sel) along the input's Morton order, ties by
    // index, which is the inliers' own Morton order in the same box (a second sort of
    // 2M codes took 0.15 s).
    std::vector<Index> mo;
    {
        std::vector<Index> pos(pts.size());  // the position in sel of each inlier
        for (std::size_t j = 0; j < sel.size(); ++j) pos[sel[j]] = static_cast<Index>(j);
        mo.reserve(sel.size());
        for (const Index i : along)
            if (near[i]) mo.push_back(pos[i]);
    }
    std::vector<Index>().swap(along);
    std::vector<std::uint8_t>().swap(near);
    std::optional<KdTree> inliers;
    {
        std::vector<Vec3> tp(sel.size());
        for (std::size_t t = 0; t < tp.size(); ++t) tp[t] = pts[sel[mo[t]]];
        inliers.emplace(KdTree::adopt(std::move(tp)));
    }
    check();
    // 2. Spacing, and the noise: each inlier's offset along its normal from the centroid
    // of itself and its 8 nearest inliers.
    // The noise and the median spacing from every stride-th inlier, at most 2^18 of them
    // (a median's error is then below 0.3 %; all of them up to 262,144 inliers).
    const std::size_t stride = (sel.size() + 262143) / 262144;
    const std::size_t n_est = (sel.size() + stride - 1) / stride;
    std::vector<Scalar> s_est(n_est), off(n_est);
    // The sampled inliers (every stride-th) in the inliers' Morton order.
    std::vector<Index> along_est;
    along_est.reserve(n_est);
    for (const Index i : mo)
        if (i % stride == 0) along_est.push_back(i / stride);
    std::vector<Index>().swap(mo);
    parallel_for(0, n_est, [&](std::size_t m) {
        thread_local std::vector<Neighbor> nb;
        const std::size_t j = along_est[m];
        const std::size_t i = j * stride;
        const Vec3& p = pts[sel[i]];
        inliers->knn(p, refine_ring + 1, nb);
        s_est[j] = refine_spacing_of(std::sqrt(nb.back().squared_distance));
        Vec3 c = Vec3::Zero();
        for (const auto& q : nb) c += inliers->point(q.index);
        off[j] = std::abs(outward_normals[sel[i]].normalized().dot(p - c / static_cast<Scalar>(nb.size())));
    }, 1024);
    // The fit's samples: the inliers, or the means of groups of them (below).
    std::size_t fit_k = k;
    stats.neighbors = k;
    bool grouped = false;
    {
        // Data denser than their noise: a fit over k neighbours keeps about sigma / sqrt(k)
        // of it whatever the density, so it must span about k2 = (20 sigma / s)^2 samples
        // (s the median spacing; at most 16 k) for sigma / sqrt(k2) <= s / 20. sigma,
        // Gaussian: the offsets' median / 0.6745 x 3 / sqrt(8) (the centroid holds the
        // point). Rather than fit over k2 samples at every vertex of a mesh refined to s,
        // the inliers are averaged in groups of about k2 / k (column_means, columns of side
        // s sqrt(k2 / k / 1.3)), the fit takes k of the means, and the mesh is refined to
        // the means' spacing. Measured (docs/methods/pu_graphcut.md): bunny00 at 2M points,
        // 0.1 % noise, sigma = 0.47 s, k2 = 89: mean distance 0.0081 % of the diagonal,
        // Hausdorff 0.63 % (fitting 89 raw samples: 0.0089 %, 1.03 %; the surface of steps
        // 6-7: 0.0134 %, 0.82 %), the stage 4.7 s instead of 31-47 s, 0.28M vertices
        // instead of 1.15M. At 100K points sigma = 0.2 s and clean data sigma < 0.03 s keep
        // the inliers as they are.
        const Scalar sigma = upper_median(std::move(off)) / Scalar(0.6745) * Scalar(1.0606601717798212);
        const Scalar s_med = upper_median(s_est);
        if (s_med > 0) {
            stats.noise_ratio = sigma / s_med;
            const Scalar want = std::ceil(Scalar(400) * (sigma / s_med) * (sigma / s_med));
            const std::size_t k2 = std::min<std::size_t>(
                sel.size(), static_cast<std::size_t>(std::min(want, static_cast<Scalar>(16 * k))));
            if (k2 > k) {
                stats.neighbors = k2;
                const Scalar h = s_med * std::sqrt(static_cast<Scalar>(k2) / static_cast<Scalar>(k) / Scalar(1.3));
                // A group of fewer than half the expected samples is dropped: an isolated
                // outlier that passed the inlier test (near the zero set, its random normal
                // agreeing) is a group of one, and would weigh in the fit as much as a mean
                // of k2 / k samples (2M bunny00: mean 0.0093 -> 0.0081 %, Hausdorff 0.84 ->
                // 0.63 %, its largest errors in the holes and off them gone).
                const auto min_count = static_cast<std::size_t>(
                    std::max<Scalar>(1, std::round(Scalar(0.5) * static_cast<Scalar>(k2) / static_cast<Scalar>(k))));
                inliers.reset();
                auto [ap, an] = column_means(pts, outward_normals, h, min_count, &sel);
                if (ap.size() >= std::max<std::size_t>(2 * k, 16)) {
                    grouped = true;
                    data.points = std::move(ap);
                    data.normals = std::move(an);
                } else {
                    // Too few groups to fit (a small, noisy part): k2 raw samples per fit.
                    fit_k = k2;
                }
            }
        }
    }
    if (!grouped) {
        inliers.reset();
        data.points = selected(pts);
        data.normals = selected(outward_normals);
        // The spacing of every sample: the estimate's own when it read all of them.
        if (stride == 1) data.spacing = std::move(s_est);
    }
    data.k = fit_k;
    return data;
}

/// @brief The end of step 8's data side: the MLS surface of the samples refine_data chose,
/// and their spacing (refine_spacing_of). Polls `stop` only, reports no progress: it runs
/// beside the graph cut (Boykov-Kolmogorov is sequential), off the calling thread.
/// @return mls empty when `samples` holds no point
inline RefineData refine_fit(RefineSamples samples, const std::stop_token& stop) {
    RefineData data;
    data.stats = samples.stats;
    if (samples.points.empty()) return data;
    // Tolerance 1e-3 x h: the vertices start within a chord's error of the surface; the
    // same distances as 1e-4 to 1e-4 % of the diagonal at 80 % of the time (bunny00).
    data.mls.emplace(with_normals(samples.points, samples.normals),
                     PointSetSurfaceParams{.k = samples.k, .tolerance = 1e-3});
    std::vector<Vec3>().swap(samples.points);
    std::vector<Vec3>().swap(samples.normals);
    if (stop.stop_requested()) throw cancelled_exception{};
    std::vector<Scalar>& sq = data.spacing;
    if (!samples.spacing.empty()) {
        sq = std::move(samples.spacing);
    } else {
        const KdTree& tree = data.mls->tree();
        sq.resize(tree.size());
        parallel_for(0, tree.size(), [&](std::size_t i) {
            thread_local std::vector<Neighbor> nb;
            tree.knn(tree.point(i), refine_ring + 1, nb);
            sq[i] = refine_spacing_of(std::sqrt(nb.back().squared_distance));
        }, 1024);
    }
    return data;
}

/// Most vertices step 8's splits may bring the mesh to: its own plus this many per sample of
/// the fit at refine_spacing 1.5, times (1.5 / refine_spacing)² at finer spacings (a surface
/// refined to 1.5 times the samples' spacing has about as many vertices as samples: the
/// kitten's 5,210 points give 5,633). A bound where the spacing reads far below the rest
/// (near-duplicate points, a dense cluster beside sparse data), so that the doubling rounds
/// cannot exhaust memory; RefineStats::budget_reached says it stopped there.
inline constexpr Scalar refine_vertex_budget = 4;

/// @brief Steps 3-6 of step 8 (see above), on the data refine_data made.
/// @return the vertices moved onto the data (MLS surface or field), the noise estimate and
///         the fit's neighbours; all 0, the mesh unchanged, when data has no surface (too
///         few inliers) or the mesh no face; projected 0, the mesh unchanged, when flat
///         faces could not be mended
inline RefineStats refine_to_samples(IndexedMesh& mesh, const RefineData& data, const PUField& field,
                                      Scalar spacing, Scalar band, const std::vector<PUSupport>& sup,
                                      const std::vector<Index>& trusted, Scalar fill_fraction, Progress& progress) {
    if (!data.mls || mesh.faces.empty()) return {};
    RefineStats stats = data.stats;
    std::size_t& projected = stats.projected;
    const std::optional<PointSetSurface>& mls = data.mls;
    const KdTree& tree = mls->tree();
    const std::vector<Scalar>& sq = data.spacing;
    progress.update(0.1);
    // Step 4's landing of a vertex: what depends on its position alone (not on the mesh).
    // Newton steps onto the zero set of the field first (the mesh of steps 6-7 can lie
    // off it: same-sign and hole-fill vertices), at most `reach` in all; then the MLS
    // projection, and the nearest sample to where the vertex would land.
    struct Landing {
        Vec3 y = Vec3::Zero();  ///< after the Newton steps
        SurfaceProjection p;    ///< the MLS projection of y
        Neighbor nearest;       ///< the sample nearest to `at()`
        bool newton = false;    ///< the Newton steps converged
        bool undefined = false; ///< the field is undefined at the vertex (outside its cube)
        bool finite = false;    ///< the projection is finite (else the vertex stays)
        // Where the field is undefined (outside its cube, where the coarse surface can
        // bulge past a flat face at the side of the box), the MLS projection starts from
        // the vertex itself and may move it up to `reach`; the data tests are made where
        // it lands.
        [[nodiscard]] const Vec3& at() const { return undefined ? p.point : y; }
    };
    const Scalar reach = 4 * band;
    auto land = [&](const Vec3& x0) {
        Landing l;
        l.y = x0;
        for (int it = 0; it < 4; ++it) {
            Vec3 g;
            const Scalar f = field.value_and_gradient(l.y, g);
            const Scalar g2 = g.squaredNorm();
            if (!std::isfinite(f) || !(g2 > 0)) {
                l.undefined = it == 0;
                break;
            }
            const Vec3 next = l.y - f / g2 * g;
            if ((next - x0).squaredNorm() > reach * reach) break;
            l.newton = (next - l.y).squaredNorm() <= Scalar(1e-6) * band * band;
            l.y = next;
            if (l.newton) break;
        }
        l.p = mls->project_unchecked(l.y);
        l.finite = l.p.point.allFinite();
        if (!l.finite) return l;
        thread_local std::vector<Neighbor> nb;
        tree.knn(l.at(), 1, nb);
        l.nearest = nb[0];
        return l;
    };

    // 3. Split and flip, on the calling thread, while the other threads land the coarse
    // vertices (splits add vertices, flips change only the connectivity, so the coarse
    // ones keep their positions; 2M bench input: 104K of the 282K vertices, the split and
    // flips 0.44 s on one core).
    const std::size_t nv0 = mesh.vertices.size();
    std::vector<Landing> coarse(nv0);
    HalfedgeMesh hm;
    std::size_t ch = 0;
    const std::stop_token stop = progress.stop();
    parallel_invoke(
        [&] {
            const std::vector<Index> along = morton_order(mesh.vertices);  // nearby vertices, nearby memory
            for (std::size_t b = 0; b < nv0; b += 4096) {
                if (stop.stop_requested()) throw cancelled_exception{};
                parallel_for(b, std::min(nv0, b + 4096), [&](std::size_t j) {
                    const Index v = along[j];
                    coarse[v] = land(mesh.vertices[v]);
                }, 64);
            }
        },
        [&] {
            hm = HalfedgeMesh::from_faces(mesh.vertices, mesh.faces);
            ch = hm.add_scalar("spacing", 0);
            {
                std::vector<Scalar> s0(hm.vertex_capacity());
                parallel_for(0, s0.size(), [&](std::size_t v) {
                    thread_local std::vector<Neighbor> nb;
                    tree.knn(hm.position(static_cast<Index>(v)), 1, nb);
                    s0[v] = sq[nb[0].index];
                }, 1024);
                for (Index v = 0; v < s0.size(); ++v) hm.scalar(ch, v) = s0[v];
            }
            const Scalar limit = Scalar(4) / 3 * spacing;
            const Scalar per_sample = refine_vertex_budget * std::max<Scalar>(1, (Scalar(1.5) / spacing) * (Scalar(1.5) / spacing));
            const std::size_t budget = nv0 + static_cast<std::size_t>(per_sample * static_cast<Scalar>(tree.size()));
            (void)split_and_flip(
                hm, 0, [](Index) { return true; },
                [&](Index h, Scalar len) {
                    if (hm.num_vertices() >= budget) {
                        stats.budget_reached = true;
                        return false;
                    }
                    return len > limit * std::min(hm.scalar(ch, hm.source(h)), hm.scalar(ch, hm.target(h)));
                },
                [&](Index h) { hm.split(h, 0.5); }, 30, progress, 0.1, 0.5);
        });
    // 4. Projection.
    IndexedMesh work;  // the refined mesh; its positions x move
    std::vector<Vec3>& x = work.vertices;
    std::vector<Face>& faces = work.faces;
    x.resize(hm.vertex_capacity());
    for (Index v = 0; v < x.size(); ++v) x[v] = hm.position(v);
    faces.reserve(hm.num_faces());
    for (Index f = 0; f < hm.face_capacity(); ++f)
        if (!hm.is_removed_face(f)) faces.push_back({hm.face_vertex(f, 0), hm.face_vertex(f, 1), hm.face_vertex(f, 2)});
    std::vector<std::uint8_t> moved(x.size(), 0), hole(x.size(), 0);
    if (fill_fraction > 0) mark_unsupported(x, sup, trusted, fill_fraction, hole, stop);
    const std::vector<Vec3> nx = vertex_normals(work);
    const std::size_t blocks = std::clamp<std::size_t>(x.size() / 4096, 1, 40);
    const std::vector<Index> along = morton_order(x);  // nearby vertices, nearby memory
    for (std::size_t b = 0; b < blocks; ++b) {
        progress.update(0.5 + 0.5 * static_cast<double>(b) / static_cast<double>(blocks));
        parallel_for(x.size() * b / blocks, x.size() * (b + 1) / blocks, [&](std::size_t j) {
            const std::size_t v = along[j];
            const Landing l = v < nv0 && x[v] == mesh.vertices[v] ? coarse[v] : land(x[v]);
            if (!l.finite) return;
            const Vec3& at = l.at();
            const Scalar s = sq[l.nearest.index];
            // No data near: a hole's fill. Where step 7 found no support either, the data
            // must also surround the point (not only lie on one side: a hole's rim).
            if (l.nearest.squared_distance > 4 * s * s) return;
            if (hole[v] && l.nearest.squared_distance > s * s / 4) {
                thread_local std::vector<Neighbor> ring;
                tree.knn(at, 16, ring);
                Vec3 c = Vec3::Zero();
                for (const auto& q : ring) c += tree.point(q.index);
                const Vec3 off = c / static_cast<Scalar>(ring.size()) - at;
                const Scalar tangential = (off - off.dot(nx[v]) * nx[v]).norm();
                if (!(tangential <= Scalar(0.25) * std::sqrt(ring.back().squared_distance))) return;
            }
            const Scalar limit = l.undefined ? reach : band;
            if ((l.p.point - l.y).squaredNorm() <= limit * limit && l.p.normal.dot(nx[v]) > 0) {
                x[v] = l.p.point;
                moved[v] = 1;
            } else if (l.newton && !hole[v]) {
                // A fit that failed (across a sharp crease the sphere snaps onto the
                // crease line): the zero set of the field, exact on flat parts.
                x[v] = l.y;
                moved[v] = 1;
            }
        }, 64);
        progress.check();
    }
    std::vector<Landing>().swap(coarse);
    // A move that leaves a vertex far off the surface of its neighbours failed (bunny00 at
    // 10M points: one vertex at a hole's rim 1.04 % of the diagonal from the truth, its
    // neighbours 0.11-0.17 %): more than twice their mean distance from their centroid,
    // along the normal (a 90-degree crease puts a vertex about half that off). It takes
    // that centroid (10M: Hausdorff 1.04 -> 0.67 %; 2M and the held-out eight at 1M within
    // 0.0001 % in the mean). Sent back to its refined position and the thin-plate fill
    // below instead, the eight had four vertices 1.5-12 % off the truth (not diagnosed).
    const MeshTopology topo(x.size(), faces);
    // The vertices selected by `which` that `off(v, centroid, radius)` finds off their ring
    // (radius: the neighbours' mean distance from their centroid) take the ring's centroid;
    // found first, then moved, so the result does not depend on the threads.
    auto to_ring_centroid = [&](const std::vector<std::uint8_t>& which, auto&& off) {
        std::vector<Vec3> to(x.size());
        std::vector<std::uint8_t> away(x.size(), 0);
        parallel_for(0, x.size(), [&](std::size_t v) {
            if (!which[v]) return;
            const auto ring = topo.vertex_neighbors(static_cast<Index>(v));
            if (ring.size() < 3) return;
            Vec3 c = Vec3::Zero();
            for (const Index w : ring) c += x[w];
            c /= static_cast<Scalar>(ring.size());
            Scalar radius = 0;
            for (const Index w : ring) radius += (x[w] - c).norm();
            radius /= static_cast<Scalar>(ring.size());
            away[v] = off(v, c, radius);
            to[v] = c;
        }, 1024);
        for (Index v = 0; v < x.size(); ++v)
            if (away[v]) x[v] = to[v];
    };
    to_ring_centroid(moved, [&](std::size_t v, const Vec3& c, Scalar radius) {
        return std::abs(nx[v].dot(x[v] - c)) > 2 * radius;
    });
    // The vertices left where they were lie on the chords of the coarse surface (new
    // ones) or off the data (coarse ones): they take the thin-plate positions between
    // the projected vertices and the coarse vertices of step 7's fill, which stay (re-
    // fairing those too raised the largest error in bunny00's holes, seed 1: 0.74 ->
    // 0.95 %).
    std::vector<std::uint8_t> rest(x.size(), 0);
    for (Index v = 0; v < x.size(); ++v) {
        rest[v] = !moved[v] && !hm.is_removed_vertex(v) && (v >= nv0 || !hole[v]);
        projected += moved[v];
    }
    progress.check();
    if (projected > 0 && projected < x.size()) {
        (void)bilaplacian_fill(x, topo, rest);
        // A filled vertex more than 8 times its neighbours' mean distance from their
        // centroid folds its faces over theirs: it takes that centroid. (Held-out fertility,
        // 1M points with 10 % outliers and the far sites thinned: one vertex the projection
        // left was put 143 times that distance away by the fill, 1.40 % of the diagonal off
        // the truth; no other vertex of that mesh lies above 8 times, 3-5 above 5.)
        to_ring_centroid(rest, [&](std::size_t v, const Vec3& c, Scalar radius) {
            return (x[v] - c).squaredNorm() > 64 * radius * radius;
        });
    }
    // The output has no degenerate triangle (pu_graphcut's guarantee): the corners of a
    // face the moves made collinear (zero_area_triangle, topology_report's test) go back to
    // their refined positions.
    for (int round = 0; round < 4; ++round) {
        std::size_t bad = 0;
        for (const Face& t : faces)
            if (zero_area_triangle(x[t[0]], x[t[1]], x[t[2]])) {
                ++bad;
                for (const Index v : t) x[v] = hm.position(v);
            }
        if (bad == 0) break;
    }
    for (Index v = 0; v < x.size(); ++v) hm.position(v) = x[v];
    // Faces flat already where the refinement put them (2-44 of 2.3M faces at 2M points:
    // two corners at one position, the midpoints of edges from two coincident vertices
    // of the surface of steps 6-7): the zero-length edge is collapsed, a corner on the
    // line of the other two loses the longest edge to a flip (the standard repairs of a
    // needle and a cap). Where neither applies (the collapse would break the manifold,
    // the flip would make another flat face), the corner opposite the longest edge moves
    // to the mean of its neighbours (one umbrella step, which lifts it off the line);
    // should any flat face remain after that, the surface of steps 6-7 is kept. (Before
    // the umbrella step, one such face of the 2M bench input with thinned far sites
    // discarded the whole refinement: mean distance 0.0081 -> 0.0134 %.)
    std::vector<Index> around;
    auto umbrella = [&](Index v) {
        if (hm.is_boundary_vertex(v)) return;  // left alone
        hm.vertex_ring(v, around);
        if (around.empty()) return;
        Vec3 sum = Vec3::Zero();
        for (const Index w : around) sum += hm.position(w);
        hm.position(v) = sum / static_cast<Scalar>(around.size());
    };
    for (int round = 0;; ++round) {
        std::size_t bad = 0;
        for (Index f = 0; f < hm.face_capacity(); ++f) {
            if (hm.is_removed_face(f)) continue;
            const Index h0 = 3 * f;
            if (!zero_area_triangle(hm.position(hm.source(h0)), hm.position(hm.source(h0 + 1)),
                                    hm.position(hm.source(h0 + 2))))
                continue;
            ++bad;
            Index longest = h0, shortest = h0;
            Scalar most = -1, least = std::numeric_limits<Scalar>::infinity();
            for (Index h = h0; h < h0 + 3; ++h) {
                const Scalar len = (hm.position(hm.target(h)) - hm.position(hm.source(h))).squaredNorm();
                if (len > most) {
                    most = len;
                    longest = h;
                }
                if (len < least) {
                    least = len;
                    shortest = h;
                }
            }
            if (least == 0 && hm.can_collapse(shortest)) {
                (void)hm.collapse(shortest, 0);
            } else if (least > 0 && !flip_degenerates(hm, longest) && hm.flip(longest)) {
            } else if (round > 0) {
                umbrella(hm.opposite(longest));
            }
        }
        if (bad == 0) break;
        if (round == 5) return {0, stats.noise_ratio, stats.neighbors, stats.budget_reached};
    }
    hm.to_mesh(mesh);
    return stats;
}

}  // namespace kintsugi::detail

#ifndef KINTSUGI_SEPARATE_STAGES
#include <kintsugi/reconstruct/detail/pu_triangulation.ipp>
#endif
