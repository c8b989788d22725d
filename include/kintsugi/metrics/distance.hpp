// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file distance.hpp
/// @brief Surface-to-surface distances: mean, RMS, 99th percentile, Hausdorff,
/// Chamfer, F-score and normal consistency, in both directions, from exact
/// point-to-triangle distances (CGAL's AABB tree).
///
/// @code
/// kintsugi::DistanceReport r = kintsugi::compare(result, reference, {.samples = 100000});
/// auto rel = r.relative(r.a_to_b);          // divided by the reference's bbox diagonal
/// std::vector<double> d = kintsugi::distances_to_mesh(points, reference);
/// @endcode
///
/// Method: `samples` points are drawn uniformly by area on each surface (seeded;
/// identical whatever the number of threads), and each is projected exactly on the
/// other surface: a to b measures how far A strays from B (accuracy, "precision"
/// for the F-score), b to a how much of B is missed by A (completeness, "recall").
/// The F-score at threshold tau is 2PR/(P+R) (Knapitsch et al., "Tanks and Temples",
/// SIGGRAPH 2017); Chamfer is the mean of the two mean distances.

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/spatial/kd_tree.hpp>
#include <kintsugi/spatial/triangle_index.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

namespace kintsugi {

/// Parameters of compare / compare_points.
struct DistanceParams {
    /// Points sampled uniformly by area on each mesh (compare_points: on the reference only).
    std::size_t samples = 200000;
    /// Seed of the sampling; results depend only on it, not on the number of threads.
    std::uint64_t seed = 0;
    /// F-score distance threshold, as a fraction of the reference's bounding-box diagonal
    /// (1 % is the usual choice of reconstruction benchmarks).
    double fscore_threshold = 0.01;
    RunControl control{};
};

/// Distances from the samples of one surface to the other, in absolute (mesh) units.
struct DirectedDistance {
    double mean = 0;
    double rms = 0;
    double p99 = 0;        ///< 99th percentile (nearest rank) of the sample distances
    double hausdorff = 0;  ///< max over the samples and the source's vertices used by a face
    double fscore_part = 0;  ///< fraction of samples closer than the threshold (precision or recall)
};

/// What compare / compare_points measure.
struct DistanceReport {
    Status status = Status::ok;
    double diagonal = 0;  ///< bounding-box diagonal of the reference B
    DirectedDistance a_to_b, b_to_a;
    double chamfer = 0;  ///< (a_to_b.mean + b_to_a.mean) / 2, absolute
    double fscore = 0;   ///< 2 P R / (P + R) with P = a_to_b.fscore_part, R = b_to_a.fscore_part
    /// mean |n_a . n_b| between each sample's normal and the normal at its closest
    /// point, over both directions; NaN when A is a point set without normals.
    double normal_consistency = 0;
    std::size_t samples_a = 0, samples_b = 0;
    std::vector<StageTiming> timings;

    /// `d` with its lengths divided by `diagonal` (fscore_part unchanged).
    [[nodiscard]] DirectedDistance relative(const DirectedDistance& d) const {
        const double s = diagonal > 0 ? 1.0 / diagonal : 0.0;
        return {d.mean * s, d.rms * s, d.p99 * s, d.hausdorff * s, d.fscore_part};
    }
};

namespace detail {

/// Checks what every distance function needs; throws invalid_input naming `fn` and `what`.
inline void validate_distance_mesh(const IndexedMesh& m, const char* fn, const char* what) {
    validate_triangle_mesh(m, std::string(fn) + ": " + what);
}

inline void validate_points(const std::vector<Vec3>& pts, const char* fn, const char* what) {
    if (pts.empty()) throw invalid_input(std::string(fn) + ": " + what + " is empty; pass at least one point");
    for (std::size_t i = 0; i < pts.size(); ++i)
        if (!pts[i].allFinite())
            throw invalid_input(std::string(fn) + ": " + what + " has a NaN or infinite coordinate at point " +
                                std::to_string(i) + "; remove or fix it");
}

inline void validate_distance_params(const DistanceParams& p, const char* fn) {
    if (p.samples == 0) throw invalid_input(std::string(fn) + ": DistanceParams::samples is 0; use at least 1");
    if (!(p.fscore_threshold > 0) || !std::isfinite(p.fscore_threshold))
        throw invalid_input(std::string(fn) + ": DistanceParams::fscore_threshold must be a positive fraction of "
                                              "the diagonal (e.g. 0.01), got " +
                            std::to_string(p.fscore_threshold));
}

/// SplitMix64 finaliser: a counter-based generator, so sample i depends only on (seed, i).
inline std::uint64_t splitmix64(std::uint64_t z) {
    z += 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}
/// Uniform double in [0, 1) from (seed, counter).
inline double uniform01(std::uint64_t seed, std::uint64_t counter) {
    return static_cast<double>(splitmix64(seed * 0xd1342543de82ef95ULL + splitmix64(counter)) >> 11) * 0x1.0p-53;
}

struct SurfaceSamples {
    std::vector<Vec3> points;
    std::vector<Index> faces;
};

/// n points uniform by area on m (Turk 1990 / Osada et al. 2002: face by cumulative
/// area, then sqrt-warped barycentrics). Deterministic in (seed, n). @pre validated m.
inline SurfaceSamples sample_surface(const IndexedMesh& m, std::size_t n, std::uint64_t seed) {
    std::vector<double> cumulative(m.faces.size());
    double total = 0;
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
        const Face& t = m.faces[f];
        total += (m.vertices[t[1]] - m.vertices[t[0]]).cross(m.vertices[t[2]] - m.vertices[t[0]]).norm();
        cumulative[f] = total;
    }
    SurfaceSamples s;
    s.points.resize(n);
    s.faces.resize(n);
    parallel_for(0, n, [&](std::size_t i) {
        const double u0 = uniform01(seed, 3 * static_cast<std::uint64_t>(i));
        const double u1 = uniform01(seed, 3 * static_cast<std::uint64_t>(i) + 1);
        const double u2 = uniform01(seed, 3 * static_cast<std::uint64_t>(i) + 2);
        auto it = std::upper_bound(cumulative.begin(), cumulative.end(), u0 * total);
        if (it == cumulative.end()) --it;
        const Index f = static_cast<Index>(it - cumulative.begin());
        const Face& t = m.faces[f];
        const double r1 = std::sqrt(u1);
        s.points[i] = (1 - r1) * m.vertices[t[0]] + r1 * (1 - u2) * m.vertices[t[1]] + r1 * u2 * m.vertices[t[2]];
        s.faces[i] = f;
    });
    return s;
}

/// Closest points of all queries (TriangleIndex::closest_points), reporting progress
/// between blocks when `progress` is given.
inline std::vector<ClosestPoint> closest_points(const TriangleIndex& index, const std::vector<Vec3>& q,
                                                Progress* progress) {
    return index.closest_points(q, [progress](double done) {
        if (progress) progress->update(done);
    });
}

/// Unit face normals (zero for degenerate faces).
inline std::vector<Vec3> unit_face_normals(const IndexedMesh& m) {
    std::vector<Vec3> n(m.faces.size());
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
        const Face& t = m.faces[f];
        const Vec3 c = (m.vertices[t[1]] - m.vertices[t[0]]).cross(m.vertices[t[2]] - m.vertices[t[0]]);
        const double len = c.norm();
        n[f] = len > 0 ? Vec3(c / len) : Vec3::Zero();
    }
    return n;
}

/// Vertices used by a face (isolated vertices are not part of the surface).
inline std::vector<Vec3> used_vertices(const IndexedMesh& m) {
    std::vector<char> used(m.vertices.size(), 0);
    for (const Face& t : m.faces) used[t[0]] = used[t[1]] = used[t[2]] = 1;
    std::vector<Vec3> out;
    for (std::size_t v = 0; v < m.vertices.size(); ++v)
        if (used[v]) out.push_back(m.vertices[v]);
    return out;
}

/// Runs body(i) for i in [0, n) in parallel blocks, reporting progress between blocks.
template <class Body>
void blocked_parallel_for(std::size_t n, Progress& progress, Body&& body) {
    constexpr std::size_t block = 16384;
    for (std::size_t b = 0; b < n; b += block) {
        progress.update(static_cast<double>(b) / static_cast<double>(n));
        parallel_for(b, std::min(n, b + block), body, 64);
    }
}

/// Statistics of sample distances d (reordered), with extra_max from the vertices.
inline DirectedDistance summarize(std::vector<double>& d, double extra_max, double tau) {
    DirectedDistance r;
    if (d.empty()) return r;
    double sum = 0, sum2 = 0, mx = extra_max;
    std::size_t within = 0;
    for (double x : d) {
        sum += x;
        sum2 += x * x;
        mx = std::max(mx, x);
        within += x < tau;
    }
    const double n = static_cast<double>(d.size());
    r.mean = sum / n;
    r.rms = std::sqrt(sum2 / n);
    r.hausdorff = mx;
    r.fscore_part = static_cast<double>(within) / n;
    const std::size_t k = static_cast<std::size_t>(std::ceil(0.99 * n)) - 1;
    std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(k), d.end());
    r.p99 = d[k];
    return r;
}

/// Lengths of a report computed in `frame`'s local coordinates, back in world units.
inline void report_to_world(DistanceReport& r, const ScaleFrame& frame) {
    if (frame.identity()) return;
    r.diagonal = frame.to_world(r.diagonal);
    r.chamfer = frame.to_world(r.chamfer);
    for (DirectedDistance* d : {&r.a_to_b, &r.b_to_a}) {
        d->mean = frame.to_world(d->mean);
        d->rms = frame.to_world(d->rms);
        d->p99 = frame.to_world(d->p99);
        d->hausdorff = frame.to_world(d->hausdorff);
    }
}

/// An empty report against reference `b`: its diagonal (the unit of the F-score threshold) set.
inline DistanceReport report_against(const IndexedMesh& b) {
    DistanceReport r;
    BoundingBox box;
    for (const Vec3& p : b.vertices) box.extend(p);
    r.diagonal = box.diagonal();
    return r;
}

inline void finish_report(DistanceReport& r) {
    r.chamfer = (r.a_to_b.mean + r.b_to_a.mean) / 2;
    const double p = r.a_to_b.fscore_part, q = r.b_to_a.fscore_part;
    r.fscore = p + q > 0 ? 2 * p * q / (p + q) : 0.0;
}

/// compare() on the internal layout. @pre a and b validated.
inline DistanceReport compare_meshes(const IndexedMesh& a, const IndexedMesh& b, const DistanceParams& params) {
    return run_cancellable<DistanceReport>(params.control, [&](Progress& progress) {
        DistanceReport r = report_against(b);
        const double tau = params.fscore_threshold * r.diagonal;

        progress.stage("sample", 0.0, 0.05);
        const SurfaceSamples sa = sample_surface(a, params.samples, params.seed);
        const SurfaceSamples sb = sample_surface(b, params.samples, splitmix64(params.seed ^ 0x5bd1e995ULL));
        const std::vector<Vec3> va = used_vertices(a), vb = used_vertices(b);
        const std::vector<Vec3> na = unit_face_normals(a), nb = unit_face_normals(b);
        progress.check();

        progress.stage("build", 0.05, 0.2);
        const TriangleIndex ta(a), tb(b);

        auto directed = [&](const SurfaceSamples& s, const std::vector<Vec3>& verts, const std::vector<Vec3>& ns,
                            const std::vector<Vec3>& nt, const TriangleIndex& target, double& normal_sum) {
            const auto hits = closest_points(target, s.points, &progress);
            std::vector<double> d(hits.size());
            normal_sum = 0;
            for (std::size_t i = 0; i < hits.size(); ++i) {
                d[i] = hits[i].distance;
                normal_sum += std::abs(ns[s.faces[i]].dot(nt[hits[i].face]));
            }
            double vmax = 0;
            for (const auto& h : closest_points(target, verts, nullptr)) vmax = std::max(vmax, h.distance);
            return summarize(d, vmax, tau);
        };
        double nab = 0, nba = 0;
        progress.stage("a_to_b", 0.2, 0.6);
        r.a_to_b = directed(sa, va, na, nb, tb, nab);
        progress.stage("b_to_a", 0.6, 1.0);
        r.b_to_a = directed(sb, vb, nb, na, ta, nba);
        r.samples_a = sa.points.size();
        r.samples_b = sb.points.size();
        r.normal_consistency = (nab / static_cast<double>(r.samples_a) + nba / static_cast<double>(r.samples_b)) / 2;
        finish_report(r);
        r.timings = progress.finish();
        return r;
    });
}

/// compare_points() on the internal layout. @pre validated; normals empty or one per point.
inline DistanceReport compare_points_impl(const std::vector<Vec3>& pts, const std::vector<Vec3>& normals,
                                          const IndexedMesh& b, const DistanceParams& params) {
    return run_cancellable<DistanceReport>(params.control, [&](Progress& progress) {
        DistanceReport r = report_against(b);
        const double tau = params.fscore_threshold * r.diagonal;
        const bool with_normals = !normals.empty();

        progress.stage("sample", 0.0, 0.05);
        const SurfaceSamples sb = sample_surface(b, params.samples, splitmix64(params.seed ^ 0x5bd1e995ULL));
        const std::vector<Vec3> vb = used_vertices(b);
        const std::vector<Vec3> nb = unit_face_normals(b);
        std::vector<Vec3> na;
        if (with_normals) {
            na.resize(normals.size());
            for (std::size_t i = 0; i < normals.size(); ++i) {
                const double len = normals[i].norm();
                na[i] = len > 0 && std::isfinite(len) ? Vec3(normals[i] / len) : Vec3::Zero();
            }
        }
        progress.check();

        progress.stage("build", 0.05, 0.2);
        const TriangleIndex tb(b);
        const KdTree kd(pts);

        progress.stage("a_to_b", 0.2, 0.6);
        const auto hits = closest_points(tb, pts, &progress);
        std::vector<double> d(pts.size()), dots(with_normals ? pts.size() : 0);
        for (std::size_t i = 0; i < hits.size(); ++i) {
            d[i] = hits[i].distance;
            if (with_normals) dots[i] = std::abs(na[i].dot(nb[hits[i].face]));
        }
        r.a_to_b = summarize(d, 0.0, tau);

        progress.stage("b_to_a", 0.6, 1.0);
        std::vector<double> e(sb.points.size()), dots_b(with_normals ? sb.points.size() : 0);
        blocked_parallel_for(sb.points.size(), progress, [&](std::size_t i) {
            const Neighbor nn = kd.nearest(sb.points[i]);
            e[i] = std::sqrt(nn.squared_distance);
            if (with_normals) dots_b[i] = std::abs(na[nn.index].dot(nb[sb.faces[i]]));
        });
        std::vector<double> ev(vb.size());
        parallel_for(0, vb.size(), [&](std::size_t i) { ev[i] = std::sqrt(kd.nearest(vb[i]).squared_distance); });
        double vmax = 0;
        for (double x : ev) vmax = std::max(vmax, x);
        r.b_to_a = summarize(e, vmax, tau);

        r.samples_a = pts.size();
        r.samples_b = sb.points.size();
        if (with_normals) {
            double s1 = 0, s2 = 0;
            for (double x : dots) s1 += x;
            for (double x : dots_b) s2 += x;
            r.normal_consistency = (s1 / static_cast<double>(dots.size()) + s2 / static_cast<double>(dots_b.size())) / 2;
        } else {
            r.normal_consistency = std::numeric_limits<double>::quiet_NaN();
        }
        finish_report(r);
        r.timings = progress.finish();
        return r;
    });
}

}  // namespace detail

/// @brief Distances between two triangle meshes, both directions: mean, RMS, p99,
/// Hausdorff, Chamfer, F-score and normal consistency.
///
/// `params.samples` points are drawn uniformly by area on A and on B (seeded,
/// identical whatever the thread count) and projected exactly on the other mesh with
/// CGAL's AABB tree; the Hausdorff distances also include the vertices used by a face.
/// F-score as in Knapitsch et al., "Tanks and Temples", ACM TOG 2017, at
/// `fscore_threshold` x B's bounding-box diagonal. Normal consistency: mean of
/// |n_a . n_b| between a sample's face normal and the normal of the closest face.
/// Zero-area faces are never sampled nor projected on.
///
/// @tparam A a type modelling TriangleMesh (the mesh measured)
/// @tparam B a type modelling TriangleMesh (the reference)
/// @param a mesh to measure (not modified)
/// @param reference reference mesh B (not modified); lengths are in its units
/// @param params samples (>0), seed, fscore_threshold (>0, fraction of B's diagonal), control
/// @return the report. Status::ok: complete; Status::cancelled: stopped through
///   params.control, every number zero.
/// @throws invalid_input if a mesh is empty or has no faces, has a NaN/infinite
///   coordinate, a face index out of range or zero total area, or if params are out of range.
template <TriangleMesh A, TriangleMesh B>
[[nodiscard]] DistanceReport compare(const A& a, const B& reference, const DistanceParams& params = {}) {
    constexpr const char* fn = "kintsugi::compare";
    detail::validate_distance_params(params, fn);
    IndexedMesh ma = kintsugi::to_indexed_mesh(a);
    IndexedMesh mb = kintsugi::to_indexed_mesh(reference);
    if (!ma.vertices.empty() && ma.faces.empty())
        throw invalid_input(std::string(fn) + ": mesh A has no faces; use kintsugi::compare_points for a point set");
    // Any magnitude: both copies rescaled by one power of two, lengths mapped back.
    const detail::ScaleFrame frame = detail::scale_frame(ma.vertices, mb.vertices);
    frame.to_local(ma.vertices);
    frame.to_local(mb.vertices);
    detail::validate_distance_mesh(ma, fn, "mesh A");
    detail::validate_distance_mesh(mb, fn, "the reference mesh B");
    DistanceReport r = detail::compare_meshes(ma, mb, params);
    detail::report_to_world(r, frame);
    return r;
}

/// @brief Distances between a point set A and a reference triangle mesh B: A's points
/// are its samples (a to b: exact projection on B), B is sampled uniformly by area
/// (b to a: distance to the nearest point of A, through a KdTree). Same statistics
/// as compare(); normal consistency uses A's normals when it has them, NaN otherwise.
///
/// @tparam A a type modelling PointSet (normals used when OrientedPointSet and present)
/// @tparam B a type modelling TriangleMesh
/// @param a points to measure (not modified)
/// @param reference reference mesh (not modified)
/// @param params samples on B (>0), seed, fscore_threshold (>0), control
/// @return the report; Status as for compare().
/// @throws invalid_input if A is empty or has a NaN/infinite coordinate, or B is
///   invalid as for compare(), or params are out of range.
template <PointSet A, TriangleMesh B>
[[nodiscard]] DistanceReport compare_points(const A& a, const B& reference, const DistanceParams& params = {}) {
    constexpr const char* fn = "kintsugi::compare_points";
    detail::validate_distance_params(params, fn);
    std::vector<Vec3> pts = kintsugi::gather_points(a);
    const std::vector<Vec3> normals = kintsugi::gather_normals(a);
    detail::validate_points(pts, fn, "point set A");
    IndexedMesh mb = kintsugi::to_indexed_mesh(reference);
    const detail::ScaleFrame frame = detail::scale_frame(pts, mb.vertices);  // any magnitude
    frame.to_local(pts);
    frame.to_local(mb.vertices);
    detail::validate_distance_mesh(mb, fn, "the reference mesh B");
    DistanceReport r =
        detail::compare_points_impl(pts, normals.size() == pts.size() ? normals : std::vector<Vec3>{}, mb, params);
    detail::report_to_world(r, frame);
    return r;
}

/// @brief Exact unsigned distance from each point to the nearest point of the mesh
/// surface (CGAL AABB tree; zero-area faces ignored), computed in parallel.
/// @tparam P a type modelling PointSet
/// @tparam M a type modelling TriangleMesh
/// @param points query points (not modified); @param mesh the surface (not modified)
/// @return one distance per point, in mesh units (empty for an empty point set)
/// @throws invalid_input if a point or vertex is NaN/infinite, the mesh is empty,
///   has a face index out of range or zero area.
template <PointSet P, TriangleMesh M>
[[nodiscard]] std::vector<Scalar> distances_to_mesh(const P& points, const M& mesh) {
    constexpr const char* fn = "kintsugi::distances_to_mesh";
    std::vector<Vec3> pts = kintsugi::gather_points(points);
    for (std::size_t i = 0; i < pts.size(); ++i)
        if (!pts[i].allFinite())
            throw invalid_input(std::string(fn) + ": point " + std::to_string(i) +
                                " has a NaN or infinite coordinate; remove or fix it");
    IndexedMesh m = kintsugi::to_indexed_mesh(mesh);
    const detail::ScaleFrame frame = detail::scale_frame(pts, m.vertices);  // any magnitude
    frame.to_local(pts);
    frame.to_local(m.vertices);
    detail::validate_distance_mesh(m, fn, "the mesh");
    std::vector<Scalar> out(pts.size());
    if (pts.empty()) return out;
    const TriangleIndex tree(m);
    const auto hits = detail::closest_points(tree, pts, nullptr);
    for (std::size_t i = 0; i < pts.size(); ++i) out[i] = frame.to_world(hits[i].distance);
    return out;
}

}  // namespace kintsugi
