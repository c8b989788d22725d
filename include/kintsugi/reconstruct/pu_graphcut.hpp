// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file pu_graphcut.hpp
/// @brief Outlier-robust surface reconstruction from oriented points: a
/// partition-of-unity implicit field labelled globally by a graph cut
/// (Nagai, Ohtake, Suzuki 2011).
///
/// @code
/// #include <kintsugi/reconstruct/pu_graphcut.hpp>
/// auto res = kintsugi::reconstruct_pu_graphcut(kintsugi::with_normals(pts, nrm), {.max_level = 8, .k = 10});
/// if (res.status == kintsugi::Status::ok) write(res.mesh);   // closed, outward, manifold
/// @endcode
///
/// Licence note: includes CGAL's Regular_triangulation_3 (Triangulation_3 package,
/// GPL-3.0-or-later).

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/stages.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/handles.hpp>
#include <kintsugi/mesh/marching_tetrahedra.hpp>
#include <kintsugi/mesh/taubin.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/reconstruct/detail/pu_graphcut_steps.hpp>
#include <kintsugi/reconstruct/detail/pu_parts.hpp>
#include <kintsugi/reconstruct/pu_field.hpp>
#include <kintsugi/spatial/kd_tree.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace kintsugi {

/// Which way the input normals point.
enum class NormalConvention {
    outward,  ///< out of the object (kintsugi's and most tools' convention)
    inward,   ///< into the object (the convention of Nagai et al.)
};

/// How the tetrahedra's vertices are labelled inside/outside.
enum class Labeling {
    graphcut,  ///< minimum cut of the graph of eq. 8–10 (the paper's method)
    sign,      ///< the plain sign of the PU field (f < 0 inside), for comparison
};

/// The smallest PUGraphcutParams::refine_spacing other than 0: edges below a quarter of the
/// samples' spacing add vertices (16 times as many as at 1), not detail.
inline constexpr Scalar min_refine_spacing = 0.25;

/// Parameters of reconstruct_pu_graphcut (aggregate; field order is API, append only).
struct PUGraphcutParams {
    /// Octree depth in [1, 12]; the paper uses 8 (Si-sa, bunny) and 9 (Dragon, Buddha).
    int max_level = 8;
    /// PU approximation tolerance ε (eq. 6), as a fraction of the bounding box's longest
    /// side; the paper's 4e-3 (Dragon).
    Scalar epsilon = 4e-3;
    /// Ratio k of terminal to non-terminal capacities (eq. 8, 9); > 0. The paper finds
    /// 5–15 good (small k erodes thin parts, large k inflates) and uses 10.
    Scalar k = 10;
    /// Taubin λ/μ iterations of the selective smoothing (paper: 30, λ = 0.5); 0 = none.
    std::size_t smoothing_iterations = 30;
    /// Seed of the random order of the support cover.
    std::uint64_t seed = 0;
    /// Input normal convention (outward by default).
    NormalConvention normals = NormalConvention::outward;
    /// graphcut (default) or sign (PU only, for comparison).
    Labeling labeling = Labeling::graphcut;
    /// Progress callback and cancellation.
    RunControl control{};
    // The measurements behind the defaults below: docs/methods/pu_graphcut.md.
    /// A support holding fewer input points than this is not trusted to tell inside from
    /// outside: its vertex's terminal links (eq. 8, 9) use the median signed distance to
    /// the tangent planes of the 7 nearest trusted supports. >= 0; default 10, the paper's
    /// "too few points" (§2.3); the paper trusts every support (0), which 10 % uniform
    /// outliers defeat.
    std::size_t min_support_points = 10;
    /// A support is trusted only if its normals agree too: PUSupport::coherence =
    /// |Σ w n| / Σ w at least this. In [0, 1], 0 disables; default 0.8 (a surface patch
    /// has more than 0.95; outlier supports far from the data about 1/sqrt(count)).
    Scalar min_support_coherence = 0.8;
    /// Scale s of the weights (s · r_i)² of the step-4 triangulation of the support
    /// centres. In [0, 1]; default 0 (no support hidden, a Delaunay triangulation);
    /// the paper's 1 hides the small supports a thin part needs, and the cut then
    /// perforates it (handles).
    Scalar triangulation_weight_scale = 0;
    /// After the cut (Labeling::graphcut only): inside regions with fewer vertices than
    /// this fraction of the largest that are not supported by the data (see
    /// min_region_supports) become outside; such cavities become inside. In [0, 1], 0
    /// disables (the paper); default 0.01: clustered outliers can leave such specks.
    Scalar min_region_fraction = 0.01;
    /// Factor on the weight of the untrusted supports in the PU field used for the edge
    /// capacities (eq. 10) and the vertex placement (step 6). In [0, 1], 1 is the
    /// paper's field; default 1e-3: where a trusted support covers x it decides f(x).
    Scalar untrusted_weight = 1e-3;
    /// Hole fill: mesh vertices farther than this fraction of r_i from the centre of
    /// every trusted support take the positions of a thin-plate patch (minimum of
    /// Σ |L x|², the other vertices fixed) before the smoothing. In [0, 1], 0 disables;
    /// default 0.75: there the field is an extrapolation or a blend of outliers.
    Scalar fill_radius_fraction = 0.75;
    /// Separated parts, in [0, 1] (0: one octree cube around every point, the paper):
    /// the points are split, recursively, at empty slabs (along x, y or z) wider than
    /// this fraction of their box's longest side, and each part gets its own cube
    /// (max_level and epsilon apply per part). A connected object has no such slab;
    /// a far point not split off grows the cube by a third at most.
    Scalar part_gap_fraction = 0.25;
    /// Separated parts holding fewer than this fraction of the points (or fewer than
    /// min_support_points) are left out as far outliers (PUGraphcutResult::far_points);
    /// in [0, 1], default 1 %: a few stray points are no object.
    Scalar min_part_fraction = 0.01;
    /// A small region (see min_region_fraction) is data, whatever its size, and is kept
    /// when at least this many of its vertices, and at least half of them, are trusted
    /// supports (min_support_points, min_support_coherence): a small second object, a
    /// real cavity. >= 0; default 4, the fewest vertices that span a volume (measured: a
    /// sphere 20x smaller than the torus beside it has 18-27 inside vertices, all
    /// trusted; outlier specks at most 6 of 47, see docs/methods/pu_graphcut.md).
    std::size_t min_region_supports = 4;
    /// Topological noise: a handle or tunnel of the result that a loop of mesh edges at
    /// most this many times h goes around is cut along the loop and both sides capped
    /// (kintsugi::remove_small_handles), h the median edge length of the part's mesh
    /// (the spacing of the support centres that sample the volume near the surface).
    /// >= 0, 0 disables; default 10: a cross-section under about 3 h across, which the
    /// labelling cannot resolve. Measured: the spurious handles' loops 0.1-6.8 h, real
    /// handles' at least 16 h (fertility, 50K points, 10 % outliers).
    Scalar max_handle_loop = 10;
    /// Detail at the samples' resolution: the cut's surface is refined until its edges
    /// are at most about this many times the local spacing of the input points near it,
    /// and each vertex with data near it is moved onto the moving-least-squares surface
    /// of those points (step 8; the topology is the labelling's). 0 keeps the surface of
    /// steps 6-7 (vertices on the triangulation's edges only), else >= min_refine_spacing
    /// (0.25: finer edges add vertices, not detail); default 1.5:
    /// clean bunny00 (100K) 14x closer to the truth than without, within 1.2x of
    /// screened Poisson at depth 10 with 40 % of its faces; 1 is 1.3x closer still at
    /// twice the vertices and time (docs/methods/pu_graphcut.md).
    Scalar refine_spacing = 1.5;
    /// Neighbours of the MLS fit of step 8 (kintsugi::PointSetSurfaceParams::k): more
    /// average more noise and flatten more detail. >= 4; default 20. Data denser than
    /// their noise are first averaged in groups so that each fit spans more samples
    /// (PUGraphcutResult::refine_neighbors_used).
    std::size_t refine_neighbors = 20;
    /// Far sites thinned (graphcut labelling only): an untrusted support whose terminal
    /// value (the median signed distance to the trusted tangent planes) exceeds this many
    /// times the trusted supports' median radius is labelled by its terminal links
    /// whatever its neighbours, so of those only one per grid cell of half that width
    /// becomes a vertex of step 4's triangulation; the rest stay supports of the field.
    /// >= 0, 0 keeps every support (the paper); default 8: the 2M bench input (10 %
    /// outliers) keeps 267K of 610K sites and runs in 11.1-14.6 s (13.9-17.3 s before) at
    /// the same mean distance; 4 was 0.05 % of the diagonal farther in Hausdorff
    /// (docs/methods/pu_graphcut.md).
    Scalar far_site_band = 8;
};

/// Result of reconstruct_pu_graphcut.
struct PUGraphcutResult {
    Status status = Status::ok;
    /// The surface (empty when cancelled, or when the overload writing into the
    /// caller's mesh was used): closed, outward oriented, 2-manifold, no degenerate
    /// triangles. Several components are possible when the data hold several objects.
    IndexedMesh mesh;
    std::size_t points = 0;              ///< input points
    std::size_t octree_cells = 0;        ///< candidate support centres
    std::size_t supports = 0;            ///< supports of the PU cover
    std::size_t hidden_supports = 0;     ///< supports hidden in the regular triangulation (not thinned ones)
    std::size_t outer_vertices = 0;      ///< outer-layer vertices (forced outside)
    std::size_t tetrahedra = 0;          ///< finite cells of the regular triangulation
    std::size_t graph_nodes = 0;         ///< non-terminal nodes (= triangulation vertices)
    std::size_t graph_edges = 0;         ///< non-terminal edges (= triangulation edges)
    Scalar cut_value = 0;                ///< minimum cut (0 with Labeling::sign)
    std::size_t inside_vertices = 0;     ///< triangulation vertices labelled inside
    std::size_t sign_disagreements = 0;  ///< vertices whose label differs from the sign of f
    std::size_t same_sign_vertices = 0;  ///< mesh vertices placed by the same-sign rule
    std::size_t smoothed_vertices = 0;   ///< mesh vertices moved by the selective smoothing
    std::size_t removed_regions = 0;     ///< small inside regions / cavities relabelled
    std::size_t filled_vertices = 0;     ///< mesh vertices placed by the thin-plate fill
    /// Per stage, in order: pu_octree, pu_cover, pu_index, triangulation, graph_cut,
    /// marching_tetrahedra, smoothing, handles, refine (summed over the parts).
    std::vector<StageTiming> timings;
    /// Input points left out of the surface: in separated parts (see
    /// PUGraphcutParams::part_gap_fraction) too small to be an object, spanning no
    /// volume (coplanar or collinear), or enclosing nothing. 0 for one object.
    std::size_t far_points = 0;
    /// Separated parts reconstructed, each in its own octree cube (1 for one object).
    /// The counts above are summed over them.
    std::size_t parts = 0;
    /// Handles and tunnels removed as topological noise (see
    /// PUGraphcutParams::max_handle_loop), summed over the parts.
    std::size_t handles_removed = 0;
    /// Mesh vertices moved onto the MLS surface of the data by step 8 (refine_spacing).
    std::size_t refined_vertices = 0;
    /// Step 8's noise estimate: the standard deviation of the inliers' offsets along their
    /// normals from their 8 neighbours' centroid, over their median spacing (the largest
    /// over the parts; 0 when step 8 did not run). Above about 0.22 each MLS fit spans more
    /// than refine_neighbors samples.
    Scalar refine_noise_ratio = 0;
    /// The input samples each MLS fit of step 8 spans: refine_neighbors, or, for data
    /// denser than their noise, (20 x refine_noise_ratio)^2, at most 16 x refine_neighbors:
    /// the inliers are then averaged in groups of about that / refine_neighbors and the fit
    /// takes refine_neighbors of the means (the largest over the parts; 0 when step 8 did
    /// not run).
    std::size_t refine_neighbors_used = 0;
    /// Untrusted supports far from the surface left out of the triangulation (see
    /// PUGraphcutParams::far_site_band), summed over the parts. Every support is either
    /// a graph node, hidden or thinned: graph_nodes = supports - hidden_supports -
    /// thinned_supports + outer_vertices.
    std::size_t thinned_supports = 0;
    /// Step 8 stopped splitting at its vertex budget (the mesh's vertices plus 4 per sample
    /// of its fit at refine_spacing 1.5, more at finer spacings) somewhere: the samples'
    /// spacing read far below the rest there (near-duplicate points, a dense cluster beside
    /// sparse data); the surface is finer than the triangulation's but not everywhere at the
    /// samples' spacing.
    bool refine_budget_reached = false;
};

namespace detail {

/// Forwards the inner run's progress to the user's callback, mapped into [a, b].
inline RunControl sub_control(const RunControl& outer, double a, double b) {
    RunControl c;
    c.stop = outer.stop;
    if (outer.progress)
        c.progress = [&outer, a, b](const ProgressEvent& e) {
            return outer.progress(ProgressEvent{e.stage, a + (b - a) * e.fraction});
        };
    return c;
}

inline void pu_graphcut_validate(const std::vector<Vec3>& pts, const std::vector<Vec3>& nrm,
                                 const PUGraphcutParams& p) {
    const std::string fn = "kintsugi::reconstruct_pu_graphcut: ";
    if (!(p.k > 0) || !std::isfinite(p.k))
        throw invalid_input(fn + "k = " + std::to_string(p.k) +
                            " must be positive and finite; the paper uses 10 (5-15 work well)");
    check_fraction(fn, "triangulation_weight_scale", p.triangulation_weight_scale,
                   "; 1 is the paper's regular triangulation, 0 (the default) hides no support");
    check_fraction(fn, "min_support_coherence", p.min_support_coherence,
                   "; the default is 0.8, 0 trusts any support with enough points");
    check_fraction(fn, "untrusted_weight", p.untrusted_weight, "; the default is 1e-3, 1 is the paper's field");
    check_fraction(fn, "fill_radius_fraction", p.fill_radius_fraction, "; the default is 0.75, 0 disables the fill");
    check_fraction(fn, "part_gap_fraction", p.part_gap_fraction,
                   "; the default is 0.25, 0 reconstructs every point in one box");
    check_fraction(fn, "min_part_fraction", p.min_part_fraction, "; the default is 0.01");
    if (!(p.max_handle_loop >= 0) || !std::isfinite(p.max_handle_loop))
        throw invalid_input(fn + "max_handle_loop = " + std::to_string(p.max_handle_loop) +
                            " must be finite and >= 0 (0 keeps every handle; the default is 10)");
    if (!(p.far_site_band >= 0) || !std::isfinite(p.far_site_band))
        throw invalid_input(fn + "far_site_band = " + std::to_string(p.far_site_band) +
                            " must be finite and >= 0 (0 keeps every support in the triangulation; the default is 8)");
    if (!(p.refine_spacing == 0 || p.refine_spacing >= min_refine_spacing) || !std::isfinite(p.refine_spacing))
        throw invalid_input(fn + "refine_spacing = " + std::to_string(p.refine_spacing) +
                            " must be 0 (the triangulation's resolution) or finite and >= 0.25 (edges below a quarter of "
                            "the samples' spacing add vertices, not detail; the default is 1.5)");
    if (p.refine_spacing > 0 && p.refine_neighbors < 4)
        throw invalid_input(fn + "refine_neighbors = " + std::to_string(p.refine_neighbors) +
                            " is too few for a surface fit; use at least 4 (the default is 20)");
    // The checks of PUField::build that do not depend on the points' spread (that one
    // runs per part, in the part's frame: pu_graphcut_validate_part).
    pu_validate_input(pts, nrm, p.max_level, p.epsilon, fn, /*tiny_normals=*/true);
}

/// PUField::build's check of one part (in its frame): "" when it passes, else the
/// message naming reconstruct_pu_graphcut (coincident, collinear or coplanar points).
inline std::string pu_graphcut_validate_part(const std::vector<Vec3>& pts, const std::vector<Vec3>& nrm,
                                             const PUGraphcutParams& p) {
    try {
        pu_validate(pts, nrm, PUFieldParams{.max_level = p.max_level, .epsilon = p.epsilon});
    } catch (const invalid_input& e) {
        std::string msg = e.what();
        const std::string from = "kintsugi::PUField::build: ";
        if (msg.rfind(from, 0) == 0) msg = "kintsugi::reconstruct_pu_graphcut: " + msg.substr(from.size());
        return msg;
    }
    return {};
}

/// Steps 1-7 on one part (validated, in its frame). Defined in
/// detail/pu_graphcut_run.ipp (kintsugi/core/stages.hpp).
KINTSUGI_STAGE PUGraphcutResult pu_graphcut_part(std::vector<Vec3> pts, std::vector<Vec3> nrm,
                                                 const PUGraphcutParams& params, const RunControl& control);

/// The whole run: validation, the separated parts (part_gap_fraction), each
/// reconstructed in its own frame and mapped back, the meshes concatenated. Defined in
/// detail/pu_graphcut_run.ipp.
KINTSUGI_STAGE PUGraphcutResult pu_graphcut_run(std::vector<Vec3> pts, std::vector<Vec3> nrm,
                                                const PUGraphcutParams& params);

}  // namespace detail

/// @brief Reconstructs a closed surface from oriented points, robustly to outliers:
/// Nagai, Ohtake, Suzuki, "Outlier robust implicit surface reconstruction using
/// graph-cut", IPSJ Journal 52(8), 2011.
///
/// Steps (every one of the paper): (1) octree to max_level with 2:1 balance;
/// (2) cover of the bounding cube by support balls with linear fits, radius by
/// bisection to the error ε, seeded random order; (3) the PU field f (the paper's f is
/// > 0 inside; PUField gives -f, kintsugi's sign);
/// (4) regular triangulation of the support centres weighted by (s r_i)² (CGAL; with
/// the paper's s = 1 hidden supports drop out; see triangulation_weight_scale for the
/// default s = 0) plus an outer layer of points forced outside; (5) graph with
/// the capacities of eq. 8–10 and constant k, minimum cut by Boykov–Kolmogorov
/// max-flow; (6) marching tetrahedra on the labels, vertex where f = 0 on the edge
/// (found on the PU field itself, not by interpolating the end values) when f changes
/// sign along it, else near the end with the smaller |f|; (7) Taubin λ/μ smoothing
/// (λ = 0.5, 30 iterations) of only the vertices on same-sign edges or on edges with
/// an end whose support holds fewer than 10 input points.
///
/// Beyond the paper, for robustness to many outliers and holes: the terminal links of
/// vertices whose support holds fewer than min_support_points points, or points whose
/// normals disagree, use the median of the nearest trusted tangent planes (see
/// PUGraphcutParams::min_support_points and min_support_coherence); those untrusted
/// supports count only where no trusted one covers x in the field of eq. 10 and step 6
/// (untrusted_weight); mesh vertices far from every trusted support (hole fills) are
/// placed by a thin-plate patch before step 7 (fill_radius_fraction).
///
/// Far outliers and separate objects: the points are split at wide empty slabs
/// (PUGraphcutParams::part_gap_fraction); each part large enough is reconstructed in
/// its own octree cube, the others are counted in far_points. Each part runs in its
/// own frame, recentred and scaled by a power of two when its coordinates lie outside
/// [2^-32, 2^32] (in the caller's coordinates otherwise, bit for bit as before), so
/// finite coordinates of any magnitude work.
///
/// Topological noise (beyond the paper): handles and tunnels that a loop shorter than
/// max_handle_loop mesh edges goes around are cut and capped (one-tetrahedron bridges
/// and perforations of the labelling); PUGraphcutResult::handles_removed counts them.
///
/// Detail at the samples' resolution (beyond the paper, step 8): the surface of steps
/// 6-7 has its vertices on the edges of the support triangulation, few and long where
/// the surface is smooth. It is refined by edge splits and Delaunay flips until its
/// edges are about refine_spacing times the local sample spacing, and every vertex
/// with data near it is moved onto the MLS surface (APSS) of the input points near the
/// field's zero set (the outliers far from it are left out; data denser than their
/// noise averaged in small groups first); hole fills are re-faired
/// between them. The labelling keeps the topology (no edge is collapsed). See
/// docs/methods/pu_graphcut.md for the measurements.
///
/// Output guarantee: a closed, consistently outward-oriented 2-manifold triangle mesh
/// without degenerate triangles (before smoothing no two vertices coincide; smoothing
/// moves vertices but never changes the connectivity; step 8 only splits and flips
/// edges, and a move that would make a triangle degenerate is undone).
///
/// Deterministic: the same input and seed give bit-identical output whatever the
/// number of threads.
///
/// @tparam P an OrientedPointSet (read once into the internal layout).
/// @param points positions (any unit) with normals (outward unless params.normals is
///        inward); outliers and holes are expected.
/// @param params see PUGraphcutParams; ε is relative to the longest bounding-box side.
/// @pre at least 4 points spread in 3D, normals present, finite and non-zero.
/// @throws invalid_input for fewer than 4 points, missing or zero normals, NaN/Inf
///         coordinates or normals, all points coplanar or collinear, k <= 0 or not
///         finite, max_level outside [1, 12], epsilon <= 0; and when the surface would
///         be empty (no support labelled inside, or no separated part large enough),
///         naming the reason and the fix. Inputs untouched.
/// @return the mesh, counts and per-stage timings. Status::cancelled: stopped through
///         params.control at any stage; the mesh is empty and the input untouched.
template <OrientedPointSet P>
[[nodiscard]] PUGraphcutResult reconstruct_pu_graphcut(const P& points, const PUGraphcutParams& params = {}) {
    if (!has_normals(points))
        throw invalid_input("kintsugi::reconstruct_pu_graphcut: the points have no normals; estimate oriented "
                            "normals first (kintsugi::estimate_normals)");
    return detail::pu_graphcut_run(gather_points(points), gather_normals(points), params);
}

/// @brief Same as reconstruct_pu_graphcut(points, params), writing the surface into
/// any TopologyMutableMesh (cleared first). On cancellation or error `out` is left
/// untouched. The returned result's `mesh` member is empty.
/// @tparam M a TopologyMutableMesh (IndexedMesh, CGAL::Surface_mesh, ...).
template <OrientedPointSet P, TopologyMutableMesh M>
PUGraphcutResult reconstruct_pu_graphcut(const P& points, M& out, const PUGraphcutParams& params = {}) {
    PUGraphcutResult res = reconstruct_pu_graphcut(points, params);
    if (res.status == Status::ok) {
        assign_mesh(out, res.mesh);
        res.mesh = IndexedMesh{};
    }
    return res;
}

}  // namespace kintsugi

#ifndef KINTSUGI_SEPARATE_STAGES
#include <kintsugi/reconstruct/detail/pu_graphcut_run.ipp>
#endif
