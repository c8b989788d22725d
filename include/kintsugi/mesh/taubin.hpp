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
#include <kintsugi/core/random.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/mesh/vertex_subset.hpp>
#include <kintsugi/spatial/morton.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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
        parallel_for(0, active.size(), [&](std::size_t i) { positions[active[i]] = next[i]; }, 4096);
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

/// The vertices the risks sum over (taubin_risk_curves and the filters' risk beside it): those
/// Taubin moves (with a neighbour) that have a non-zero normal.
inline std::vector<std::uint8_t> risk_counted(const MeshTopology& topo, const std::vector<Vec3>& normals) {
    std::vector<std::uint8_t> counted(normals.size(), 0);
    for (std::size_t v = 0; v < normals.size(); ++v)
        counted[v] = !topo.vertex_neighbors(static_cast<Index>(v)).empty() && normals[v].squaredNorm() > 0;
    return counted;
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
/// counts moved by a quarter). Stops at max_steps, or once k exceeds the least-risk count for
/// `sigma` by half of it, and by at least 20: the least-risk count grows with σ (the
/// σ-dependent term 2σ² tr S_k favours smaller traces, i.e. more steps, as σ grows), so the
/// counts of every σ up to `sigma` lie within the sweep once its risk has risen well past its
/// minimum. Pass the largest σ of interest (select_by_risk: its acceptance limit, 1.1 times the
/// estimate, 1.3 where the estimate reads strong noise). The stop was at twice the count plus
/// 30 until 2026-12-06: the same count and choice in all 54 noise-table cells, a third fewer
/// pairs (docs/methods/feature_bilateral.md).
/// The sweep is memory-bound: the moving vertices are renumbered along a Morton curve, each
/// one's position and probe values kept together in single precision (half the traffic; the
/// curves move by about 1e-6 relative, the counts not at all on the bench's 295K vertices) and
/// the sums are taken in the second half step, in double (BM_feature_bilateral/3/3: 1.8 s →
/// 0.7 s for 201 pairs); each row is summed in SSE2 registers, in the scalar order (in a stack
/// array each add waited on the previous store: 200 pairs on 295K vertices at -O3 0.83-0.98 s
/// → 0.66-0.85 s, the same curves). The returned mesh is recomputed by taubin_smooth in double.
/// Deterministic: per-vertex arithmetic, sums folded in fixed chunks (parallel_reduce).
/// The probes are drawn vertex by vertex in `draw_order` (a permutation of the vertices; empty:
/// index order), so that a caller holding the vertices in an order of its own can keep the draws of
/// the user's order (select_by_risk).
/// @pre `active` holds every vertex with a neighbour (so it is closed under neighbours) and
///      counted[v] != 0 only for v in `active`: taubin_risk_curves builds them so.
template <std::size_t probes>
TaubinRiskCurves taubin_risk_curves_with(const std::vector<Vec3>& y, const MeshTopology& topo,
                                         const std::vector<Index>& active, const std::vector<std::uint8_t>& counted,
                                         const std::vector<Vec3>& normals, Scalar sigma, std::size_t max_steps,
                                         const TaubinParams& params, Progress& progress,
                                         const std::vector<Index>& draw_order) {
    constexpr std::size_t stride = 3 + probes;  // x, y, z, then the probes
    if (!draw_order.empty() && draw_order.size() != y.size())
        throw invalid_input("kintsugi::detail::taubin_risk_curves: draw_order has " + std::to_string(draw_order.size()) +
                            " entries for " + std::to_string(y.size()) + " vertices");
    const std::size_t m = active.size();
    TaubinRiskCurves out;
    // Local numbering: the moving vertices along a Morton curve. A neighbour of a moving vertex
    // moves too (it has a neighbour), so the local arrays hold every value a step reads.
    std::vector<Index> order(m);
    {
        const MortonBox box(y);
        const std::vector<Index> by_code = morton_order(m, box, [&](Index i) { return y[active[i]]; });
        for (std::size_t k = 0; k < m; ++k) order[k] = active[by_code[k]];
    }
    // Local indices are 32-bit (2^32 moving vertices would take hundreds of GB before this).
    std::vector<Index> local(y.size(), Index(-1));
    for (std::size_t k = 0; k < m; ++k) local[order[k]] = static_cast<Index>(k);
    std::vector<std::size_t> offsets(m + 1, 0);
    for (std::size_t k = 0; k < m; ++k) offsets[k + 1] = offsets[k] + topo.vertex_neighbors(order[k]).size();
    std::vector<std::uint32_t> nbr(offsets[m]);
    parallel_for(0, m, [&](std::size_t k) {
        std::size_t o = offsets[k];
        for (Index u : topo.vertex_neighbors(order[k])) nbr[o++] = static_cast<std::uint32_t>(local[u]);  // the one-ring's order: same sums
    }, 4096);
    // Per local vertex: state (position relative to the box centre, then the probes); for the
    // sums, n, n·y (in double, from the stored floats: the residual at k = 0 is exactly 0), the
    // initial probes and whether it is counted (a normal). Positions are taken relative to the
    // centre in double before the cast, so their rounding is relative to the extent, not to
    // the distance from the origin (a scan 5e6 from it with an extent of 100 would otherwise
    // lose the noise). The probes' seed sequence follows `draw_order`.
    BoundingBox box;
    for (Index v : active) box.extend(y[v]);
    const Vec3 centre = box.center();
    std::vector<float> state(stride * m, 0), next(stride * m, 0);
    std::vector<float> nrm(3 * m, 0), z0(probes * m, 0);
    std::vector<Scalar> ny(m, 0);
    std::vector<std::uint8_t> is_counted(m, 0);
    for (std::size_t k = 0; k < m; ++k)
        for (int c = 0; c < 3; ++c) state[stride * k + c] = static_cast<float>(y[order[k]][c] - centre[c]);
    auto dot_n = [&](std::size_t k, const float* s) {
        return Scalar(nrm[3 * k]) * s[0] + Scalar(nrm[3 * k + 1]) * s[1] + Scalar(nrm[3 * k + 2]) * s[2];
    };
    std::uint64_t seed = 0x9E3779B97F4A7C15ull;
    for (std::size_t i = 0; i < y.size(); ++i) {
        const Index v = draw_order.empty() ? static_cast<Index>(i) : draw_order[i];
        if (!counted[v]) continue;
        const Index k = local[v];
        is_counted[k] = 1;
        ++out.moved;
        for (std::size_t p = 0; p < probes; ++p) {
            z0[probes * k + p] = state[stride * k + 3 + p] = static_cast<float>(rademacher(seed));
        }
        for (int c = 0; c < 3; ++c) nrm[3 * k + c] = static_cast<float>(normals[v][c]);
        ny[k] = dot_n(k, &state[stride * k]);
    }
    using Sums = std::array<Scalar, 3>;
    auto add_sums = [&](std::size_t k, const float* s, Sums& acc) {
        const Scalar h = dot_n(k, s) - ny[k];
        acc[0] += h * h;
        for (std::size_t p = 0; p < probes; ++p) {
            acc[1] += Scalar(z0[probes * k + p]) * s[3 + p];
            acc[2] += Scalar(s[3 + p]) * s[3 + p];
        }
    };
    auto record = [&](const Sums& sums) {
        out.residual.push_back(sums[0]);
        out.trace.push_back(sums[1] / static_cast<Scalar>(probes));
        out.trace_sq.push_back(sums[2] / static_cast<Scalar>(probes));
    };
    // One half step from `state` into `next` over local vertices [first, last); with `acc`, the
    // sums of the new values of the counted ones.
    auto half_step = [&](Scalar factor, std::size_t first, std::size_t last, Sums* acc) {
        const float f = static_cast<float>(factor);
        for (std::size_t k = first; k < last; ++k) {
            const std::size_t deg = offsets[k + 1] - offsets[k];
            const float* s = &state[stride * k];
            float* t = &next[stride * k];
            const float w = 1.0f / static_cast<float>(deg);
#if defined(__SSE2__)
            // Lane by lane the scalar code's operations in its order (the same bits); as a
            // std::array in memory, each neighbour's add waited on the previous one's store
            // (half the sweep's time, 2026-12-07).
            // Groups of four from the row's start, and one more ending at its end (overlapping
            // the last group; the lanes both compute get the same value).
            static_assert(stride >= 4, "the last group of four must lie within the row");
            constexpr std::size_t quads = stride / 4, tail = stride - 4;
            __m128 sum[quads + 1];
            for (std::size_t q = 0; q <= quads; ++q) sum[q] = _mm_setzero_ps();
            for (std::size_t o = offsets[k]; o < offsets[k + 1]; ++o) {
                const float* u = &state[stride * nbr[o]];
                for (std::size_t q = 0; q < quads; ++q) sum[q] = _mm_add_ps(sum[q], _mm_loadu_ps(u + 4 * q));
                sum[quads] = _mm_add_ps(sum[quads], _mm_loadu_ps(u + tail));
            }
            const __m128 fv = _mm_set1_ps(f), wv = _mm_set1_ps(w);
            auto put = [&](std::size_t at, __m128 sq) {
                const __m128 sv = _mm_loadu_ps(s + at);
                _mm_storeu_ps(t + at, _mm_add_ps(sv, _mm_mul_ps(fv, _mm_sub_ps(_mm_mul_ps(sq, wv), sv))));
            };
            put(tail, sum[quads]);
            for (std::size_t q = 0; q < quads; ++q) put(4 * q, sum[q]);
#else
            std::array<float, stride> sum{};
            for (std::size_t o = offsets[k]; o < offsets[k + 1]; ++o) {
                const float* u = &state[stride * nbr[o]];
                for (std::size_t c = 0; c < stride; ++c) sum[c] += u[c];
            }
            for (std::size_t c = 0; c < stride; ++c) t[c] = s[c] + f * (sum[c] * w - s[c]);
#endif
            if (acc && is_counted[k]) add_sums(k, t, *acc);
        }
    };
    {
        Sums s0{0, 0, 0};
        for (std::size_t k = 0; k < m; ++k)
            if (is_counted[k]) add_sums(k, &state[stride * k], s0);
        record(s0);
    }
    if (m == 0 || out.moved == 0) return out;
    std::size_t best = 0;
    for (std::size_t k = 1; k <= max_steps; ++k) {
        progress.update(static_cast<double>(k) / static_cast<double>(max_steps));
        parallel_for(0, (m + 1023) / 1024, [&](std::size_t b) {
            half_step(params.lambda, 1024 * b, std::min(m, 1024 * b + 1024), nullptr);
        }, 1);
        state.swap(next);
        const Sums sums = parallel_reduce(
            0, m, Sums{0, 0, 0},
            [&](std::size_t first, std::size_t last, Sums acc) {
                half_step(params.mu, first, last, &acc);
                return acc;
            },
            [](Sums a, Sums b) { return Sums{a[0] + b[0], a[1] + b[1], a[2] + b[2]}; });
        state.swap(next);
        record(sums);
        if (taubin_risk(out, k, sigma) < taubin_risk(out, best, sigma)) best = k;
        if (k > best + std::max<std::size_t>(20, best / 2)) break;
    }
    return out;
}

inline TaubinRiskCurves taubin_risk_curves(const std::vector<Vec3>& y, const MeshTopology& topo,
                                           const std::vector<Vec3>& normals, Scalar sigma, std::size_t max_steps,
                                           const TaubinParams& params, Progress& progress,
                                           const std::vector<Index>& draw_order = {}) {
    const std::vector<Index> active = movable_vertices(topo, y.size(), {}).vertices;
    const std::vector<std::uint8_t> counted = risk_counted(topo, normals);
    const std::size_t n = std::max<std::size_t>(static_cast<std::size_t>(std::count(counted.begin(), counted.end(), 1)), 1);
    const std::size_t want = ((std::size_t{1} << 17) + n - 1) / n;  // rounded up
    auto run = [&]<std::size_t P>() {
        return taubin_risk_curves_with<P>(y, topo, active, counted, normals, sigma, max_steps, params, progress,
                                          draw_order);
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
