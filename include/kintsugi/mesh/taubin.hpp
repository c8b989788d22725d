// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file taubin.hpp
/// @brief Taubin λ/μ smoothing of a triangle mesh, optionally of a subset of its
/// vertices only (the others stay fixed and act as boundary conditions).
///
/// @code
/// std::vector<std::uint8_t> movable(mesh.vertices.size(), 0);
/// movable[17] = 1;                                    // only vertex 17 moves
/// kintsugi::smooth_taubin(mesh, movable, {.iterations = 30});
/// @endcode

#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/mesh/vertex_subset.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace kintsugi {

/// Parameters of smooth_taubin.
struct TaubinParams {
    /// Number of λ/μ pairs, >= 0 (default 30; 0 leaves the mesh as it is). Nagai et al.
    /// (2011) use 30, by which the motion has nearly converged.
    std::size_t iterations = 30;
    /// Forward (shrinking) step v ← v + λ U(v), in (0, 1] (default 0.5: Nagai et al.'s
    /// value; 1 moves a vertex onto the mean of its neighbours).
    Scalar lambda = 0.5;
    /// Backward (inflating) step v ← v + μ U(v), in [−1, 0) (default −0.5). Nagai et al.
    /// use μ = −λ (their "v − λU′"); Taubin (1995) suggests |μ| slightly above λ (e.g.
    /// −0.53) for a filter that does not shrink at all.
    Scalar mu = -0.5;
    /// Progress callback and stop token (default: none); a cancelled run leaves the mesh untouched.
    RunControl control{};
};

/// Result of smooth_taubin: moved_vertices = the movable vertices that have at least
/// one neighbour.
using TaubinResult = VertexSubsetResult;

namespace detail {

/// The umbrella vector U(v) = mean of v's one-ring − v (v must have a neighbour).
inline Vec3 umbrella(const std::vector<Vec3>& positions, const MeshTopology& topo, Index v) {
    const auto nb = topo.vertex_neighbors(v);
    Vec3 mean = Vec3::Zero();
    for (Index u : nb) mean += positions[u];
    mean /= static_cast<Scalar>(nb.size());
    return mean - positions[v];
}

/// Smooths `positions` in place over the one-rings of `topo`; only vertices with
/// movable[v] != 0 (all when movable is empty) move. Uniform umbrella operator
/// U(v) = mean(neighbours) − v, Jacobi updates (deterministic, parallel).
inline std::size_t taubin_smooth(std::vector<Vec3>& positions, const MeshTopology& topo,
                                 const std::vector<std::uint8_t>& movable, const TaubinParams& params,
                                 Progress& progress) {
    const std::vector<Index> active = movable_vertices(topo, positions.size(), movable).vertices;
    if (active.empty() || params.iterations == 0) return active.size();
    std::vector<Vec3> next(active.size());
    auto step = [&](Scalar factor) {
        parallel_for(0, active.size(), [&](std::size_t i) {
            const Index v = active[i];
            next[i] = positions[v] + factor * umbrella(positions, topo, v);
        }, 1024);
        for (std::size_t i = 0; i < active.size(); ++i) positions[active[i]] = next[i];
    };
    for (std::size_t it = 0; it < params.iterations; ++it) {
        progress.update(static_cast<double>(it) / static_cast<double>(params.iterations));
        step(params.lambda);
        step(params.mu);
    }
    return active.size();
}

/// What taubin_risk_curves returns: for k = 0, 1, ... λ|μ pairs, the residual along the
/// normals Σ_v (n_v·(S_k y − y)_v)², tr S_k and tr S_kᵀS_k, over the `moved` vertices (those
/// with a neighbour and a non-zero normal; S_k restricted to them).
struct TaubinRiskCurves {
    std::vector<Scalar> residual, trace, trace_sq;
    std::size_t moved = 0;
};

/// Stein's unbiased risk estimate (Stein 1981) of a smoother f over m values with noise of
/// variance σ²: E |f(y) − x|² = |f(y) − y|² − mσ² + 2σ² div f, `divergence` being div f
/// (tr S for a linear f = S y).
inline Scalar stein_risk(Scalar residual, std::size_t m, Scalar sigma, Scalar divergence) {
    const Scalar s2 = sigma * sigma;
    return residual - static_cast<Scalar>(m) * s2 + 2 * s2 * divergence;
}

/// stein_risk of k pairs for noise of variance σ² along the normals: E Σ_v (n_v·(S_k y − x)_v)².
/// It holds for any zero-mean noise of that variance, since S_k is linear.
inline Scalar taubin_risk(const TaubinRiskCurves& c, std::size_t k, Scalar sigma) {
    return stein_risk(c.residual[k], c.moved, sigma, c.trace[k]);
}

/// The step count of least taubin_risk for σ (the first of equal ones).
inline std::size_t least_risk_steps(const TaubinRiskCurves& c, Scalar sigma) {
    std::size_t best = 0;
    for (std::size_t k = 1; k < c.residual.size(); ++k)
        if (taubin_risk(c, k, sigma) < taubin_risk(c, best, sigma)) best = k;
    return best;
}

/// Taubin λ|μ pairs 0..max_steps from `y`, every vertex with a neighbour moving (Jacobi
/// updates, the steps of taubin_smooth), recording over the vertices with a non-zero normal
/// the residual along `normals`, tr S_k and tr S_kᵀS_k. The traces: Hutchinson's estimator
/// (E zᵀS_k z and E |S_k z|²) over fixed-seed Rademacher vectors smoothed beside the
/// positions, the power of two from 2 to 16 that brings probes × moved vertices to 2^17 or more
/// (the estimate's relative error falls as 1/√(probes·tr S_k); with two, small meshes' least-risk
/// counts moved by a quarter). Stops at max_steps, or once k exceeds twice the least-risk count
/// for 1.25·σ plus 30 (the risk has risen past its minimum for any σ near the given one).
/// Deterministic: the sums are folded in fixed chunks (parallel_reduce).
template <std::size_t probes>
TaubinRiskCurves taubin_risk_curves_with(const std::vector<Vec3>& y, const MeshTopology& topo,
                                         const std::vector<Index>& active, const std::vector<Index>& counted,
                                         const std::vector<Vec3>& normals, Scalar sigma, std::size_t max_steps,
                                         const TaubinParams& params, Progress& progress) {
    const std::size_t m = active.size();
    TaubinRiskCurves out;
    out.moved = counted.size();
    // Positions and probe values (probes interleaved per vertex), double-buffered: each half
    // step reads one buffer and writes the other (vertices that do not move hold y and 0 in both).
    std::vector<Vec3> x = y, nx = y;
    std::vector<Scalar> z(probes * y.size(), 0);
    std::uint64_t state = 0x9E3779B97F4A7C15ull;
    for (Index v : counted)
        for (std::size_t p = 0; p < probes; ++p) {
            state = state * 6364136223846793005ull + 1442695040888963407ull;
            z[probes * v + p] = (state >> 63) ? 1 : -1;
        }
    const std::vector<Scalar> z0 = z;
    std::vector<Scalar> nz = z;
    auto record = [&] {
        // Fixed chunks folded in order: the same sums whatever the thread count.
        using Sums = std::array<Scalar, 3>;
        const Sums sums = parallel_reduce(
            0, counted.size(), Sums{0, 0, 0},
            [&](std::size_t first, std::size_t last, Sums acc) {
                for (std::size_t i = first; i < last; ++i) {
                    const Index v = counted[i];
                    const Scalar h = normals[v].dot(x[v] - y[v]);
                    acc[0] += h * h;
                    for (std::size_t p = 0; p < probes; ++p) {
                        acc[1] += z0[probes * v + p] * z[probes * v + p];
                        acc[2] += z[probes * v + p] * z[probes * v + p];
                    }
                }
                return acc;
            },
            [](Sums a, Sums b) { return Sums{a[0] + b[0], a[1] + b[1], a[2] + b[2]}; });
        out.residual.push_back(sums[0]);
        out.trace.push_back(sums[1] / static_cast<Scalar>(probes));
        out.trace_sq.push_back(sums[2] / static_cast<Scalar>(probes));
    };
    auto step = [&](Scalar f) {
        parallel_for(0, m, [&](std::size_t i) {
            const Index v = active[i];
            const auto nb = topo.vertex_neighbors(v);
            Vec3 mean = Vec3::Zero();
            std::array<Scalar, probes> mz{};
            for (Index u : nb) {
                mean += x[u];
                for (std::size_t p = 0; p < probes; ++p) mz[p] += z[probes * u + p];
            }
            const Scalar w = Scalar(1) / static_cast<Scalar>(nb.size());
            nx[v] = x[v] + f * (mean / static_cast<Scalar>(nb.size()) - x[v]);  // umbrella()'s arithmetic
            for (std::size_t p = 0; p < probes; ++p)
                nz[probes * v + p] = z[probes * v + p] + f * (mz[p] * w - z[probes * v + p]);
        }, 1024);
        x.swap(nx);
        z.swap(nz);
    };
    record();
    if (m == 0 || counted.empty()) return out;
    std::size_t best = 0;
    for (std::size_t k = 1; k <= max_steps; ++k) {
        progress.update(static_cast<double>(k) / static_cast<double>(max_steps));
        step(params.lambda);
        step(params.mu);
        record();
        if (taubin_risk(out, k, 1.25 * sigma) < taubin_risk(out, best, 1.25 * sigma)) best = k;
        if (k > 2 * best + 30) break;
    }
    return out;
}

inline TaubinRiskCurves taubin_risk_curves(const std::vector<Vec3>& y, const MeshTopology& topo,
                                           const std::vector<Vec3>& normals, Scalar sigma, std::size_t max_steps,
                                           const TaubinParams& params, Progress& progress) {
    const std::vector<Index> active = movable_vertices(topo, y.size(), {}).vertices;
    std::vector<Index> counted;
    for (Index v : active)
        if (normals[v].squaredNorm() > 0) counted.push_back(v);
    const std::size_t n = std::max<std::size_t>(counted.size(), 1);
    const std::size_t want = ((std::size_t{1} << 17) + n - 1) / n;  // rounded up
    auto run = [&]<std::size_t P>() {
        return taubin_risk_curves_with<P>(y, topo, active, counted, normals, sigma, max_steps, params, progress);
    };
    if (want <= 2) return run.template operator()<2>();
    if (want <= 4) return run.template operator()<4>();
    if (want <= 8) return run.template operator()<8>();
    return run.template operator()<16>();
}

inline void taubin_validate(const TaubinParams& p, std::size_t nv, const std::vector<std::uint8_t>& movable) {
    const std::string fn = "kintsugi::smooth_taubin: ";
    if (!(p.lambda > 0 && p.lambda <= 1))
        throw invalid_input(fn + "lambda = " + std::to_string(p.lambda) + " is outside (0, 1]; use e.g. 0.5");
    if (!(p.mu < 0 && p.mu >= -1))
        throw invalid_input(fn + "mu = " + std::to_string(p.mu) + " is outside [-1, 0); use e.g. -0.5 or -0.53");
    check_vertex_flags(movable, nv, fn, "movable", true);
}

}  // namespace detail

/// @brief Taubin λ/μ smoothing ("A signal processing approach to fair surface
/// design", SIGGRAPH 1995), selective: only the chosen vertices move.
///
/// Alternates v ← v + λU(v) and v ← v + μU(v) with the uniform umbrella operator
/// U(v) = (1/n) Σ_j v_j − v over the one-ring. Used with a vertex subset it is the
/// selective bi-Laplacian smoothing of Nagai, Ohtake, Suzuki (2011, §2.3): the fixed
/// vertices are boundary conditions the moving ones blend into.
///
/// @tparam M a MutableTriangleMesh (IndexedMesh, Eigen V/F view, CGAL::Surface_mesh...).
/// @param mesh    positions are updated in place; connectivity is read once.
/// @param movable empty (every vertex moves) or one flag per vertex, non-zero = moves.
/// @param params  iterations, λ, μ, cancellation.
/// @pre finite coordinates, face indices in range.
/// @throws invalid_input for λ outside (0, 1], μ outside [−1, 0), a movable vector
///         of the wrong length, a NaN/Inf coordinate or a face index out of range.
/// @return Status::ok with the number of vertices that moved; Status::cancelled:
///         stopped through params.control, the mesh is untouched.
template <MutableTriangleMesh M>
TaubinResult smooth_taubin(M& mesh, const std::vector<std::uint8_t>& movable = {}, const TaubinParams& params = {}) {
    detail::taubin_validate(params, kintsugi::num_vertices(mesh), movable);
    std::vector<Vec3> positions = detail::finite_vertex_positions(mesh, "kintsugi::smooth_taubin: ");
    const MeshTopology topo(mesh);
    // Any magnitude: sums of coordinates near 1e308 overflow; a power-of-two rescaling is exact.
    const detail::ScaleFrame frame = detail::scale_frame(positions);
    frame.to_local(positions);
    TaubinResult out = detail::run_cancellable<TaubinResult>(params.control, [&](detail::Progress& progress) {
        TaubinResult r;
        progress.stage("taubin", 0.0, 1.0);
        r.moved_vertices = detail::taubin_smooth(positions, topo, movable, params, progress);
        r.timings = progress.finish();
        return r;
    });
    if (out.status == Status::ok && params.iterations > 0) {
        frame.to_world(positions);
        detail::write_flagged_positions(mesh, positions, movable);
    }
    return out;
}

}  // namespace kintsugi
