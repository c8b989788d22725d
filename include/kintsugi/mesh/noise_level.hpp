// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file noise_level.hpp
/// @brief `estimate_noise_level`: the standard deviation of a mesh's noise normal to
/// its surface, from robust statistics of local quadric-fit residuals, so that a
/// filter can set its scales from the data instead of asking the caller.
///
/// @code
/// kintsugi::NoiseLevel n = kintsugi::estimate_noise_level(mesh);
/// // n.sigma (model units), n.relative = sigma / n.mean_edge_length
/// @endcode
///
/// ## Method
/// For every vertex v used by a face, its neighbourhood is the vertices within
/// `rings` edge rings. In a frame whose z axis is the sum of the area-weighted normals
/// of those vertices, a quadric height function z = q(x, y) (6 coefficients) is fitted
/// by least squares; s_v² = RSS / (n − 6) is an unbiased estimate of the variance of
/// the heights if the surface is locally a quadric and the noise independent with
/// standard deviation σ (then (n − 6)s_v²/σ² is χ² with n − 6 degrees of freedom).
/// Neighbourhoods that straddle a sharp edge or a corner are not quadrics; their
/// s_v² are outliers, so σ² is the **median** of the s_v² each divided by the median
/// of χ²_k/k (k = n − 6; Wilson–Hilferty: (1 − 2/(9k))³): a robust scale estimate
/// that ignores up to half the vertices (Rousseeuw & Croux, "Alternatives to the
/// median absolute deviation", JASA 1993, on median-based scale; the residual-of-fit
/// idea is the one of image noise estimation, e.g. Donoho & Johnstone 1994's MAD of
/// fine-scale residuals). A quadric rather than a plane: on curved shapes sampled
/// with ~10 edges per radius a plane's bias is of the order of 0.1 mean edge lengths,
/// the lowest noise we aim at (measured in docs/methods/feature_bilateral.md).
///
/// **Light noise: umbrella differences.** Below 0.3|e| a shape's own detail over two
/// rings (a coarse or scanned mesh is not a quadric there) reads as noise: the clean
/// armadillo reads 0.11|e|, the clean elephant 0.14|e|, and 0.1|e| of added noise 1.5-1.9
/// times the truth. There σ is also estimated from differences, the idea of
/// difference-based variance estimators in regression (T. Gasser, L. Sroka, C.
/// Jennen-Steinmetz, "Residual variance and residual pattern in nonlinear regression",
/// Biometrika 1986): the umbrella height u_v = n_v · (mean of the one-ring − v) holds the
/// curvature, which varies slowly, plus a combination of the noise; across an interior edge
/// (a, b) the curvature cancels and, for independent noise, Var(u_a − u_b) = σ²(2 + 3/d_a +
/// 3/d_b − 2k/(d_a d_b)) (degrees d, k faces on the edge). σ² is the median over the edges
/// of (u_a − u_b)² divided by that factor and by the median of χ²₁. The normals n_v are the
/// vertices' own under light noise and averaged over three rings toward 0.3|e| (the own
/// normals tilt with the noise). The differences are used only where their squares look
/// χ²-distributed: 90th percentile within 15 times the median (χ²₁: 5.95; Gaussian noise
/// reads 5.7-6.6, clean curved meshes 7.4-12, impulsive noise of 10 % or a third of the
/// vertices 21-460, where the median would read the unmoved majority). The result is the
/// lower of the two estimates below 0.2|e| and the quadric's from 0.3|e|, blended linearly
/// in between: the clean armadillo reads 0.066|e|, the elephant 0.049|e|; 0.1|e| added
/// reads 1.24 and 1.19 times the truth; the other shapes measured read 0.98-1.16
/// (docs/methods/feature_bilateral.md, "Noise level: umbrella differences").
///
/// σ is the noise **normal to the surface**: a tangential displacement of a vertex
/// changes the sampling, not the shape, and cannot be seen. For Gaussian noise along
/// the normals σ is the noise's standard deviation; for isotropic noise of standard
/// deviation σ₃ per axis it is σ₃; for noise of standard deviation s along random
/// unit directions it is s/√3. Impulsive noise (few vertices moved far) reads as the
/// noise of the majority of vertices, which the median keeps.
///
/// `mean_edge_length` is the input's; noise lengthens edges: for independent noise of
/// σ normal to the surface every |e|² grows by about 2σ², so `clean_edge_length` =
/// mean |e| · √(1 − 2σ²/mean |e|²) (at least a tenth of the mean |e|) estimates the
/// edge length under the noise, against which noise levels are usually quoted
/// (σ = 0.3|e| etc.). Tangential noise lengthens edges too and is not taken off: under
/// noise along random directions the figure stays 10–30 % high at 0.5–0.8|e|.
///
/// Cost: one small least-squares fit per vertex, and under 0.3|e| two passes over the faces
/// and the edges and five over the one-rings, linear in the mesh, parallel; the
/// result does not depend on the thread count (each vertex is fitted alone, and the
/// median is of a fixed array).

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/mesh/topology.hpp>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace kintsugi {

/// Parameters of estimate_noise_level (aggregate; field order is API, append only).
struct NoiseLevelParams {
    /// Neighbourhood of each fit: the vertices within this many edge rings. Range 1–8,
    /// default 2 (about 19 vertices on a regular mesh: 13 degrees of freedom for a
    /// quadric; 1 ring leaves 1, 3 rings fit larger patches where a quadric is biased).
    std::size_t rings = 2;
    RunControl control{};
};

/// What estimate_noise_level returns.
struct NoiseLevel {
    Status status = Status::ok;  ///< ok, or cancelled (then every figure is 0)
    Scalar sigma = 0;            ///< standard deviation of the noise normal to the surface, model units
    Scalar mean_edge_length = 0;   ///< mean edge length of the input, model units
    Scalar clean_edge_length = 0;  ///< mean edge length with the normal noise's share taken off (see file comment)
    Scalar relative = 0;           ///< sigma / clean_edge_length
    std::size_t vertices_used = 0;  ///< vertices whose fit entered the median (enough neighbours, not degenerate)
    Scalar quadric_sigma = 0;     ///< the quadric-fit estimate alone, model units
    /// The difference-based estimate, model units; 0 when not computed (quadric estimate at or
    /// above 0.3|e|, heavy-tailed differences, or fewer than 16 interior edges). When it is
    /// above the quadric estimate it is reported but `sigma` is the quadric's.
    Scalar difference_sigma = 0;
};

namespace detail::noise {

/// Median of χ²_k / k (Wilson–Hilferty approximation, within 0.2 % for k ≥ 3).
inline Scalar chi2_median_ratio(Scalar k) {
    const Scalar t = 1 - 2 / (9 * k);
    return t * t * t;
}

/// The per-vertex estimates s_v² / median(χ²_k/k), NaN where the fit is not made.
inline std::vector<Scalar> local_variances(const std::vector<Vec3>& V, const std::vector<Face>& F,
                                           const MeshTopology& topo, std::size_t rings, Progress& progress) {
    const std::size_t nv = V.size();
    // Area-weighted vertex normals (unnormalised): the frames' z axes are their sums.
    std::vector<Vec3> vn(nv, Vec3::Zero());
    for (const Face& f : F) {
        const Vec3 c = (V[f[1]] - V[f[0]]).cross(V[f[2]] - V[f[0]]);
        for (Index v : f) vn[v] += c;
    }
    std::vector<Scalar> out(nv, std::numeric_limits<Scalar>::quiet_NaN());
    const std::size_t blocks = std::clamp<std::size_t>(nv / 4096, 1, 20);
    for (std::size_t b = 0; b < blocks; ++b) {
        parallel_for(nv * b / blocks, nv * (b + 1) / blocks, [&](std::size_t v) {
            if (topo.vertex_faces(v).empty()) return;
            thread_local std::vector<std::uint32_t> mark;
            thread_local std::uint32_t stamp = 0;
            thread_local std::vector<Index> ring;
            if (mark.size() != nv) {
                mark.assign(nv, 0);
                stamp = 0;
            }
            if (++stamp == 0) {
                std::fill(mark.begin(), mark.end(), 0);
                stamp = 1;
            }
            // Breadth-first over the edge rings (each vertex once), at most 4096 vertices
            // (a bounded cost around high-valence vertices).
            ring.assign(1, static_cast<Index>(v));
            mark[v] = stamp;
            std::size_t level_begin = 0;
            for (std::size_t r = 0; r < rings && ring.size() < 4096; ++r) {
                const std::size_t level_end = ring.size();
                for (std::size_t k = level_begin; k < level_end && ring.size() < 4096; ++k)
                    for (Index u : topo.vertex_neighbors(ring[k])) {
                        if (ring.size() >= 4096) break;  // else a hub's whole ring, once per spoke
                        if (mark[u] != stamp) {
                            mark[u] = stamp;
                            ring.push_back(u);
                        }
                    }
                level_begin = level_end;
            }
            const std::size_t n = ring.size();
            if (n < 9) return;  // fewer than 3 degrees of freedom: no estimate
            Vec3 z = Vec3::Zero(), centre = Vec3::Zero();
            for (Index u : ring) {
                z += vn[u];
                centre += V[u];
            }
            const Scalar zn = z.norm();
            if (!(zn > 0) || !std::isfinite(zn)) return;
            z /= zn;
            centre /= static_cast<Scalar>(n);
            const Vec3 x = z.unitOrthogonal(), y = z.cross(x);
            // Normal equations of z = c0 + c1 u + c2 w + c3 u² + c4 uw + c5 w², the
            // in-plane coordinates divided by their rms (conditioning).
            Scalar scale2 = 0;
            for (Index u : ring) {
                const Vec3 d = V[u] - centre;
                scale2 += d.dot(x) * d.dot(x) + d.dot(y) * d.dot(y);
            }
            const Scalar s = std::sqrt(scale2 / static_cast<Scalar>(n));
            if (!(s > 0)) return;
            Eigen::Matrix<Scalar, 6, 6> A = Eigen::Matrix<Scalar, 6, 6>::Zero();
            Eigen::Matrix<Scalar, 6, 1> rhs = Eigen::Matrix<Scalar, 6, 1>::Zero();
            for (Index u : ring) {
                const Vec3 d = V[u] - centre;
                const Scalar a = d.dot(x) / s, c = d.dot(y) / s, h = d.dot(z);
                Eigen::Matrix<Scalar, 6, 1> m;
                m << 1, a, c, a * a, a * c, c * c;
                A.selfadjointView<Eigen::Lower>().rankUpdate(m);
                rhs += h * m;
            }
            A.triangularView<Eigen::StrictlyUpper>() = A.transpose();
            const Eigen::LDLT<Eigen::Matrix<Scalar, 6, 6>> ldlt(A);
            if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-10)) return;
            const Eigen::Matrix<Scalar, 6, 1> coef = ldlt.solve(rhs);
            // The residuals summed directly (Σh² − coefᵀ·rhs cancels when they are small).
            Scalar rss = 0;
            for (Index u : ring) {
                const Vec3 d = V[u] - centre;
                const Scalar a = d.dot(x) / s, c = d.dot(y) / s, h = d.dot(z);
                const Scalar r = h - (coef[0] + coef[1] * a + coef[2] * c + coef[3] * a * a + coef[4] * a * c +
                                      coef[5] * c * c);
                rss += r * r;
            }
            const Scalar k = static_cast<Scalar>(n - 6);
            if (std::isfinite(rss)) out[v] = rss / k / chi2_median_ratio(k);
        }, 256);
        progress.update(static_cast<double>(b + 1) / static_cast<double>(blocks));
    }
    return out;
}

/// `normals` (unit or zero) `rounds` times replaced by the normalised sum over each vertex and
/// its one-ring; zero where undefined.
inline std::vector<Vec3> ring_averaged_normals(std::vector<Vec3> n, const MeshTopology& topo, int rounds) {
    auto normalise = [](Vec3& a) {
        const Scalar l = a.norm();
        a = l > 0 && std::isfinite(l) ? Vec3(a / l) : Vec3(Vec3::Zero());
    };
    std::vector<Vec3> next(n.size());
    for (int r = 0; r < rounds; ++r) {
        parallel_for(0, n.size(), [&](std::size_t v) {
            Vec3 a = n[v];
            for (Index u : topo.vertex_neighbors(v)) a += n[u];
            normalise(a);
            next[v] = a;
        }, 4096);
        n.swap(next);
    }
    return n;
}

/// Unit area-weighted vertex normals of positions already in a safe frame; zero where undefined.
inline std::vector<Vec3> unit_vertex_normals(const std::vector<Vec3>& V, const std::vector<Face>& F) {
    std::vector<Vec3> n(V.size(), Vec3::Zero());
    for (const Face& f : F) {
        const Vec3 c = (V[f[1]] - V[f[0]]).cross(V[f[2]] - V[f[0]]);
        for (Index v : f) n[v] += c;
    }
    for (Vec3& a : n) {
        const Scalar l = a.norm();
        a = l > 0 && std::isfinite(l) ? Vec3(a / l) : Vec3(Vec3::Zero());
    }
    return n;
}

/// A difference-based estimate and how heavy its tail is.
struct DifferenceEstimate {
    Scalar sigma = 0;  ///< model units; 0 when fewer than 16 edges qualify
    /// 90th percentile over the median of the scaled squared differences (infinite when the
    /// median is 0 or fewer than 16 edges qualify)
    Scalar tail = 0;
};

/// The difference-based estimate (see the file comment): σ from the median over interior
/// edges of (u_v − u_w)² / c_vw, u the umbrella heights along `normals`, c_vw their variance
/// per unit σ² under independent noise (from the degrees and the edge's faces), divided by the
/// median of χ²₁ (0.4549).
inline DifferenceEstimate difference_sigma(const std::vector<Vec3>& V, const MeshTopology& topo,
                                           const std::vector<Vec3>& normals) {
    const std::size_t nv = V.size();
    std::vector<Scalar> u(nv, 0);
    std::vector<std::uint8_t> ok(nv, 0);
    parallel_for(0, nv, [&](std::size_t v) {
        const auto ring = topo.vertex_neighbors(v);
        if (ring.size() < 3 || topo.is_boundary_vertex(v) || normals[v].isZero()) return;
        Vec3 sum = Vec3::Zero();
        for (Index w : ring) sum += V[w] - V[v];
        u[v] = normals[v].dot(sum) / static_cast<Scalar>(ring.size());
        ok[v] = 1;
    }, 4096);
    const auto& edges = topo.edges();
    std::vector<Scalar> r(edges.size(), std::numeric_limits<Scalar>::quiet_NaN());
    parallel_for(0, edges.size(), [&](std::size_t e) {
        const Index a = edges[e][0], b = edges[e][1];
        if (a == b || !ok[a] || !ok[b]) return;
        // u_a = (1/d_a) Σ ε_j − ε_a: Var(u_a) = 1 + 1/d_a; Cov(u_a, u_b) = −1/d_a − 1/d_b + k/(d_a d_b)
        // for k common neighbours (the edge's opposite vertices, one per face).
        const Scalar da = static_cast<Scalar>(topo.vertex_neighbors(a).size());
        const Scalar db = static_cast<Scalar>(topo.vertex_neighbors(b).size());
        const Scalar k = static_cast<Scalar>(topo.edge_faces(static_cast<Index>(e)).size());
        const Scalar c = 2 + 1 / da + 1 / db + 2 / da + 2 / db - 2 * k / (da * db);
        const Scalar d = u[a] - u[b];
        if (c > 0) r[e] = d * d / c;
    }, 4096);
    std::erase_if(r, [](Scalar x) { return !std::isfinite(x); });
    DifferenceEstimate out;
    if (r.size() < 16) {
        out.tail = std::numeric_limits<Scalar>::infinity();  // too few edges: not used
        return out;
    }
    auto mid = r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2);
    std::nth_element(r.begin(), mid, r.end());
    const Scalar median = std::max<Scalar>(*mid, 0);
    auto p90 = r.begin() + static_cast<std::ptrdiff_t>(r.size() * 9 / 10);
    std::nth_element(mid, p90, r.end());
    out.sigma = std::sqrt(median / Scalar(0.4549));
    out.tail = median > 0 ? *p90 / median : std::numeric_limits<Scalar>::infinity();
    return out;
}

/// σ, the mean and clean edge lengths from positions already in a safe frame. With
/// `difference` the quadric estimate is combined with the difference-based one below 0.3|e|
/// (file comment); without, σ is the quadric estimate alone.
inline NoiseLevel estimate(const std::vector<Vec3>& V, const std::vector<Face>& F, const MeshTopology& topo,
                           std::size_t rings, Progress& progress, bool difference = true) {
    NoiseLevel out;
    std::vector<Scalar> s2 = local_variances(V, F, topo, rings, progress);
    std::erase_if(s2, [](Scalar x) { return !std::isfinite(x); });
    out.vertices_used = s2.size();
    if (!s2.empty()) {
        // The median (upper median for an even count: a fixed element, no averaging).
        auto mid = s2.begin() + static_cast<std::ptrdiff_t>(s2.size() / 2);
        std::nth_element(s2.begin(), mid, s2.end());
        out.sigma = std::sqrt(std::max<Scalar>(*mid, 0));
    }
    out.quadric_sigma = out.sigma;
    Scalar sum = 0, sum2 = 0;
    std::size_t count = 0;
    for (const auto& e : topo.edges())
        if (e[0] != e[1]) {
            const Scalar l2 = (V[e[0]] - V[e[1]]).squaredNorm();
            sum += std::sqrt(l2);
            sum2 += l2;
            ++count;
        }
    if (count > 0) {
        out.mean_edge_length = sum / static_cast<Scalar>(count);
    }
    if (difference && out.mean_edge_length > 0 && out.sigma < Scalar(0.3) * out.mean_edge_length) {
        // Below 0.3|e| the quadric fits read the shape's detail as noise; the umbrella
        // differences read less of it. Their vertex normals: the faces' own under light noise
        // (least detail read), averaged over three rings from 0.3|e| (the own normals tilt with
        // the noise and read 15-20 % low at 0.8|e|), blended in between.
        // Only where the differences are Gaussian-like: their 90th percentile within 15 times
        // the median (χ²₁: 5.95; Gaussian noise from 0.1|e| 5.7-6.6, clean curved meshes
        // 7.4-12; 10 % or a third of the vertices moved, 21-460: the median then reads the
        // unmoved majority).
        const Scalar L = out.mean_edge_length;
        std::vector<Vec3> normals = unit_vertex_normals(V, F);
        const DifferenceEstimate d0 = difference_sigma(V, topo, normals);
        const Scalar s3 =
            d0.tail <= Scalar(15) ? difference_sigma(V, topo, ring_averaged_normals(std::move(normals), topo, 3)).sigma : 0;
        const Scalar w = std::clamp((s3 / L - Scalar(0.1)) / Scalar(0.2), Scalar(0), Scalar(1));
        out.difference_sigma = s3 > 0 ? (1 - w) * d0.sigma + w * s3 : 0;
        if (out.difference_sigma > 0 && out.difference_sigma < out.sigma) {
            // The lower of the two below 0.2|e|, the quadric's from 0.3|e|, linear in between
            // (never above the quadric's: a higher difference reading is reported, not used).
            const Scalar t = std::clamp((out.sigma / L - Scalar(0.2)) / Scalar(0.1), Scalar(0), Scalar(1));
            out.sigma = std::min(out.sigma, (1 - t) * out.difference_sigma + t * out.sigma);
        }
    }
    if (count > 0) {
        // Each squared edge length grows by about 2σ²: scale the mean by the factor
        // that takes 2σ² off the mean square (at least a tenth of the mean is kept).
        const Scalar ms = sum2 / static_cast<Scalar>(count);
        const Scalar shrink = ms > 0 ? std::max(1 - 2 * out.sigma * out.sigma / ms, Scalar(0.01)) : Scalar(1);
        out.clean_edge_length = out.mean_edge_length * std::sqrt(shrink);
        out.relative = out.clean_edge_length > 0 ? out.sigma / out.clean_edge_length : 0;
    }
    return out;
}

/// The figures of `n` (model units of the frame's local coordinates) in world units.
inline void to_world(NoiseLevel& n, const ScaleFrame& frame) {
    for (Scalar* x : {&n.sigma, &n.mean_edge_length, &n.clean_edge_length, &n.quadric_sigma, &n.difference_sigma})
        *x = frame.to_world(*x);
}

}  // namespace detail::noise

/// @brief Estimates the standard deviation of the noise normal to a mesh's surface
/// from the median of local quadric-fit residual variances, combined below 0.3|e| with a
/// median of umbrella-height differences across edges (see the file comment).
/// @tparam M a type modelling TriangleMesh
/// @param mesh   the mesh (not modified); units are the model's
/// @param params ring count of the fits (1–8, default 2), control
/// @return sigma (model units), the input's and the estimated clean mean edge length,
///         sigma relative to the latter, the number of vertices fitted, and the two
///         estimates sigma comes from (quadric_sigma, difference_sigma).
///         Status::cancelled: every figure 0.
/// @throws invalid_input on an empty mesh, NaN/Inf coordinates, a face index out of
///         range, or rings outside 1–8.
template <TriangleMesh M>
[[nodiscard]] NoiseLevel estimate_noise_level(const M& mesh, const NoiseLevelParams& params = {}) {
    const std::string fn = "kintsugi::estimate_noise_level";
    if (params.rings < 1 || params.rings > 8)
        throw invalid_input(fn + ": rings = " + std::to_string(params.rings) + " must be between 1 and 8");
    IndexedMesh m = kintsugi::to_indexed_mesh(mesh);
    if (m.faces.empty()) throw invalid_input(fn + ": the mesh has no faces; pass a non-empty triangle mesh");
    detail::check_mesh_values(m, fn.c_str());
    const detail::ScaleFrame frame = detail::scale_frame(m.vertices);
    frame.to_local(m.vertices);
    detail::Progress progress(params.control);
    try {
        progress.stage("noise level", 0.0, 1.0);
        const MeshTopology topo(m.vertices.size(), m.faces);
        NoiseLevel out = detail::noise::estimate(m.vertices, m.faces, topo, params.rings, progress);
        (void)progress.finish();
        detail::noise::to_world(out, frame);
        return out;
    } catch (const detail::cancelled_exception&) {
        NoiseLevel out;
        out.status = Status::cancelled;
        return out;
    }
}

}  // namespace kintsugi
