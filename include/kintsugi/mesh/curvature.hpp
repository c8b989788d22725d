// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file curvature.hpp
/// @brief Principal curvatures and directions at every point of a point set or every
/// vertex of a triangle mesh, from local jet (polynomial) fits.
///
/// @code
/// auto r = kintsugi::estimate_curvatures(points, {.k = 60});  // any PointSet
/// auto m = kintsugi::estimate_curvatures(mesh);                            // any TriangleMesh
/// auto q = kintsugi::estimate_curvatures_at(points, new_points);           // off-sample queries
/// // r.curvatures[i].k1 >= k2, d1, d2, normal; mean_curvature(), gaussian_curvature()
/// @endcode
///
/// Method: Cazals & Pouget, "Estimating differential quantities using polynomial
/// fitting of osculating jets", CAGD 2005, through the library's one jet fit
/// (spatial/jet_fit.hpp, which normal estimation uses too). A point's neighbourhood
/// is its k nearest points (point sets) or the vertices within `rings` edge rings,
/// widened ring by ring until it has `k` vertices (meshes). Signs: curvatures are
/// positive where the surface bends away from the normal (1/R on a sphere with
/// outward normals); the normal is oriented along the input's normals when the
/// point set has them, along the area-weighted vertex normal on a mesh (outward for
/// a closed mesh with counter-clockwise faces), and is the fit's own otherwise.
/// Accuracy measured in tests/mesh/test_curvature.cpp (docs/methods/point_set_surface.md).

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/spatial/jet_fit.hpp>
#include <kintsugi/spatial/kd_tree.hpp>

#include <algorithm>
#include <string>
#include <vector>

namespace kintsugi {

/// Parameters of estimate_curvatures (aggregate; field order is API, append only).
struct CurvatureParams {
    /// Neighbourhood size: the point and its k-1 nearest points (point sets); the
    /// fewest vertices a mesh neighbourhood is widened to. Range
    /// [jet_coefficients(degree), number of points]. 30 with degree 4 measured within
    /// 0.14 % (max) of the analytic curvatures on 20K-point spheres and tori; larger k
    /// averages noise at the price of bias where the curvature changes.
    std::size_t k = 30;
    /// Jet degree, 2 to 4. 4 is Cazals & Pouget's choice for curvature: on the 20K
    /// torus (k 30) the largest error is 5.4 % with degree 2, 1.9 % with 3, 0.13 %
    /// with 4 (docs/methods/point_set_surface.md).
    int degree = 4;
    /// Meshes: the neighbourhood holds at least the vertices within this many edge
    /// rings (then grows ring by ring up to k vertices). Range >= 1; default 2.
    std::size_t rings = 2;
    RunControl control{};
};

/// Curvature at one point.
struct PrincipalCurvature {
    Scalar k1 = 0, k2 = 0;                      ///< principal curvatures, k1 >= k2 (1/units; sign: see file comment)
    Vec3 d1 = Vec3::Zero(), d2 = Vec3::Zero();  ///< unit principal directions of k1, k2 (zero when not valid)
    Vec3 normal = Vec3::Zero();                 ///< unit normal the signs refer to
    bool valid = false;                         ///< false where the neighbourhood was degenerate
    [[nodiscard]] Scalar mean_curvature() const { return (k1 + k2) / 2; }
    [[nodiscard]] Scalar gaussian_curvature() const { return k1 * k2; }
};

/// Outcome of estimate_curvatures.
struct CurvatureResult {
    Status status = Status::ok;
    std::vector<PrincipalCurvature> curvatures;  ///< one per point / vertex, input order; empty when cancelled
    std::size_t invalid = 0;                     ///< points whose fit was degenerate (valid == false)
    std::vector<StageTiming> timings;            ///< "neighbours" (kd-tree or topology), "fit"
};

namespace detail::curvature {

inline void validate(const char* fn, const std::vector<Vec3>& pts, const CurvatureParams& p, const char* what) {
    if (pts.empty()) throw invalid_input(std::string(fn) + ": the " + what + " is empty; pass at least " +
                                         std::to_string(jet_coefficients(std::clamp(p.degree, 2, 4))) + " points");
    if (p.degree < 2 || p.degree > 4)
        throw invalid_input(std::string(fn) + ": params.degree = " + std::to_string(p.degree) +
                            " is out of range; pass 2, 3 or 4");
    const std::size_t need = jet_coefficients(p.degree);
    if (p.k < need || p.k > pts.size())
        throw invalid_input(std::string(fn) + ": params.k = " + std::to_string(p.k) + " is out of range; it must be in [" +
                            std::to_string(need) + ", " + std::to_string(pts.size()) +
                            "] (a degree-" + std::to_string(p.degree) + " jet needs " + std::to_string(need) +
                            " points, and there are " + std::to_string(pts.size()) + ")");
    check_finite_points(pts, std::string(fn) + ": " + (std::string(what) == "mesh" ? "vertex " : "point "));
}

inline PrincipalCurvature to_principal(const JetFit& j) {
    PrincipalCurvature c;
    if (!j.valid) return c;
    c.k1 = j.k1;
    c.k2 = j.k2;
    c.d1 = j.d1;
    c.d2 = j.d2;
    c.normal = j.normal;
    c.valid = true;
    return c;
}

/// Runs fit(i) -> PrincipalCurvature for every i, in parallel fixed blocks with progress.
template <class Fit>
std::vector<PrincipalCurvature> fit_all(std::size_t n, Progress& progress, Fit&& fit) {
    std::vector<PrincipalCurvature> out(n);
    const std::size_t blocks = std::clamp<std::size_t>(n / 2048, 1, 50);
    for (std::size_t b = 0; b < blocks; ++b) {
        parallel_for(n * b / blocks, n * (b + 1) / blocks, [&](std::size_t i) { out[i] = fit(i); }, 32);
        progress.update(static_cast<double>(b + 1) / static_cast<double>(blocks));
    }
    return out;
}

/// Runs `body(progress)` (which returns the curvatures) under the RunControl: timings,
/// the invalid count, and Status::cancelled with no curvatures when cancelled.
template <class Body>
CurvatureResult run_guarded(const CurvatureParams& params, Body&& body) {
    CurvatureResult result;
    detail::Progress progress(params.control);
    try {
        result.curvatures = body(progress);
        result.timings = progress.finish();
    } catch (const detail::cancelled_exception&) {
        result.status = Status::cancelled;
        result.curvatures.clear();
        return result;
    }
    result.invalid = static_cast<std::size_t>(
        std::count_if(result.curvatures.begin(), result.curvatures.end(), [](const auto& x) { return !x.valid; }));
    return result;
}

/// Jet fits from the k nearest samples: at every sample (queries == nullptr; the
/// sample itself is the fit's origin) or at every query point (the jet centred there).
/// Oriented along the sample's (or the nearest sample's) normal when there are normals.
inline CurvatureResult knn_fits(std::vector<Vec3> pts, const std::vector<Vec3>* queries,
                                const std::vector<Vec3>& normals, const CurvatureParams& params) {
    return run_guarded(params, [&](Progress& progress) {
        progress.stage("neighbours", 0.0, 0.1);
        const auto tree = KdTree::adopt(std::move(pts));
        progress.stage("fit", 0.1, 1.0);
        const std::size_t k = params.k;
        const int degree = params.degree;
        const std::size_t n = queries ? queries->size() : tree.size();
        return fit_all(n, progress, [&](std::size_t i) {
            thread_local std::vector<Neighbor> nn;
            const Vec3& x = queries ? (*queries)[i] : tree.point(i);
            tree.knn(x, k, nn);
            auto get = [&](std::size_t j) -> const Vec3& { return tree.point(nn[j].index); };
            JetFit jf;
            if (queries) {
                jf = fit_jet(get, nn.size(), x, degree, true);
            } else {
                // The point itself first (a duplicate may precede it in the kNN order).
                for (std::size_t j = 0; j < nn.size(); ++j)
                    if (nn[j].index == i) {
                        std::swap(nn[0], nn[j]);
                        break;
                    }
                jf = fit_jet(get, nn.size(), degree, true);
            }
            if (!normals.empty()) orient_jet(jf, normals[nn.front().index]);
            return to_principal(jf);
        });
    });
}

}  // namespace detail::curvature

/// @brief Principal curvatures and directions at every point of a point set, from a
/// jet fitted to the point and its k-1 nearest neighbours (Cazals & Pouget, CAGD 2005).
/// @tparam P a PointSet (std::vector<Eigen::Vector3d>, with_normals view, PointCloud,
///         CGAL::Point_set_3, project_points view). With normals (has_normals), each
///         result's normal and signs follow them; without, the fit's own sign is kept.
/// @param points positions in any unit (curvatures come out in 1/units).
/// @param params k, degree, control (rings is unused here).
/// @pre finite coordinates; k in [jet_coefficients(degree), n]; degree in [2, 4].
/// @throws invalid_input for an empty set, a NaN/Inf coordinate, k or degree out of range.
/// @return status ok: one PrincipalCurvature per point (valid false where degenerate);
///         cancelled: curvatures empty (the input is never modified).
template <PointSet P>
[[nodiscard]] CurvatureResult estimate_curvatures(const P& points, const CurvatureParams& params = {}) {
    constexpr const char* fn = "kintsugi::estimate_curvatures";
    std::vector<Vec3> pts = gather_points(points);
    detail::curvature::validate(fn, pts, params, "point set");
    return detail::curvature::knn_fits(std::move(pts), nullptr, gather_normals(points), params);
}

/// @brief Principal curvatures and directions of the surface sampled by `samples`, at
/// query points that need not be samples (e.g. new surfels, MLS projections): a jet
/// fitted to each query's k nearest samples, centred at the query (fit_jet_at).
/// @tparam P a PointSet (the samples; with normals, the signs follow the nearest
///         sample's normal). @tparam Q a PointSet (the queries, near the surface).
/// @param params k, degree, control (rings is unused).
/// @pre finite coordinates; k in [jet_coefficients(degree), number of samples].
/// @throws invalid_input for empty samples, a NaN/Inf sample or query, k or degree out of range.
/// @return status ok: one PrincipalCurvature per query (its normal and curvatures are
///         those of the fitted surface point nearest above the query); cancelled: empty.
template <PointSet P, PointSet Q>
[[nodiscard]] CurvatureResult estimate_curvatures_at(const P& samples, const Q& queries,
                                                     const CurvatureParams& params = {}) {
    constexpr const char* fn = "kintsugi::estimate_curvatures_at";
    std::vector<Vec3> pts = gather_points(samples);
    detail::curvature::validate(fn, pts, params, "point set");
    const std::vector<Vec3> q = gather_points(queries);
    detail::check_finite_points(q, std::string(fn) + ": query point ");
    return detail::curvature::knn_fits(std::move(pts), &q, gather_normals(samples), params);
}

/// @brief Principal curvatures and directions at every vertex of a triangle mesh, from
/// a jet fitted to the vertices within `rings` edge rings (widened ring by ring until
/// there are k of them; Cazals & Pouget, CAGD 2005).
/// @tparam M a TriangleMesh (IndexedMesh, Eigen V/F view, CGAL::Surface_mesh, a user type).
/// @param mesh triangles counter-clockwise seen from outside (the normals' and
///        curvatures' sign follow the area-weighted vertex normals).
/// @param params k (fewest vertices per neighbourhood), degree, rings, control.
/// @pre finite coordinates; face indices in range; k in [jet_coefficients(degree), V].
/// @throws invalid_input for an empty mesh, a NaN/Inf coordinate, a face index out of
///         range, k, degree or rings out of range.
/// @return status ok: one PrincipalCurvature per vertex (valid false for isolated
///         vertices and degenerate neighbourhoods); cancelled: curvatures empty.
template <TriangleMesh M>
[[nodiscard]] CurvatureResult estimate_curvatures(const M& mesh, const CurvatureParams& params = {}) {
    constexpr const char* fn = "kintsugi::estimate_curvatures";
    IndexedMesh m = to_indexed_mesh(mesh);
    detail::curvature::validate(fn, m.vertices, params, "mesh");
    if (params.rings == 0) throw invalid_input(std::string(fn) + ": params.rings is 0; pass at least 1 (default 2)");
    detail::check_face_indices(m, fn);
    return detail::curvature::run_guarded(params, [&](detail::Progress& progress) {
        progress.stage("neighbours", 0.0, 0.1);
        const MeshTopology topo(m.vertices.size(), m.faces);
        const std::vector<Vec3> vn = vertex_normals(m);
        progress.stage("fit", 0.1, 1.0);
        const std::size_t k = params.k, rings = params.rings;
        const int degree = params.degree;
        const std::vector<Vec3>& pos = m.vertices;
        return detail::curvature::fit_all(pos.size(), progress, [&](std::size_t v) {
            if (topo.vertex_neighbors(v).empty()) return PrincipalCurvature{};
            // Breadth-first rings around v (v first), until `rings` rings and k vertices.
            thread_local std::vector<Index> ring;
            thread_local std::vector<Index> seen;  // sorted visited set (neighbourhoods are small)
            ring.assign(1, v);
            seen.assign(1, v);
            std::size_t begin = 0;
            for (std::size_t r = 0; begin < ring.size() && (r < rings || ring.size() < k); ++r) {
                const std::size_t end = ring.size();
                for (std::size_t i = begin; i < end; ++i)
                    for (Index w : topo.vertex_neighbors(ring[i])) {
                        const auto it = std::lower_bound(seen.begin(), seen.end(), w);
                        if (it != seen.end() && *it == w) continue;
                        seen.insert(it, w);
                        ring.push_back(w);
                    }
                begin = end;
            }
            JetFit jf = detail::fit_jet([&](std::size_t j) -> const Vec3& { return pos[ring[j]]; }, ring.size(), degree,
                                        true);
            orient_jet(jf, vn[v]);
            return detail::curvature::to_principal(jf);
        });
    });
}

}  // namespace kintsugi
