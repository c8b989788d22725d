// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file estimate_normals.hpp
/// @brief Normal estimation (PCA or jet fitting over k nearest neighbours) and
/// consistent orientation (minimum spanning tree), on any point container.
///
/// @code
/// std::vector<Eigen::Vector3d> pts = ..., nrm;
/// auto view = kintsugi::with_normals(pts, nrm);          // normals are written here
/// auto r = kintsugi::estimate_normals(view, {.k = 18, .method = kintsugi::NormalMethod::jet});
/// // r.components: kNN-graph components, each oriented outward-by-its-top-point
/// @endcode
///
/// Neighbours: one n×(k+1) table from kintsugi::KdTree (or the caller's SpatialIndex),
/// shared by fitting and orientation. PCA as CGAL's pca_estimate_normals (same fit, same
/// neighbourhoods); jet as CGAL's Monge_via_jet_fitting, solved with Eigen's QR; the
/// orientation orients every kNN-graph component (CGAL's mst_orient_normals orients only
/// the seed's). Why, and the timings against CGAL: docs/methods/normals.md.
/// Licence: this header uses Eigen, Boost.Graph and nanoflann only (no GPL code).
///
/// Deterministic: the output is bit-identical whatever the thread count.

#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>
#include <kintsugi/core/spread.hpp>
#include <kintsugi/normals/detail/estimate_normals_impl.hpp>
#include <kintsugi/spatial/kd_tree.hpp>

#include <cstddef>
#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace kintsugi {

/// How a normal is fitted to a point's k nearest neighbours.
enum class NormalMethod {
    pca,  ///< least-squares plane (smallest covariance eigenvector); fast, smooths sharp edges
    jet,  ///< degree-2 jet (osculating quadric), Cazals & Pouget 2005; better on curved parts, k >= 5
};

/// Parameters of estimate_normals / orient_normals.
struct NormalParams {
    /// Neighbourhood size: each normal is fitted to the point and its k nearest
    /// other points (CGAL's convention; fewer when the set has only k points).
    /// Range [3, number of points] ([5, n] for jet, whose quadric needs 6 points).
    /// 18 is CGAL's documented example value and works on scans of ~1e4–1e6 points.
    std::size_t k = 18;
    NormalMethod method = NormalMethod::pca;
    /// Orient the normals consistently (MST propagation) after fitting them.
    bool orient = true;
    RunControl control{};
};

/// Outcome of estimate_normals / orient_normals.
struct NormalResult {
    Status status = Status::ok;
    std::size_t points = 0;      ///< points processed
    std::size_t components = 0;  ///< kNN-graph components oriented (0 when not oriented)
    std::vector<StageTiming> timings;  ///< "kd-tree", "neighbours", "fit", "orient"
};

namespace detail::normals {

inline void validate_common(const char* fn, std::size_t n, std::size_t k, std::size_t min_k) {
    if (n == 0) throw invalid_input(std::string(fn) + ": the point set is empty; pass at least 3 points");
    if (n < 3)
        throw invalid_input(std::string(fn) + ": the point set has " + std::to_string(n) +
                            " points; at least 3 are needed to fit a normal");
    if (n >= std::numeric_limits<NodeIndex>::max())
        throw invalid_input(std::string(fn) + ": " + std::to_string(n) + " points is more than supported (2^32 - 1)");
    if (k < min_k || k > n)
        throw invalid_input(std::string(fn) + ": params.k = " + std::to_string(k) + " is out of range; it must be in [" +
                            std::to_string(min_k) + ", " + std::to_string(n) +
                            "] (the number of neighbours of each point, at most the number of points)");
}

template <class P>
void write_normals(P& points, const std::vector<Vec3>& normals) {
    if constexpr (requires { point_set_traits<P>::prepare_normals(points); })
        point_set_traits<P>::prepare_normals(points);
    for (std::size_t i = 0; i < normals.size(); ++i) point_set_traits<P>::set_normal(points, i, normals[i]);
}

/// The positions of `points`, checked finite (invalid_input naming `fn` otherwise).
template <class P>
std::vector<Vec3> checked_positions(const char* fn, const P& points) {
    std::vector<Vec3> pts = kintsugi::gather_points(points);
    check_finite_points(pts, std::string(fn) + ": point ");
    return pts;
}

/// estimate_normals' checks, in order; returns the positions in the caller's frame.
template <class P>
std::vector<Vec3> estimate_input(const char* fn, const P& points, const NormalParams& params) {
    if (params.method != NormalMethod::pca && params.method != NormalMethod::jet)
        throw invalid_input(std::string(fn) + ": params.method is not a NormalMethod (pca or jet)");
    const bool jet = params.method == NormalMethod::jet;
    const std::size_t n = kintsugi::num_points(points);
    validate_common(fn, n, params.k, 3);
    if (jet && params.k < 5)
        throw invalid_input(std::string(fn) + ": params.k = " + std::to_string(params.k) +
                            " is too small for jet fitting, which needs k >= 5 (the point and 5 neighbours "
                            "for the quadric's 6 coefficients)");
    if (jet && n < 6)
        throw invalid_input(std::string(fn) + ": the point set has " + std::to_string(n) +
                            " points; jet fitting needs at least 6");
    std::vector<Vec3> pts = checked_positions(fn, points);
    // Points at one place or on one line have no normal (every direction across the line
    // fits); a plane's is its normal.
    (void)require_spread_off_a_line(pts, std::string(fn) + ": ", "a normal needs points spread over a surface");
    return pts;
}

/// A KdTree over `pts` (stage "kd-tree", [0, a)) and each point's `k` nearest (stage
/// "neighbours", [a, b)); returns then(positions, table).
template <class Then>
auto with_own_neighbours(std::vector<Vec3>&& pts, std::size_t k, double a, double b, Progress& progress,
                         Then&& then) {
    progress.stage("kd-tree", 0.0, a);
    const auto tree = KdTree::adopt(std::move(pts));
    progress.stage("neighbours", a, b);
    return then(tree.points(), knn_table(tree, tree.points(), k, progress));
}

/// The stages after "neighbours": fit (from `a`), orient when asked, then the normals
/// written into `points`. `pts` in the local frame, `table` over them.
template <class P>
NormalResult fit_orient_write(P& points, const std::vector<Vec3>& pts, const KnnTable& table,
                              const NormalParams& params, double a, Progress& progress) {
    NormalResult result;
    progress.stage("fit", a, params.orient ? 0.8 : 1.0);
    std::vector<Vec3> normals = fit_normals(pts, table, params.method == NormalMethod::jet, progress);
    if (params.orient) {
        progress.stage("orient", 0.8, 1.0);
        result.components = orient_mst(pts, table, normals, progress);
    }
    result.timings = progress.finish();
    write_normals(points, normals);
    return result;
}

}  // namespace detail::normals

/// @brief Estimates a unit normal at every point from its k nearest neighbours,
/// by PCA (plane fit) or jet fitting (Cazals & Pouget, "Estimating differential
/// quantities using polynomial fitting of osculating jets", SGP 2003 / CAGD 2005),
/// then, when `params.orient`, orients them consistently by minimum-spanning-tree
/// propagation (Hoppe, DeRose, Duchamp, McDonald, Stuetzle, "Surface reconstruction
/// from unorganized points", SIGGRAPH 1992), every kNN-graph component seeded by
/// its top-most point turned towards +z (outward for closed shapes).
///
/// @tparam P a NormalWritablePointSet (std::vector + with_normals, PointCloud,
///         CGAL::Point_set_3, eigen_points(P, N), project_points with a writable normal).
///         point_set_traits<P>::prepare_normals is called first when it exists.
/// @param points the point set; positions in any unit; its normals are overwritten
///        with unit vectors on success.
/// @param params k (neighbours of each point, itself not counted), method, orient, control.
/// @pre at least 3 points (6 for jet); k in [3, n] for PCA, [5, n] for jet; finite coordinates.
/// @throws invalid_input for an empty set, fewer than 3 points, k out of range, a
///         NaN/Inf coordinate, or an unknown method; the input is untouched.
/// @return status ok: normals written; cancelled (progress callback returned
///         false or stop requested): the point set, normals included, is untouched.
template <NormalWritablePointSet P>
NormalResult estimate_normals(P& points, const NormalParams& params = {}) {
    std::vector<Vec3> pts = detail::normals::estimate_input("kintsugi::estimate_normals", points, params);
    const std::size_t n = pts.size();
    detail::scale_frame(pts).to_local(pts);  // any magnitude: exact power-of-two rescaling
    NormalResult result = detail::run_cancellable<NormalResult>(params.control, [&](detail::Progress& progress) {
        return detail::normals::with_own_neighbours(
            std::move(pts), std::min(params.k + 1, n), 0.1, 0.4, progress,
            [&](const std::vector<Vec3>& local, const detail::normals::KnnTable& table) {
                return detail::normals::fit_orient_write(points, local, table, params, 0.4, progress);
            });
    });
    result.points = n;
    return result;
}

/// @brief estimate_normals() over a spatial index the caller already holds (a KdTree, a
/// UniformGrid or any type of theirs modelling SpatialIndex): no tree is built. The
/// normals are those estimate_normals(points, params) gives, bit for bit, whatever the
/// index, since every SpatialIndex returns the same neighbours in the same order.
///
/// @tparam P as estimate_normals(points, params).
/// @tparam S a SpatialIndex over the positions of `points`, same numbering (point i of
///         the index is point i of `points`), in the points' own coordinates; its const
///         knn() is called from several threads at once.
/// @param index  the index; not modified.
/// @param params as estimate_normals(points, params); the stages are "neighbours", "fit",
///        "orient" (no "kd-tree").
/// @throws invalid_input as estimate_normals(points, params), and when index.size()
///         differs from the number of points or a query returns fewer than k + 1
///         neighbours or an index out of range; the input is untouched.
/// @return as estimate_normals(points, params).
template <NormalWritablePointSet P, SpatialIndex S>
NormalResult estimate_normals(P& points, const S& index, const NormalParams& params = {}) {
    constexpr const char* fn = "kintsugi::estimate_normals";
    const std::vector<Vec3> world = detail::normals::estimate_input(fn, points, params);
    const std::size_t n = world.size();
    if (static_cast<std::size_t>(index.size()) != n)
        throw invalid_input(std::string(fn) + ": the spatial index holds " + std::to_string(index.size()) +
                            " points and the point set " + std::to_string(n) +
                            "; build the index over the same points");
    NormalResult result = detail::run_cancellable<NormalResult>(params.control, [&](detail::Progress& progress) {
        progress.stage("neighbours", 0.0, 0.4);
        const auto table = detail::normals::knn_table(index, world, std::min(params.k + 1, n), progress, fn);
        std::vector<Vec3> local = world;
        detail::scale_frame(local).to_local(local);  // as estimate_normals(points, params) fits
        return detail::normals::fit_orient_write(points, local, table, params, 0.4, progress);
    });
    result.points = n;
    return result;
}

/// @brief Orients existing normals consistently, keeping their directions and
/// changing signs only: minimum-spanning-tree propagation over the k-nearest-
/// neighbour graph weighted 1 - |ni·nj| (Hoppe et al., SIGGRAPH 1992), every
/// component seeded by its top-most point turned towards +z.
///
/// @tparam P a NormalWritablePointSet that also stores normals (OrientedPointSet).
/// @param points the point set; normals of any length, non-zero and finite; the
///        flipped ones are rewritten as their negation.
/// @param params k (graph neighbours of each point, itself not counted) and control;
///        method and orient are ignored.
/// @pre at least 3 points, k in [3, n], finite coordinates and normals, normals present.
/// @throws invalid_input for an empty set, fewer than 3 points, k out of range, a
///         NaN/Inf coordinate, missing normals, or a zero or non-finite normal.
/// @return status ok: signs fixed; cancelled: the point set is untouched.
template <NormalWritablePointSet P>
    requires OrientedPointSet<P>
NormalResult orient_normals(P& points, const NormalParams& params = {}) {
    constexpr const char* fn = "kintsugi::orient_normals";
    const std::size_t n = kintsugi::num_points(points);
    detail::normals::validate_common(fn, n, params.k, 3);
    if (!kintsugi::has_normals(points))
        throw invalid_input(std::string(fn) + ": the point set has no normals; call kintsugi::estimate_normals instead");
    std::vector<Vec3> pts = detail::normals::checked_positions(fn, points);
    detail::scale_frame(pts).to_local(pts);  // any magnitude: exact power-of-two rescaling
    std::vector<Vec3> normals = kintsugi::gather_normals(points);
    for (std::size_t i = 0; i < n; ++i)
        if (!normals[i].allFinite() || normals[i].squaredNorm() == 0)
            throw invalid_input(std::string(fn) + ": normal " + std::to_string(i) +
                                " is zero, NaN or infinite; estimate normals first or remove the point");

    NormalResult result = detail::run_cancellable<NormalResult>(params.control, [&](detail::Progress& progress) {
        return detail::normals::with_own_neighbours(
            std::move(pts), std::min(params.k + 1, n), 0.2, 0.6, progress,
            [&](const std::vector<Vec3>& local, const detail::normals::KnnTable& table) {
                progress.stage("orient", 0.6, 1.0);
                // Orientation weights use unit directions; the written normals keep their length.
                std::vector<Vec3> unit(n);
                for (std::size_t i = 0; i < n; ++i) unit[i] = normals[i].normalized();
                NormalResult r;
                r.components = detail::normals::orient_mst(local, table, unit, progress);
                r.timings = progress.finish();
                for (std::size_t i = 0; i < n; ++i)
                    if (unit[i].dot(normals[i]) < 0) point_set_traits<P>::set_normal(points, i, -normals[i]);
                return r;
            });
    });
    result.points = n;
    return result;
}

}  // namespace kintsugi
