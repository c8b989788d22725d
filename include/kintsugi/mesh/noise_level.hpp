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
/// Cost: one small least-squares fit per vertex, linear in the mesh, parallel; the
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

/// σ, the mean and clean edge lengths from positions already in a safe frame.
inline NoiseLevel estimate(const std::vector<Vec3>& V, const std::vector<Face>& F, const MeshTopology& topo,
                           std::size_t rings, Progress& progress) {
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
        // Each squared edge length grows by about 2σ²: scale the mean by the factor
        // that takes 2σ² off the mean square (at least a tenth of the mean is kept).
        const Scalar ms = sum2 / static_cast<Scalar>(count);
        const Scalar shrink = ms > 0 ? std::max(1 - 2 * out.sigma * out.sigma / ms, Scalar(0.01)) : Scalar(1);
        out.clean_edge_length = out.mean_edge_length * std::sqrt(shrink);
        out.relative = out.clean_edge_length > 0 ? out.sigma / out.clean_edge_length : 0;
    }
    return out;
}

}  // namespace detail::noise

/// @brief Estimates the standard deviation of the noise normal to a mesh's surface
/// from the median of local quadric-fit residual variances (see the file comment).
/// @tparam M a type modelling TriangleMesh
/// @param mesh   the mesh (not modified); units are the model's
/// @param params ring count of the fits (1–8, default 2), control
/// @return sigma (model units), the input's and the estimated clean mean edge length,
///         sigma relative to the latter, the number of vertices fitted.
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
        out.sigma = frame.to_world(out.sigma);
        out.mean_edge_length = frame.to_world(out.mean_edge_length);
        out.clean_edge_length = frame.to_world(out.clean_edge_length);
        return out;
    } catch (const detail::cancelled_exception&) {
        NoiseLevel out;
        out.status = Status::cancelled;
        return out;
    }
}

}  // namespace kintsugi
