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
#include <kintsugi/core/types.hpp>
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
    /// centres. In [0, 1]; default 0 (every support kept, a Delaunay triangulation);
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
    std::size_t hidden_supports = 0;     ///< supports hidden in the regular triangulation
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
    /// marching_tetrahedra, smoothing (summed over the parts).
    std::vector<StageTiming> timings;
    /// Input points left out of the surface: in separated parts (see
    /// PUGraphcutParams::part_gap_fraction) too small to be an object, spanning no
    /// volume (coplanar or collinear), or enclosing nothing. 0 for one object.
    std::size_t far_points = 0;
    /// Separated parts reconstructed, each in its own octree cube (1 for one object).
    /// The counts above are summed over them.
    std::size_t parts = 0;
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
                   "; 1 is the paper's regular triangulation, 0 (the default) keeps every support");
    check_fraction(fn, "min_support_coherence", p.min_support_coherence,
                   "; the default is 0.8, 0 trusts any support with enough points");
    check_fraction(fn, "untrusted_weight", p.untrusted_weight, "; the default is 1e-3, 1 is the paper's field");
    check_fraction(fn, "fill_radius_fraction", p.fill_radius_fraction, "; the default is 0.75, 0 disables the fill");
    check_fraction(fn, "part_gap_fraction", p.part_gap_fraction,
                   "; the default is 0.25, 0 reconstructs every point in one box");
    check_fraction(fn, "min_part_fraction", p.min_part_fraction, "; the default is 0.01");
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

/// Forwards a part's progress into [a, b] of the whole run, at most once per 1 % of
/// the run (`last`: the last fraction forwarded); the parts' own "done" is dropped.
inline RunControl part_control(const RunControl& outer, double a, double b, double& last) {
    RunControl c;
    c.stop = outer.stop;
    if (outer.progress)
        c.progress = [&outer, a, b, &last](const ProgressEvent& e) {
            const double f = a + (b - a) * e.fraction;
            if (e.stage == "done" || f < last + 0.01) return true;
            last = f;
            return outer.progress(ProgressEvent{e.stage, f});
        };
    return c;
}

/// Steps 1-7 on one part (validated, in its frame).
inline PUGraphcutResult pu_graphcut_part(std::vector<Vec3> pts, std::vector<Vec3> nrm, const PUGraphcutParams& params,
                                         const RunControl& control) {
    PUGraphcutResult res;
    res.points = pts.size();
    // Fractions of the overall progress per stage (measured on the 100K bunny).
    constexpr double pu_end = 0.35, tri_end = 0.7, cut_end = 0.85, mt_end = 0.92;

    // Steps 1-3: the PU field.
    PUFieldResult pu = PUField::build_from(std::move(pts), std::move(nrm),
                                           PUFieldParams{.max_level = params.max_level,
                                                         .epsilon = params.epsilon,
                                                         .seed = params.seed,
                                                         .inward_normals = params.normals == NormalConvention::inward,
                                                         .control = sub_control(control, 0.0, pu_end)});
    if (pu.status == Status::cancelled) {
        res.status = Status::cancelled;
        return res;
    }
    res.octree_cells = pu.octree_cells;
    res.supports = pu.supports;
    res.timings = pu.timings;
    const PUField& field = pu.field;
    const auto& sup = field.supports();

    return run_cancellable<PUGraphcutResult>(control, [&](Progress& progress) {
        // Step 4: regular triangulation of the supports (weights (s r)²) plus an outer layer
        // of plain points on a box enclosing every support ball: never hidden (no ball
        // contains them), never hiding a support, labelled outside so the surface closes.
        progress.stage("triangulation", pu_end, tri_end);
        const std::size_t ns = sup.size();
        std::vector<Vec3> sites(ns);
        std::vector<Scalar> radii(ns);
        BoundingBox balls;
        for (std::size_t i = 0; i < ns; ++i) {
            sites[i] = sup[i].center;
            radii[i] = params.triangulation_weight_scale * sup[i].radius;
            balls.extend(sup[i].center - Vec3::Constant(sup[i].radius));
            balls.extend(sup[i].center + Vec3::Constant(sup[i].radius));
        }
        const Scalar margin = Scalar(0.05) * balls.extent().maxCoeff();
        balls.min -= Vec3::Constant(margin);
        balls.max += Vec3::Constant(margin);
        const auto outer = box_surface_points(balls, 6);
        for (const Vec3& p : outer) {
            sites.push_back(p);
            radii.push_back(0);
        }
        const PUTetMesh tm = regular_tet_mesh(sites, radii, progress, 0.0, 0.8);
        const std::size_t nv = tm.vertices.size();
        // Vertices are numbered by increasing site index, so the surviving supports come
        // first (vertex v < alive_supports is support tm.site[v]) and the outer layer last.
        const auto alive_supports = static_cast<std::size_t>(
            std::lower_bound(tm.site.begin(), tm.site.end(), ns) - tm.site.begin());
        std::vector<std::uint8_t> is_outer(nv, 0);
        std::fill(is_outer.begin() + static_cast<std::ptrdiff_t>(alive_supports), is_outer.end(), 1);
        res.hidden_supports = ns - alive_supports;
        res.outer_vertices = nv - alive_supports;
        res.tetrahedra = tm.tets.size();
        res.graph_nodes = nv;
        res.graph_edges = tm.edges.size();

        // f at the vertices: the PU field at the support centres (eq. 1). A support
        // holding fewer than min_support_points input points, or points whose normals
        // disagree (an outlier's support, an empty one far from the data, a coarse one
        // full of outliers) carries no information about inside and outside, and with
        // many outliers such supports fill the empty space with wrong-signed values. At
        // those vertices, and at the outer layer, the terminal links use instead the
        // median signed distance to the tangent planes g_j of the nearest trusted
        // supports (centroids d_j nearest; Hoppe et al. 1992 with a median, so that one
        // trusted-looking outlier support cannot flip a region), which keeps the deep
        // inside and outside anchored by the terminal links of eq. 8-9.
        const std::vector<Vec3> centers(tm.vertices.begin(),
                                        tm.vertices.begin() + static_cast<std::ptrdiff_t>(alive_supports));
        auto trusted_support = [&](const PUSupport& s) {
            return s.point_count >= params.min_support_points && s.coherence >= params.min_support_coherence;
        };
        // The PU field with the weights of untrusted supports scaled by untrusted_weight:
        // where a trusted support covers x it decides f(x), elsewhere the untrusted
        // supports still define a (continuous) field. Used for eq. 10 and the vertex
        // placement of step 6.
        std::vector<Scalar> factors(ns);
        for (std::size_t i = 0; i < ns; ++i)
            factors[i] = trusted_support(sup[i]) ? Scalar(1) : params.untrusted_weight;
        const PUField tfield = params.untrusted_weight == 1 ? field : field.reweighted(std::move(factors));
        // The paper's sign (> 0 inside) from here on: f_pu, f, the graph and the labels.
        std::vector<Scalar> fc = tfield.values(centers);
        for (Scalar& v : fc) v = -v;
        progress.update(0.9);
        std::vector<Index> trusted;
        for (std::size_t i = 0; i < ns; ++i)
            if (trusted_support(sup[i])) trusted.push_back(i);
        if (trusted.empty())
            for (std::size_t i = 0; i < ns; ++i) trusted.push_back(i);
        std::vector<Vec3> origins(trusted.size());
        for (std::size_t j = 0; j < trusted.size(); ++j) origins[j] = sup[trusted[j]].origin;
        const auto origin_tree = KdTree::adopt(std::move(origins));
        std::vector<Scalar> f(nv), f_pu(nv);
        parallel_for(0, nv, [&](std::size_t v) {
            bool trust = false;
            if (!is_outer[v]) {
                f_pu[v] = std::isnan(fc[v]) ? Scalar(0) : fc[v];
                trust = trusted_support(sup[tm.site[v]]);
            }
            if (trust) {
                f[v] = f_pu[v];
            } else {
                constexpr std::size_t planes = 7;  // odd: the median is one plane's value
                thread_local std::vector<Neighbor> nbs;
                origin_tree.knn(tm.vertices[v], std::min(planes, trusted.size()), nbs);
                thread_local std::vector<Scalar> ds;
                ds.clear();
                for (const auto& nb : nbs) {
                    const PUSupport& s = sup[trusted[nb.index]];
                    ds.push_back(s.normal.dot(tm.vertices[v] - s.origin));
                }
                std::nth_element(ds.begin(), ds.begin() + ds.size() / 2, ds.end());
                f[v] = ds[ds.size() / 2];
                if (is_outer[v]) f_pu[v] = std::min(f[v], Scalar(-1e-12));
            }
        }, 1024);

        // Step 5: labels.
        progress.stage("graph_cut", tri_end, cut_end);
        std::vector<std::uint8_t> inside;
        if (params.labeling == Labeling::graphcut) {
            inside = graphcut_labels(tm, f_pu, f, is_outer, params.k, res.cut_value, control);
            if (params.min_region_fraction > 0) {
                std::vector<std::uint8_t> trusted_vertex(nv, 0);
                for (std::size_t v = 0; v < alive_supports; ++v) trusted_vertex[v] = trusted_support(sup[tm.site[v]]);
                res.removed_regions = remove_small_regions(tm, is_outer, inside, params.min_region_fraction,
                                                           trusted_vertex, params.min_region_supports, control.stop);
            }
        } else {
            // PU alone: the sign of the field (outer layer outside).
            inside.resize(nv);
            for (std::size_t v = 0; v < nv; ++v) inside[v] = !is_outer[v] && f_pu[v] > 0;
        }
        for (std::size_t v = 0; v < nv; ++v) {
            res.inside_vertices += inside[v];
            if (!is_outer[v] && (inside[v] != 0) != (f_pu[v] > 0)) ++res.sign_disagreements;
        }
        progress.check();

        // Step 6: marching tetrahedra with the same-sign rule.
        progress.stage("marching_tetrahedra", cut_end, mt_end);
        MarchingTetrahedraParams mp;
        mp.tets_positively_oriented = true;
        mp.control.stop = control.stop;
        MarchingTetrahedraResult mt = marching_tetrahedra(tm.vertices, tm.tets, inside, f_pu, mp);
        if (mt.status == Status::cancelled) throw cancelled_exception{};
        (void)place_on_zero_set(tfield, tm.vertices, f_pu, mt, mp.min_edge_fraction, 8, progress);
        res.same_sign_vertices = mt.same_sign_vertices;

        // Step 7: selective Taubin smoothing of the vertices on same-sign edges and on
        // edges with an end whose support holds fewer than 10 input points; before it,
        // the thin-plate fill of the unsupported vertices (fill_radius_fraction).
        progress.stage("smoothing", mt_end, 1.0);
        constexpr std::size_t few_points = 10;
        auto sparse = [&](Index v) { return is_outer[v] || sup[tm.site[v]].point_count < few_points; };
        std::vector<std::uint8_t> movable(mt.mesh.vertices.size(), 0);
        for (std::size_t i = 0; i < movable.size(); ++i) {
            const auto& e = mt.vertex_edges[i];
            movable[i] = mt.same_sign[i] || sparse(e[0]) || sparse(e[1]);
        }
        // Unsupported vertices (hole fills, see fill_radius_fraction): farther than
        // fill_radius_fraction x r_i from the centre of every trusted support.
        std::vector<std::uint8_t> unsupported(mt.mesh.vertices.size(), 0);
        if (params.fill_radius_fraction > 0)
            mark_unsupported(mt.mesh.vertices, sup, trusted, params.fill_radius_fraction, unsupported, control.stop);
        // The fill first (from the placed vertices around it), then the selective
        // smoothing of the other movable vertices, which sees the filled positions.
        const MeshTopology topo(mt.mesh.vertices.size(), mt.mesh.faces);
        progress.check();
        res.filled_vertices = biharmonic_fill(mt.mesh.vertices, topo, unsupported);
        progress.check();
        for (std::size_t i = 0; i < movable.size(); ++i) movable[i] = movable[i] && !unsupported[i];
        if (params.smoothing_iterations > 0) {
            TaubinParams tp;
            tp.iterations = params.smoothing_iterations;
            res.smoothed_vertices = taubin_smooth(mt.mesh.vertices, topo, movable, tp, progress);
        }
        res.mesh = std::move(mt.mesh);
        auto t = progress.finish();
        res.timings.insert(res.timings.end(), t.begin(), t.end());
        res.status = Status::ok;
        return std::move(res);
    });
}

/// The whole run: validation, the separated parts (part_gap_fraction), each
/// reconstructed in its own frame (PUFrame: the caller's coordinates when safe, else
/// recentred and scaled by a power of two) and mapped back, the meshes concatenated.
inline PUGraphcutResult pu_graphcut_run(std::vector<Vec3> pts, std::vector<Vec3> nrm, const PUGraphcutParams& params) {
    pu_graphcut_validate(pts, nrm, params);
    const std::string fn = "kintsugi::reconstruct_pu_graphcut: ";
    const std::size_t n = pts.size();
    std::vector<std::vector<Index>> groups = pu_separated_parts(pts, params.part_gap_fraction);
    const std::size_t min_points = std::max<std::size_t>(
        {static_cast<std::size_t>(std::ceil(params.min_part_fraction * static_cast<Scalar>(n))),
         params.min_support_points, 4});
    std::vector<std::size_t> chosen;
    for (std::size_t g = 0; g < groups.size(); ++g)
        if (groups.size() == 1 || groups[g].size() >= min_points) chosen.push_back(g);
    if (chosen.empty())
        throw invalid_input(fn + "no part of the input can be reconstructed: the points fall into " +
                            std::to_string(groups.size()) + " groups separated by empty space (gaps wider than " +
                            "part_gap_fraction = " + std::to_string(params.part_gap_fraction) +
                            " of their extent) and none holds " + std::to_string(min_points) +
                            " points or more (min_part_fraction of the input, at least min_support_points); "
                            "remove the scattered points, or set part_gap_fraction = 0 to reconstruct them in one box");
    std::size_t total = 0;
    for (const std::size_t g : chosen) total += groups[g].size();

    PUGraphcutResult res;
    res.points = n;
    res.far_points = n - total;
    std::string problem;  // why the last part left out gave nothing
    std::size_t done = 0;
    double last = -1;
    for (const std::size_t g : chosen) {
        const std::vector<Index>& ids = groups[g];
        const double a = static_cast<double>(done) / static_cast<double>(total);
        done += ids.size();
        const double b = static_cast<double>(done) / static_cast<double>(total);
        const PUFrame frame = PUFrame::of(pts, ids);
        std::vector<Vec3> pp, nn;
        if (ids.size() == n) {
            pp = std::move(pts);
            nn = std::move(nrm);
        } else {
            pp.reserve(ids.size());
            nn.reserve(ids.size());
            for (const Index i : ids) {
                pp.push_back(pts[i]);
                nn.push_back(nrm[i]);
            }
        }
        if (!frame.identity)
            for (Vec3& x : pp) x = frame.to_frame(x);
        pu_safe_normals(nn);
        if (std::string bad = pu_graphcut_validate_part(pp, nn, params); !bad.empty()) {
            if (chosen.size() == 1) {
                if (res.far_points > 0)
                    bad += " (" + std::to_string(res.far_points) + " points far from the others were left out)";
                throw invalid_input(bad);
            }
            problem = bad;
            res.far_points += ids.size();
            continue;
        }
        const RunControl control = chosen.size() == 1 ? params.control : part_control(params.control, a, b, last);
        PUGraphcutResult r = pu_graphcut_part(std::move(pp), std::move(nn), params, control);
        if (r.status == Status::cancelled) {
            return cancelled_result<PUGraphcutResult>();
        }
        if (r.mesh.faces.empty()) {
            problem = fn + "the surface is empty: the labelling put none of the " + std::to_string(r.supports) +
                      " supports inside, so the points do not enclose a volume at this resolution; check that the "
                      "normals point out of the object (or set normals = NormalConvention::inward), or raise "
                      "max_level / lower epsilon";
            res.far_points += ids.size();
            continue;
        }
        for (Vec3& v : r.mesh.vertices) {
            v = frame.from_frame(v);
            if (!v.allFinite())
                throw invalid_input(fn + "the surface reaches beyond the largest finite double (the points lie too "
                                         "close to it); scale the points down first");
        }
        const Index base = res.mesh.vertices.size();
        res.mesh.vertices.insert(res.mesh.vertices.end(), r.mesh.vertices.begin(), r.mesh.vertices.end());
        for (auto f : r.mesh.faces) {
            for (auto& v : f) v += base;
            res.mesh.faces.push_back(f);
        }
        ++res.parts;
        using R = PUGraphcutResult;
        for (std::size_t R::*count :
             {&R::octree_cells, &R::supports, &R::hidden_supports, &R::outer_vertices, &R::tetrahedra,
              &R::graph_nodes, &R::graph_edges, &R::inside_vertices, &R::sign_disagreements, &R::same_sign_vertices,
              &R::smoothed_vertices, &R::removed_regions, &R::filled_vertices})
            res.*count += r.*count;
        res.cut_value += r.cut_value;
        for (const StageTiming& t : r.timings) {
            auto it = std::find_if(res.timings.begin(), res.timings.end(),
                                   [&](const StageTiming& u) { return u.stage == t.stage; });
            if (it == res.timings.end()) res.timings.push_back(t);
            else it->seconds += t.seconds;
        }
    }
    if (res.mesh.faces.empty()) {
        if (groups.size() > 1)
            problem += " (the points fall into " + std::to_string(groups.size()) +
                       " parts separated by empty space; " + std::to_string(chosen.size()) + " hold " +
                       std::to_string(min_points) + " points or more and none of them gave a surface)";
        throw invalid_input(problem);
    }
    if (chosen.size() > 1 && params.control.progress && !params.control.progress(ProgressEvent{"done", 1.0})) {
        return cancelled_result<PUGraphcutResult>();
    }
    res.status = Status::ok;
    return res;
}

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
/// Output guarantee: a closed, consistently outward-oriented 2-manifold triangle mesh
/// without degenerate triangles (before smoothing no two vertices coincide; smoothing
/// moves vertices but never changes the connectivity).
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
