// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file impulses.hpp
/// @brief `remove_impulses`: finds the vertices impulsive noise moved far off the surface
/// (a few vertices displaced, the others left in place) and puts them back onto the
/// surface their neighbours describe; leaves meshes without such noise untouched.
///
/// @code
/// kintsugi::ImpulseResult r = kintsugi::remove_impulses(mesh);
/// // r.impulsive: the heights were heavy-tailed; r.moved_vertices: how many were put back
/// @endcode
///
/// ## Method
/// A vertex's **height** is the least distance from it to the plane of three consecutive
/// neighbours (for every interior edge (v, b), b and the two vertices opposite it). A vertex
/// on a crease or at a box corner lies in the plane of the neighbours on one of its sides,
/// so its height is near zero, while an impulse lifts a vertex above every such plane; and
/// the least height ignores a moved neighbour as long as one side is free of them.
/// - **Gate.** Gaussian-like noise gives heights whose 99th percentile is at most 5–12 times
///   their median (measured on nine shapes at 0.1–0.8|e| and on the clean meshes); 10 % of
///   the vertices moved by σ = |e| give 21–126 times. The stage runs only when the 99th
///   percentile exceeds `gate` (15) times the median, the median taken at least as
///   `floor` (0.01) times the mean edge length so that exact planes (median 0) need real
///   spikes to pass.
/// - **Flags and repair**, in up to `passes` (3) passes: the vertices whose height exceeds
///   `threshold` (6) times that median are flagged (on a mesh of exact planes, median under the
///   floor, also 6 times the median of their neighbours' heights, so that a clean curved strip
///   between planes is not taken for impulses; a few vertices on its border still can be, up to
///   38 of 14K moved by at most 0.8|e| in a test with a half-cylinder on a plate), and each
///   flagged vertex is put at the
///   height, at its place (at its ring's mean when it lies over two edge lengths outside the
///   points' footprint), of a quadric z = q(x, y) fitted to the unflagged vertices within
///   two rings (in the frame of their least-variance direction, which a flagged neighbour
///   cannot tilt; iteratively reweighted with Tukey's biweight, so that moved vertices under
///   the threshold lose their weight; a plane with fewer than 9 points). Then the heights of
///   the unflagged vertices are taken again, the median from them (it falls once the
///   impulses that inflated it are back), and impulses masked by a moved neighbour show.
/// - **Spikes** (detail::impulses::SpikeConstants), before the gate: a few vertices far off the
///   surface, whose height exceeds 10 median edge lengths and 200 times the median height (or,
///   moved nearly along the surface, whose every edge exceeds 10 median edge lengths and which
///   lie off their neighbours' mean by over 0.8 of the shortest), and which stand out from their
///   ring (height or shortest edge over 3 times its radius), are put back onto the robust
///   quadric at their neighbours' mean (`spike_vertices`), however few they are; the gate and the
///   rest then read the repaired mesh. A needle tip meshed with edges over 10 median edge lengths
///   would read as one.
/// - **Dense noise.** The method assumes most vertices are in place. When more than
///   `max_fraction` (0.2) of the vertices are flagged, nothing is put back (`dense`): with a
///   third of the vertices moved the fits are too contaminated (measured in
///   docs/methods/feature_bilateral.md).
/// - **Unmoved vertices.** Vertices left within `keep` (2) times the median of a plane of
///   three neighbours are reported as unmoved (`unmoved_vertices`;
///   smooth_feature_bilateral holds them in place). When a mesh of exact planes comes with
///   held vertices (smooth_feature_bilateral's coplanar stage), nothing is put back: the held
///   corners already do better there.
/// - **Impulses on top of Gaussian noise.** The vertices taken as unmoved then carry the
///   Gaussian noise, and holding them would keep it (10 % × |e| plus 0.1|e| Gaussian: bunny.off
///   11.2° held, 8.2° not). smooth_feature_bilateral holds them only when the repaired mesh does
///   not read as Gaussian noise (its umbrella differences under 0.1|e| and under 1/1.35 of
///   the quadric fits' reading, or heavy-tailed; docs/methods/feature_bilateral.md, "Impulses
///   on top of Gaussian noise").
///
/// A switching filter in the sense of image processing's switching median filters: only
/// the detected impulses change. Vertex pre-filtering against impulsive noise before normal
/// filtering is the approach of X. Lu, Z. Deng, W. Chen, "A robust scheme for feature-preserving
/// mesh denoising", IEEE TVCG 22(3), 2016. Measurements: docs/methods/feature_bilateral.md
/// ("Impulse removal").
///
/// Cost: linear in the mesh (a pass over the edges and a median per pass, a fit of at most
/// 256 points per flagged vertex; the spikes: a median of the edge lengths and up to three
/// passes over the vertices' rings), parallel; the result does not depend on the thread count.

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/mesh/vertex_subset.hpp>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace kintsugi {

/// Parameters of remove_impulses (aggregate; field order is API, append only).
struct ImpulseParams {
    /// Gate: the stage runs when the 99th percentile of the heights exceeds this many times
    /// their median; > 1, default 15 (Gaussian noise and clean meshes measured 5–12,
    /// impulsive noise 21–126).
    Scalar gate = 15;
    /// A vertex is put back when its height exceeds this many times the median; > 0,
    /// default 6 (about 1 % of the vertices under Gaussian noise; an impulse of σ = |e|
    /// passes unless it moved by less than ~0.2|e|).
    Scalar threshold = 6;
    /// Least median, as a fraction of the mean edge length; ≥ 0, default 0.01 (exact planes
    /// have median height 0, where any rounding would otherwise pass the gate).
    Scalar floor = 0.01;
    /// Detection passes, 1–100, default 3: each flags the vertices above the threshold among
    /// those not yet flagged (an impulse next to another shows once that one is back) and
    /// repairs all flagged ones.
    std::size_t passes = 3;
    /// Most flagged vertices, as a fraction of all; in (0, 1], default 0.2 (a tenth of the
    /// vertices moved flags 8–17 %, a third 12–46 %; above it, nothing is put back).
    Scalar max_fraction = 0.2;
    /// Unflagged vertices within this many times the median of a plane of three neighbours
    /// are reported unmoved; ≥ 0, default 2.
    Scalar keep = 2;
    RunControl control{};
};

/// What remove_impulses did.
struct ImpulseResult {
    Status status = Status::ok;
    /// The heights were heavy-tailed (the gate passed); vertices were put back unless `dense`,
    /// no vertex stood out, or the mesh is of exact planes whose unmoved vertices the caller holds.
    bool impulsive = false;
    /// Vertices put back (0 when the gate did not pass or `dense`).
    std::size_t moved_vertices = 0;
    /// More than max_fraction of the vertices were flagged: nothing was put back by the gated stage
    /// (spikes may have been: `spike_vertices`).
    bool dense = false;
    /// Vertices taken as unmoved (see ImpulseParams::keep; 0 unless vertices were put back).
    std::size_t unmoved_vertices = 0;
    /// Median and 99th percentile of the heights, in mesh units.
    Scalar median_height = 0;
    Scalar high_height = 0;
    std::vector<StageTiming> timings;  ///< "impulses"
    /// Spikes put back before the gate (a few vertices far off the surface; see the file comment).
    std::size_t spike_vertices = 0;
};

namespace detail::impulses {

/// The least height of v above the plane of three consecutive neighbours (-1: none).
inline Scalar height(const std::vector<Vec3>& p, const std::vector<Face>& faces, const MeshTopology& topo,
                     Index v, Scalar min_area2) {
    Scalar best = -1;
    const auto nb = topo.vertex_neighbors(v);
    const auto ed = topo.vertex_edges(v);
    for (std::size_t i = 0; i < nb.size(); ++i) {
        const auto ef = topo.edge_faces(ed[i]);
        if (ef.size() != 2) continue;
        const Index b = nb[i];
        Index op[2];
        for (int k = 0; k < 2; ++k) {
            const Face& f = faces[ef[k]];
            op[k] = f[0] != v && f[0] != b ? f[0] : f[1] != v && f[1] != b ? f[1] : f[2];
        }
        const Vec3 n = (p[b] - p[op[0]]).cross(p[op[1]] - p[op[0]]);
        const Scalar n2 = n.squaredNorm();
        // A thin triangle's plane can turn about its long side, through v: only triples
        // whose height is at least a fifth of their longest side (|n| = 2 area).
        const Scalar longest2 = std::max({(p[b] - p[op[0]]).squaredNorm(), (p[op[1]] - p[op[0]]).squaredNorm(),
                                          (p[op[1]] - p[b]).squaredNorm()});
        if (!(n2 > min_area2) || !(n2 > 0.04 * longest2 * longest2)) continue;
        const Scalar h = std::abs(n.dot(p[v] - p[op[0]])) / std::sqrt(n2);
        if (best < 0 || h < best) best = h;
    }
    return best;
}

/// The k-th smallest of `x` (a copy: the caller's order is kept).
inline Scalar quantile(std::vector<Scalar> x, double q) {
    const auto k = static_cast<std::size_t>(q * static_cast<double>(x.size() - 1));
    std::nth_element(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(k), x.end());
    return x[k];
}

/// The least |cross|² of the triples height() takes: an area of 0.005|e|² for mean edge length L.
inline Scalar height_min_area2(Scalar L) { return 1e-4 * L * L * L * L; }

/// Every vertex's height (-1: none; `L` the edge length the least triple area is taken from),
/// and in `defined` those that are defined, in vertex order.
inline std::vector<Scalar> heights(const std::vector<Vec3>& p, const std::vector<Face>& faces, const MeshTopology& topo,
                                   Scalar L, std::vector<Scalar>& defined) {
    const std::size_t n = p.size();
    const Scalar min_area2 = height_min_area2(L);
    std::vector<Scalar> h(n, -1);
    parallel_for(0, n, [&](std::size_t v) { h[v] = height(p, faces, topo, static_cast<Index>(v), min_area2); }, 1024);
    defined.clear();
    defined.reserve(n);
    for (Scalar x : h)
        if (x >= 0) defined.push_back(x);
    return h;
}

/// Every vertex's height (-1: none), and the gate on them: with at least 20 heights defined,
/// r.median_height and r.high_height (the 99th percentile), and r.impulsive when the latter
/// exceeds params.gate times the former (taken at least as params.floor · L). `L` is the mean
/// edge length. Shared by run() and the untangling stage (mesh/untangle.hpp), which leaves
/// impulsive noise to run().
inline std::vector<Scalar> gate_heights(const std::vector<Vec3>& p, const std::vector<Face>& faces,
                                        const MeshTopology& topo, Scalar L, const ImpulseParams& params,
                                        ImpulseResult& r) {
    std::vector<Scalar> defined;
    std::vector<Scalar> h = heights(p, faces, topo, L, defined);
    if (defined.size() < 20) return h;  // too few for a percentile
    r.median_height = quantile(defined, 0.5);
    r.high_height = quantile(defined, 0.99);
    r.impulsive = r.high_height > params.gate * std::max(r.median_height, params.floor * L);
    return h;
}

/// The repaired position of v: the height at v of a quadric z = q(x, y) fitted to the
/// unflagged vertices within two rings (at most 64 neighbours per ring vertex, evenly
/// strided, and 256 points, so a hub costs a bounded amount), in the frame of their
/// least-variance direction (a plane with fewer than 9 points, v unchanged with fewer than 3).
/// `L` is the mean edge length (the fit's unit). With `at_centroid` the quadric is evaluated not
/// at v's place but at the mean of its unflagged one-ring (of the fit's points if none), which
/// puts back a vertex moved along the surface too (spikes: put_back_spikes).
inline Vec3 repaired_position(const std::vector<Vec3>& p, const MeshTopology& topo,
                              const std::vector<unsigned char>& is_flagged, Scalar L, Index v,
                              bool at_centroid = false) {
    thread_local std::vector<Index> candidates;
    candidates.clear();
    const auto nb = topo.vertex_neighbors(v);
    const std::size_t step = std::max<std::size_t>(1, nb.size() / 64);
    for (std::size_t i = 0; i < nb.size(); i += step) {
        candidates.push_back(nb[i]);
        const auto nb2 = topo.vertex_neighbors(nb[i]);
        const std::size_t step2 = std::max<std::size_t>(1, nb2.size() / 64);
        for (std::size_t k = 0; k < nb2.size(); k += step2) candidates.push_back(nb2[k]);
    }
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    candidates.erase(std::remove_if(candidates.begin(), candidates.end(),
                                    [&](Index u) { return u == v || is_flagged[u]; }),
                     candidates.end());
    Index pts[256];
    const std::size_t m = std::min<std::size_t>(candidates.size(), 256);
    for (std::size_t k = 0; k < m; ++k) pts[k] = candidates[k * candidates.size() / m];
    if (m < 3) return p[v];
    // The frame: the least-variance direction of the points (their plane), which a
    // flagged neighbour cannot tilt as it tilts the ring normal.
    Vec3 c = Vec3::Zero();
    for (std::size_t k = 0; k < m; ++k) c += p[pts[k]];
    c /= static_cast<Scalar>(m);
    Eigen::Matrix<Scalar, 3, 3> C = Eigen::Matrix<Scalar, 3, 3>::Zero();
    for (std::size_t k = 0; k < m; ++k) {
        const Vec3 d = (p[pts[k]] - c) / L;
        C += d * d.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<Scalar, 3, 3>> eig(C);
    const Vec3 nz = eig.eigenvectors().col(0);
    const Vec3 tx = eig.eigenvectors().col(2);
    const Vec3 ty = nz.cross(tx);
    const bool quadric = m >= 9;
    Vec3 o = p[v];  // where the quadric is evaluated
    if (!at_centroid) {
        // v's place over two edge lengths outside the points' footprint in their plane (moved
        // along the surface as well; a border vertex lies at the footprint's edge): the quadric
        // would be extrapolated there, so it is evaluated at the ring's mean.
        auto planar = [&](const Vec3& d) { return (d - d.dot(nz) * nz).norm(); };
        Scalar reach = 0;
        for (std::size_t k = 0; k < m; ++k) reach = std::max(reach, planar(p[pts[k]] - c));
        at_centroid = planar(p[v] - c) > reach + 2 * L;
    }
    if (at_centroid) {
        o = Vec3::Zero();
        std::size_t k = 0;
        for (Index u : topo.vertex_neighbors(v))
            if (!is_flagged[u]) o += p[u], ++k;
        o = k > 0 ? Vec3(o / static_cast<Scalar>(k)) : c;
    }
    Scalar zs[256];
    Eigen::Matrix<Scalar, 6, 1> rows[256];
    for (std::size_t k = 0; k < m; ++k) {
        const Vec3 d = (p[pts[k]] - o) / L;  // in edge lengths: a well-scaled system
        const Scalar x = tx.dot(d), y = ty.dot(d);
        zs[k] = nz.dot(d);
        rows[k] << 1, x, y, quadric ? x * x : 0, quadric ? x * y : 0, quadric ? y * y : 0;
    }
    // Iteratively reweighted least squares with Tukey's biweight (c = 4.685 robust
    // standard deviations of the residuals): unflagged neighbours the noise moved too
    // (impulses under the threshold, or dense impulses) lose their weight.
    Scalar w[256];
    std::fill(w, w + m, Scalar(1));
    Eigen::Matrix<Scalar, 6, 1> q = Eigen::Matrix<Scalar, 6, 1>::Zero();
    for (int iter = 0; iter < 6; ++iter) {
        Eigen::Matrix<Scalar, 6, 6> A = Eigen::Matrix<Scalar, 6, 6>::Zero();
        Eigen::Matrix<Scalar, 6, 1> rhs = Eigen::Matrix<Scalar, 6, 1>::Zero();
        Scalar total = 0;
        for (std::size_t k = 0; k < m; ++k) {
            A += w[k] * rows[k] * rows[k].transpose();
            rhs += w[k] * zs[k] * rows[k];
            total += w[k];
        }
        if (!quadric)
            for (int k = 3; k < 6; ++k) A(k, k) += 1;
        if (!(total > 0)) break;
        const Eigen::LDLT<Eigen::Matrix<Scalar, 6, 6>> ldlt(A);
        if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-8)) {
            if (iter == 0) return at_centroid ? o : p[v];
            break;
        }
        q = ldlt.solve(rhs);
        Scalar res[256];
        for (std::size_t k = 0; k < m; ++k) res[k] = std::abs(zs[k] - rows[k].dot(q));
        std::nth_element(res, res + m / 2, res + m);
        const Scalar c = 4.685 * std::max<Scalar>(1.4826 * res[m / 2], 0.01);
        for (std::size_t k = 0; k < m; ++k) {
            const Scalar u = (zs[k] - rows[k].dot(q)) / c;
            w[k] = std::abs(u) < 1 ? (1 - u * u) * (1 - u * u) : 0;
        }
    }
    return o + q[0] * L * nz;
}

/// Spikes: a few vertices far off the surface (a scanner's stray samples, a file's corrupted
/// rows), too few for the gate's 99th percentile to see them. A vertex is one when its height
/// exceeds both `edges` times the median edge length and `ratio` times the median height (taken
/// at least as ImpulseParams::floor median edge lengths), or by `off_centre` below, and stands
/// out from its ring (`local`). Without the repair a feature-aware filter keeps such a vertex as a
/// cone tip and a linear one spreads it: the npm bunny with one
/// vertex moved 50|e| came out with the spike in place and its neighbours dragged 13.6|e| (at
/// 10⁴|e|: 1,598|e|). The bounds sit twice above the largest heights measured without spikes,
/// 4.96|e| and 104.5 times the median (the RealData angel clean and with noise; 61 meshes of
/// ../shared/data, and 32 shapes at 0.1-1.2|e| along the normals and 0.3-1.0|e| in random
/// directions; docs/methods/
/// feature_bilateral.md, "Spikes"). Lengths are medians, as the mean edge length of a mesh
/// with spikes is theirs (20 spikes of 10⁴|e| on 1,839 vertices: 218 times the mesh's).
struct SpikeConstants {
    static constexpr Scalar edges = 10, ratio = 200;
    /// A vertex moved nearly along the surface keeps a low height; it is a spike too when every
    /// edge at it is over `edges` median edge lengths and it lies over `off_centre` times its
    /// shortest edge from its neighbours' mean (a spike at distance D from a ring of radius r:
    /// about D / (D − r) ≥ 1; a vertex amid its ring 0, on a border about 0.5).
    static constexpr Scalar off_centre = 0.8;
    /// Either way the vertex must stand out from its own ring too: its height (or its shortest
    /// edge) over `local` times the ring's radius (ring_radius, without the other candidates: two
    /// spikes side by side). A spike D off a ring of radius r reads D / r ≥ 10; a coarse part's corner beside
    /// finer ones reads about 1 or less (a 12-triangle cube's corner: height 0.58 s against a radius
    /// of about 0.8 s; a box corner fanned to a finely meshed face), and is left alone.
    static constexpr Scalar local = 3;
};

/// The radius of v's ring: the largest distance of a neighbour from the neighbours' mean, over
/// the neighbours `skip` does not exclude (at most 64, evenly strided: a hub costs a bounded
/// amount); 0 without any.
template <class Skip>
Scalar ring_radius(const std::vector<Vec3>& p, const MeshTopology& topo, Index v, const Skip& skip) {
    const auto nb = topo.vertex_neighbors(v);
    const std::size_t step = std::max<std::size_t>(1, nb.size() / 64);
    Vec3 mean = Vec3::Zero();
    std::size_t k = 0;
    for (std::size_t i = 0; i < nb.size(); i += step)
        if (!skip(nb[i])) mean += p[nb[i]], ++k;
    if (k == 0) return 0;
    mean /= static_cast<Scalar>(k);
    Scalar r = 0;
    for (std::size_t i = 0; i < nb.size(); i += step)
        if (!skip(nb[i])) r = std::max(r, (p[nb[i]] - mean).norm());
    return r;
}

/// The median edge length over the edges of `topo` (0 without edges).
inline Scalar median_edge_length(const std::vector<Vec3>& p, const MeshTopology& topo) {
    std::vector<Scalar> len;
    len.reserve(topo.edges().size());
    for (const auto& e : topo.edges()) len.push_back((p[e[0]] - p[e[1]]).norm());
    return len.empty() ? Scalar(0) : quantile(std::move(len), 0.5);
}

/// Puts the spikes (SpikeConstants) back where a robust quadric through their unflagged two-ring
/// puts them (repaired_position), in up to the default ImpulseParams::passes (3; a spike next to another
/// shows once that one is back); returns the vertices moved, sorted. Nothing moves when more than
/// the default ImpulseParams::max_fraction (0.2) of the vertices would (not a few stray vertices: a surface this
/// stage cannot read) or with fewer than 20 heights defined. Linear in the mesh, parallel,
/// independent of the thread count.
inline std::vector<Index> put_back_spikes(std::vector<Vec3>& p, const std::vector<Face>& faces, const MeshTopology& topo,
                                          Progress& progress) {
    using K = SpikeConstants;
    const ImpulseParams defaults;
    const std::size_t n = p.size();
    const Scalar Le = median_edge_length(p, topo);
    if (!(Le > 0)) return {};
    const Scalar min_area2 = height_min_area2(Le);
    std::vector<Scalar> defined;
    std::vector<Scalar> h = heights(p, faces, topo, Le, defined);
    if (defined.size() < 20) return {};
    const Scalar bound = std::max(K::edges * Le, K::ratio * std::max(quantile(std::move(defined), 0.5), defaults.floor * Le));
    progress.check();
    std::vector<unsigned char> is_flagged(n, 0);
    std::vector<Index> flagged;
    std::vector<Vec3> input, next;
    for (std::size_t pass = 0; pass < defaults.passes; ++pass) {
        if (pass > 0)
            parallel_for(0, n, [&](std::size_t v) {
                if (!is_flagged[v]) h[v] = height(p, faces, topo, static_cast<Index>(v), min_area2);
            }, 1024);
        // Candidates: far above the planes of their neighbours, or far off them in every direction
        // (every edge long, the vertex off their mean).
        std::vector<unsigned char> candidate(n, 0);
        std::vector<Scalar> shortest(n, 0);
        parallel_for(0, n, [&](std::size_t v) {
            if (is_flagged[v]) return;
            const auto nb = topo.vertex_neighbors(static_cast<Index>(v));
            if (nb.size() < 3) return;
            Scalar s_min = std::numeric_limits<Scalar>::infinity();
            Vec3 mean = Vec3::Zero();
            for (Index u : nb) {
                s_min = std::min(s_min, (p[u] - p[v]).norm());
                mean += p[u];
            }
            mean /= static_cast<Scalar>(nb.size());
            shortest[v] = s_min;
            const bool stray = s_min > K::edges * Le && (p[v] - mean).norm() > K::off_centre * s_min;
            candidate[v] = h[v] > bound ? 1 : stray ? 2 : 0;
        }, 1024);
        // Flagged when it stands out from its ring too, the ring taken without other candidates
        // (two spikes side by side) and flagged vertices.
        std::size_t added = 0;
        for (std::size_t v = 0; v < n; ++v) {
            if (!candidate[v]) continue;
            const Scalar r = ring_radius(p, topo, static_cast<Index>(v),
                                         [&](Index u) { return candidate[u] != 0 || is_flagged[u] != 0; });
            const Scalar x = candidate[v] == 1 ? h[v] : shortest[v];
            if (!(x > K::local * r)) continue;
            is_flagged[v] = 1;
            flagged.push_back(static_cast<Index>(v));
            ++added;
        }
        if (added == 0) break;
        if (static_cast<Scalar>(flagged.size()) > defaults.max_fraction * static_cast<Scalar>(n)) {
            if (!input.empty()) p = std::move(input);
            return {};
        }
        if (input.empty()) input = p;
        next.resize(flagged.size());
        parallel_for(0, flagged.size(), [&](std::size_t i) { next[i] = repaired_position(p, topo, is_flagged, Le, flagged[i], true); }, 256);
        for (std::size_t i = 0; i < flagged.size(); ++i) p[flagged[i]] = next[i];
        progress.check();
    }
    // Those with no unflagged two-ring to be put back onto stayed where they were: not counted.
    std::erase_if(flagged, [&](Index v) { return p[v] == input[v]; });
    std::sort(flagged.begin(), flagged.end());
    return flagged;
}

/// remove_impulses on positions in a sane frame; `hold` (optional) marks vertices that
/// never move (known to be in place). `L` is the mean edge length. When vertices were put
/// back, `labels` (optional) receives per vertex 1 (put back), 2 (unmoved) or 0, and `before`
/// (optional) the positions as they came in (the copy the run keeps anyway); both are left
/// as they are otherwise.
inline ImpulseResult run(std::vector<Vec3>& p, const std::vector<Face>& faces, const MeshTopology& topo, Scalar L,
                         const std::vector<unsigned char>* hold, const ImpulseParams& params, Progress& progress,
                         std::vector<unsigned char>* labels = nullptr, std::vector<Vec3>* before = nullptr) {
    ImpulseResult r;
    const std::size_t n = p.size();
    const Scalar min_area2 = height_min_area2(L);
    std::vector<Scalar> h = gate_heights(p, faces, topo, L, params, r);
    progress.check();
    if (!r.impulsive) return r;
    Scalar scale = std::max(r.median_height, params.floor * L);
    std::vector<Vec3> input = p;
    std::vector<Index> flagged;
    std::vector<unsigned char> is_flagged(n, 0);
    // A vertex is flagged when its height exceeds `threshold` times the scale. On a mesh of
    // exact planes (median height under the floor) also `threshold` times the median height
    // of its unflagged neighbours: there an impulse stands out from neighbours at height 0,
    // while a clean curved strip (heights all alike) does not. (On curved meshes that local
    // test would lose the impulses next to other impulses: fertility + 10 % 3.8° → 5.3°.)
    const bool exact_planes = r.median_height < params.floor * L;
    // Exact planes whose unmoved vertices the caller already holds (smooth_feature_bilateral's
    // coplanar stage): the filters do better there without the repair (the Block + 10 %:
    // 1.0° against 1.2-1.5°, its fits rounding crease vertices), so nothing is put back.
    if (exact_planes && hold) return r;
    auto flag_new = [&] {
        std::vector<Index> fresh;
        for (std::size_t v = 0; v < n; ++v) {
            if (is_flagged[v] || !(h[v] > params.threshold * scale) || (hold && (*hold)[v])) continue;
            if (!exact_planes) {
                fresh.push_back(static_cast<Index>(v));
                continue;
            }
            Scalar local[64];
            std::size_t k = 0;
            const auto nb = topo.vertex_neighbors(static_cast<Index>(v));
            const std::size_t step = std::max<std::size_t>(1, nb.size() / 64);
            for (std::size_t i = 0; i < nb.size() && k < 64; i += step)
                if (!is_flagged[nb[i]] && h[nb[i]] >= 0) local[k++] = h[nb[i]];
            if (k > 0) {
                std::nth_element(local, local + k / 2, local + k);
                if (!(h[v] > params.threshold * local[k / 2])) continue;
            }
            fresh.push_back(static_cast<Index>(v));
        }
        for (Index v : fresh) {
            flagged.push_back(v);
            is_flagged[v] = 1;
        }
        return fresh.size();
    };
    auto repaired = [&](Index v) { return repaired_position(p, topo, is_flagged, L, v); };
    std::vector<Vec3> next;
    for (std::size_t pass = 0; pass < params.passes; ++pass) {
        if (pass > 0) {  // impulses masked by moved neighbours show once those are back
            parallel_for(0, n, [&](std::size_t v) {
                if (!is_flagged[v]) h[v] = height(p, faces, topo, static_cast<Index>(v), min_area2);
            }, 1024);
            std::vector<Scalar> un;
            for (std::size_t v = 0; v < n; ++v)
                if (!is_flagged[v] && h[v] >= 0) un.push_back(h[v]);
            if (!un.empty()) scale = std::min(scale, std::max(quantile(un, 0.5), params.floor * L));
        }
        const std::size_t added = flag_new();
        if (added == 0) break;
        if (static_cast<Scalar>(flagged.size()) > params.max_fraction * static_cast<Scalar>(n)) {
            r.dense = true;  // not impulsive noise in the sense of the method: the input back
            p = std::move(input);
            return r;
        }
        progress.update(static_cast<double>(pass) / static_cast<double>(params.passes));
        // One round: the fits read unflagged vertices only, which the repair does not move.
        next.resize(flagged.size());
        parallel_for(0, flagged.size(), [&](std::size_t i) { next[i] = repaired(flagged[i]); }, 256);
        for (std::size_t i = 0; i < flagged.size(); ++i) p[flagged[i]] = next[i];
        progress.check();
    }
    r.moved_vertices = flagged.size();
    if (flagged.empty()) return r;  // heavy-tailed but nothing stands out from its neighbours
    // Labels: 1 put back; 2 within `keep` times the median of a plane of three neighbours
    // (taken as unmoved); 0 neither.
    parallel_for(0, n, [&](std::size_t v) {
        if (is_flagged[v]) return;
        const Scalar hv = height(p, faces, topo, static_cast<Index>(v), min_area2);
        is_flagged[v] = hv >= 0 && hv <= params.keep * scale ? 2 : 0;
    }, 1024);
    for (unsigned char c : is_flagged) r.unmoved_vertices += c == 2;
    if (labels) *labels = std::move(is_flagged);
    if (before) *before = std::move(input);
    return r;
}

}  // namespace detail::impulses

/// @brief Puts back onto the surface the vertices impulsive noise moved (see the file comment).
/// @tparam M a type modelling MutableTriangleMesh
/// @param mesh   any triangle mesh; only spikes and flagged vertices move, the latter only when the gate passes
/// @param params gate, threshold, floor, passes, max_fraction, keep, progress/cancellation
/// @throws invalid_input for a NaN/Inf coordinate, a face index out of range, gate ≤ 1,
///         threshold ≤ 0, floor < 0, passes outside 1–100, max_fraction outside (0, 1],
///         keep < 0 (each message names the parameter).
/// @return Status::ok (spike_vertices, impulsive, moved_vertices, the height statistics); Status::cancelled:
///         stopped through params.control, the mesh is untouched.
template <MutableTriangleMesh M>
ImpulseResult remove_impulses(M& mesh, const ImpulseParams& params = {}) {
    const std::string fn = "kintsugi::remove_impulses: ";
    if (!(params.gate > 1) || !std::isfinite(params.gate)) throw invalid_input(fn + "gate must be a finite number > 1");
    if (!(params.threshold > 0) || !std::isfinite(params.threshold)) throw invalid_input(fn + "threshold must be a finite number > 0");
    if (!(params.floor >= 0) || !std::isfinite(params.floor)) throw invalid_input(fn + "floor must be finite and >= 0");
    if (params.passes < 1 || params.passes > 100) throw invalid_input(fn + "passes must be in 1..100");
    if (!(params.max_fraction > 0 && params.max_fraction <= 1)) throw invalid_input(fn + "max_fraction must be in (0, 1]");
    if (!(params.keep >= 0) || !std::isfinite(params.keep)) throw invalid_input(fn + "keep must be finite and >= 0");
    std::vector<Vec3> positions = detail::finite_vertex_positions(mesh, fn);
    const MeshTopology topo(mesh);
    const detail::ScaleFrame frame = detail::scale_frame(positions);
    frame.to_local(positions);
    ImpulseResult out = detail::run_cancellable<ImpulseResult>(params.control, [&](detail::Progress& progress) {
        progress.stage("impulses", 0.0, 1.0);
        // Spikes first: the gate's percentile does not see a few, and they inflate the mean edge length.
        const std::size_t spikes = detail::impulses::put_back_spikes(positions, topo.faces(), topo, progress).size();
        const Scalar L = detail::mean_edge_length(positions, topo, false);
        ImpulseResult r = L > 0 ? detail::impulses::run(positions, topo.faces(), topo, L, nullptr, params, progress)
                                : ImpulseResult{};
        r.spike_vertices = spikes;
        r.timings = progress.finish();
        return r;
    });
    if (out.status == Status::ok) {
        out.median_height = frame.to_world(out.median_height);
        out.high_height = frame.to_world(out.high_height);
        if (out.moved_vertices > 0 || out.spike_vertices > 0) {
            frame.to_world(positions);
            detail::write_flagged_positions(mesh, positions, {});
        }
    }
    return out;
}

}  // namespace kintsugi
