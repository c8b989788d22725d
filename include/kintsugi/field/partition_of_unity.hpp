// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file partition_of_unity.hpp
/// @brief Partition-of-unity blends of local functions, f = Σ w_i g_i / Σ w_i, shared by
/// the methods that blend local fits:
/// - PUAccumulator: the blend itself, f and ∇f = (Σ(∇w_i g_i + w_i ∇g_i) Σw - Σw_i g_i Σ∇w_i) / (Σw)²,
///   from the weights and local functions the caller visits;
/// - the weights, C¹ and zero on the border of their support: ball_weight, the b2 weight
///   w(x) = b2(1.5 |x - c| / r) of Nagai, Ohtake, Suzuki, "Outlier robust implicit surface
///   reconstruction using graph-cut" (IPSJ Journal 2011, eq. 1 and 5), and box_weight,
///   Π_k (1 - t_k²)² over a cube (t_k = |x_k - c_k| / half side);
/// - PartitionOfUnity: balls indexed by a uniform grid, so that a query visits only the
///   balls near it, blended with ball_weight and PUAccumulator (PUField,
///   reconstruct/pu_field.hpp). The octree RBF (rbf/rbf_octree.hpp) blends its cells'
///   overlap boxes with box_weight and PUAccumulator, found by descending its octree.
///
/// @code
/// #include <kintsugi/field/partition_of_unity.hpp>
/// kintsugi::PartitionOfUnity pu(balls, cube_min, cube_side);   // balls: std::vector<PUBall>
/// // f(x) = Σ w_i(x) g_i(x) / Σ w_i(x) with your own local functions g_i:
/// kintsugi::Vec3 grad;
/// double f = pu.blend(x, [&](std::size_t i, const kintsugi::Vec3& y, kintsugi::Vec3* g) {
///     if (g) *g = normal[i];                       // ∇g_i(y), asked only for the gradient
///     return normal[i].dot(y - origin[i]);         // g_i(y)
/// }, nullptr, &grad);                              // NaN where no ball covers x
/// @endcode
///
/// Used by PUField (reconstruct/pu_field.hpp, linear local functions); any local
/// approximant (quadrics, RBF patches of octree cells) blends the same way. With
/// supports found by your own index (an octree of boxes, say):
///
/// @code
/// kintsugi::PUAccumulator acc(/*gradient=*/true);
/// for (const Cell& c : cells_whose_box_holds(x)) {           // your own search
///     kintsugi::Vec3 dw, dg;
///     const double w = kintsugi::box_weight(x, c.center, c.half, &dw);
///     acc.add(w, dw, c.local(x, &dg), dg);
/// }
/// if (acc.covered()) { double f = acc.value(); kintsugi::Vec3 g = acc.gradient(); }
/// @endcode

#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

/// Quadratic B-spline b2(t) of Nagai et al. eq. 5: 3/4 - t² on [0, 0.5),
/// (1.5 - t)²/2 on [0.5, 1.5), 0 beyond. C¹, support [0, 1.5).
[[nodiscard]] inline Scalar b2_weight(Scalar t) {
    if (t >= Scalar(1.5)) return 0;
    if (t >= Scalar(0.5)) return (Scalar(1.5) - t) * (Scalar(1.5) - t) / 2;
    return Scalar(0.75) - t * t;
}
/// Derivative of b2_weight.
[[nodiscard]] inline Scalar b2_weight_derivative(Scalar t) {
    if (t >= Scalar(1.5)) return 0;
    if (t >= Scalar(0.5)) return t - Scalar(1.5);
    return -2 * t;
}

/// @brief Accumulates one partition-of-unity blend at a point x: add() each support i
/// whose weight w_i(x) is positive, with its local function's value g_i(x); then
/// f(x) = Σ w_i g_i / Σ w_i and, when constructed with gradient = true and given ∇w_i
/// and ∇g_i, ∇f(x) = (Σ(∇w_i g_i + w_i ∇g_i) Σw - Σ w_i g_i Σ∇w_i) / (Σw)². The sums run
/// in the order of the add() calls (the result's rounding depends on that order only).
class PUAccumulator {
public:
    /// gradient: whether the gradient sums are kept (the 4-argument add()).
    explicit PUAccumulator(bool gradient = false) : gradient_(gradient) {}
    /// Adds w g (value only).
    void add(Scalar w, Scalar g) {
        W_ += w;
        F_ += w * g;
    }
    /// Adds w g with ∇w and ∇g (the gradient sums only when constructed with gradient = true).
    void add(Scalar w, const Vec3& dw, Scalar g, const Vec3& dg) {
        W_ += w;
        F_ += w * g;
        if (gradient_) {
            dW_ += dw;
            dF_ += dw * g + w * dg;
        }
    }
    /// Whether some positive weight was added (Σw > 0); f is undefined otherwise.
    [[nodiscard]] bool covered() const { return W_ > 0; }
    /// Σ w_i g_i / Σ w_i. @pre covered()
    [[nodiscard]] Scalar value() const { return F_ / W_; }
    /// ∇f. @pre covered() and constructed with gradient = true
    [[nodiscard]] Vec3 gradient() const { return (dF_ * W_ - F_ * dW_) / (W_ * W_); }
    /// Σ w_i.
    [[nodiscard]] Scalar weight_sum() const { return W_; }

private:
    bool gradient_ = false;
    Scalar W_ = 0, F_ = 0;
    Vec3 dW_ = Vec3::Zero(), dF_ = Vec3::Zero();
};

namespace detail {
/// a b2(1.5 d / r) and, into grad when not null, its gradient, at diff = x - c with
/// d = |diff| (inv_r = 1 / r). Shared by ball_weight and PartitionOfUnity::blend, which
/// has d and 1 / r at hand.
[[nodiscard]] inline Scalar b2_ball_weight(const Vec3& diff, Scalar d, Scalar inv_r, Scalar a, Vec3* grad) {
    const Scalar t = Scalar(1.5) * d * inv_r;
    if (grad) *grad = d > 0 ? Vec3(a * b2_weight_derivative(t) * Scalar(1.5) * inv_r / d * diff) : Vec3::Zero();
    return a * b2_weight(t);
}
}  // namespace detail

/// @brief The b2 weight of the ball (center, radius): b2(1.5 |x - center| / radius),
/// 3/4 at the centre, positive on the open ball, C¹, 0 from its sphere on (Nagai et al.
/// eq. 5). PUField's weight (through PartitionOfUnity).
/// @param radius > 0 (not checked here; PartitionOfUnity checks its balls).
/// @param gradient null, or receives ∇w(x) (0 outside the ball and at its centre).
[[nodiscard]] inline Scalar ball_weight(const Vec3& x, const Vec3& center, Scalar radius, Vec3* gradient = nullptr) {
    const Vec3 diff = x - center;
    const Scalar d2 = diff.squaredNorm();
    if (!(d2 < radius * radius)) {
        if (gradient) *gradient = Vec3::Zero();
        return 0;
    }
    return detail::b2_ball_weight(diff, std::sqrt(d2), 1 / radius, 1, gradient);
}

/// @brief The weight of the open cube with centre `center` and half side `half`:
/// Π_k (1 - t_k²)², t_k = |x_k - center_k| / half. 1 at the centre, positive inside,
/// C¹, 0 with its gradient on the cube's faces and outside. The octree RBF's weight
/// over the overlap boxes of its cells (rbf/rbf_octree.hpp): unlike a ball's, the cube
/// weights of a tiling cover every point of it without gaps at the corners for any
/// overlap factor above 1.
/// @param half > 0 (not checked here).
/// @param gradient null, or receives ∇w(x) (0 outside the cube).
[[nodiscard]] inline Scalar box_weight(const Vec3& x, const Vec3& center, Scalar half, Vec3* gradient = nullptr) {
    Scalar t[3];
    for (int k = 0; k < 3; ++k) {
        t[k] = std::abs(x[k] - center[k]) / half;
        if (!(t[k] < 1)) {
            if (gradient) *gradient = Vec3::Zero();
            return 0;
        }
    }
    Vec3 s, ds;
    for (int k = 0; k < 3; ++k) {
        const Scalar q = 1 - t[k] * t[k];
        s[k] = q * q;
        ds[k] = -4 * t[k] * q / half * (x[k] >= center[k] ? 1 : -1);
    }
    if (gradient) *gradient = Vec3(ds[0] * s[1] * s[2], s[0] * ds[1] * s[2], s[0] * s[1] * ds[2]);
    return s.prod();
}

/// The support of one local function: the open ball (center, radius).
struct PUBall {
    Vec3 center = Vec3::Zero();
    Scalar radius = 0;  ///< > 0, in the caller's units
};

namespace detail {
/// Squared distance from c to the box [lo, hi] (0 inside).
[[nodiscard]] inline Scalar box_squared_distance(const Vec3& c, const Vec3& lo, const Vec3& hi) {
    Scalar d2 = 0;
    for (int k = 0; k < 3; ++k) {
        const Scalar t = c[k] < lo[k] ? lo[k] - c[k] : (c[k] > hi[k] ? c[k] - hi[k] : Scalar(0));
        d2 += t * t;
    }
    return d2;
}
}  // namespace detail

/// Balls with the weights w_i(x) = b2(1.5 |x - c_i| / r_i) (positive on the open ball,
/// C¹, zero outside), indexed by a uniform grid over a cube; blends local functions
/// g_i into f(x) = Σ a_i w_i(x) g_i(x) / Σ a_i w_i(x). Immutable; every query is const
/// and thread-safe. Memory: the balls plus one entry per (grid cell, ball) overlap.
class PartitionOfUnity {
public:
    PartitionOfUnity() = default;

    /// @brief Indexes `balls` over the cube [cube_min, cube_min + cube_side]³, the
    /// domain of blend() (a ball may reach outside it).
    /// @param balls centres and radii (caller's units); at least one.
    /// @param cube_min, cube_side the cube of the queries; cube_side > 0.
    /// @throws invalid_input for no ball, a NaN/Inf centre, a radius that is not
    ///         positive and finite, or a bad cube.
    PartitionOfUnity(std::vector<PUBall> balls, const Vec3& cube_min, Scalar cube_side)
        : PartitionOfUnity(build(std::move(balls), cube_min, cube_side, [](double) {})) {}

    /// Same as the constructor; on_progress(fraction in [0, 1]) is called between
    /// blocks of balls on the calling thread and may throw to stop the build.
    template <class OnProgress>
    [[nodiscard]] static PartitionOfUnity build(std::vector<PUBall> balls, const Vec3& cube_min, Scalar cube_side,
                                                OnProgress&& on_progress);

    [[nodiscard]] std::size_t size() const { return balls_.size(); }
    [[nodiscard]] bool empty() const { return balls_.empty(); }
    [[nodiscard]] PUBall ball(std::size_t i) const { return {balls_[i].c, balls_[i].r}; }
    [[nodiscard]] Vec3 cube_min() const { return center_ - Vec3::Constant(half_); }
    [[nodiscard]] Scalar cube_side() const { return 2 * half_; }
    /// Grid cells per side (a power of two in [4, 128], the cell side near the median radius).
    [[nodiscard]] int grid_resolution() const { return grid_; }
    /// Number of (grid cell, ball) overlaps stored.
    [[nodiscard]] std::size_t overlaps() const { return cell_balls_.size(); }

    /// w_i(x) of ball i (0 outside the ball): ball_weight(x, centre, radius).
    [[nodiscard]] Scalar weight(std::size_t i, const Vec3& x) const {
        const auto& s = balls_[i];
        const Vec3 diff = x - s.c;
        const Scalar d2 = diff.squaredNorm();
        return d2 >= s.r2 ? Scalar(0) : detail::b2_ball_weight(diff, std::sqrt(d2), s.inv_r, 1, nullptr);
    }

    /// Calls visit(i) for every ball whose open ball contains x, in increasing i.
    /// Nothing when x lies outside the cube.
    template <class Visit>
    void for_each_ball(const Vec3& x, Visit&& visit) const {
        const std::size_t cell = cell_of(x);
        if (cell == npos) return;
        for (std::size_t k = cell_offsets_[cell], e = cell_offsets_[cell + 1]; k < e; ++k) {
            const auto& s = balls_[cell_balls_[k]];
            if ((x - s.c).squaredNorm() < s.r2) visit(static_cast<std::size_t>(cell_balls_[k]));
        }
    }

    /// @brief f(x) = Σ a_i w_i(x) g_i(x) / Σ a_i w_i(x) over the balls containing x.
    /// @param local g_i: called as local(i, x, Vec3* grad) -> Scalar; writes ∇g_i(x)
    ///        into *grad when grad is not null (only when `gradient` is not null).
    /// @param factors null (all 1) or one factor a_i >= 0 per ball; 0 drops ball i.
    /// @param gradient null, or receives ∇f(x) (NaN where f is NaN).
    /// @return f(x); NaN outside the cube, for a NaN x, or where no ball with a_i > 0
    ///         contains x.
    template <class Local>
    [[nodiscard]] Scalar blend(const Vec3& x, Local&& local, const Scalar* factors = nullptr,
                               Vec3* gradient = nullptr) const {
        constexpr Scalar nan = std::numeric_limits<Scalar>::quiet_NaN();
        if (gradient) *gradient = Vec3::Constant(nan);
        const std::size_t cell = cell_of(x);
        if (cell == npos) return nan;
        PUAccumulator acc(gradient != nullptr);
        Vec3 gw = Vec3::Zero(), lg = Vec3::Zero();
        const auto* ids = cell_balls_.data();
        for (std::size_t k = cell_offsets_[cell], e = cell_offsets_[cell + 1]; k < e; ++k) {
            const auto& s = balls_[ids[k]];
            const Vec3 diff = x - s.c;
            const Scalar d2 = diff.squaredNorm();
            if (d2 >= s.r2) continue;
            const Scalar a = factors ? factors[ids[k]] : Scalar(1);
            if (a == 0) continue;
            const Scalar w = detail::b2_ball_weight(diff, std::sqrt(d2), s.inv_r, a, gradient ? &gw : nullptr);
            const Scalar g = local(static_cast<std::size_t>(ids[k]), x, gradient ? &lg : nullptr);
            acc.add(w, gw, g, lg);
        }
        if (!acc.covered()) return nan;
        if (gradient) *gradient = acc.gradient();
        return acc.value();
    }

private:
    static constexpr std::size_t npos = static_cast<std::size_t>(-1);
    struct Ball {
        Vec3 c;
        Scalar r, inv_r, r2;
    };

    [[nodiscard]] std::size_t cell_of(const Vec3& x) const {
        if (balls_.empty()) return npos;
        if (!x.allFinite() || ((x - center_).array().abs() > half_).any()) return npos;
        const int G = grid_;
        std::size_t cell = 0;
        for (int k = 2; k >= 0; --k) {
            const int i = std::min(G - 1, static_cast<int>((x[k] - center_[k] + half_) * to_grid_));
            cell = cell * static_cast<std::size_t>(G) + static_cast<std::size_t>(std::max(0, i));
        }
        return cell;
    }

    std::vector<Ball> balls_;
    Vec3 center_ = Vec3::Zero();  ///< centre of the cube
    Scalar half_ = 0;             ///< half its side
    Scalar to_grid_ = 0;          ///< G / side
    int grid_ = 1;
    std::vector<std::size_t> cell_offsets_;   ///< CSR over the G³ cells (x fastest)
    std::vector<std::uint32_t> cell_balls_;   ///< per cell, the balls meeting it, increasing
};

template <class OnProgress>
PartitionOfUnity PartitionOfUnity::build(std::vector<PUBall> balls, const Vec3& cube_min, Scalar cube_side,
                                         OnProgress&& on_progress) {
    const std::string fn = "kintsugi::PartitionOfUnity: ";
    if (balls.empty()) throw invalid_input(fn + "no ball given; give at least one support");
    if (balls.size() >= (std::size_t{1} << 32))
        throw invalid_input(fn + std::to_string(balls.size()) + " balls; at most 2^32 - 1");
    if (!cube_min.allFinite() || !(cube_side > 0) || !std::isfinite(cube_side))
        throw invalid_input(fn + "the cube needs a finite corner and a positive finite side");
    for (std::size_t i = 0; i < balls.size(); ++i)
        if (!balls[i].center.allFinite() || !(balls[i].radius > 0) || !std::isfinite(balls[i].radius))
            throw invalid_input(fn + "ball " + std::to_string(i) +
                                " needs a finite centre and a positive finite radius");
    PartitionOfUnity pu;
    pu.half_ = cube_side / 2;
    pu.center_ = cube_min + Vec3::Constant(pu.half_);
    const std::size_t n = balls.size();
    pu.balls_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        const Scalar r = balls[i].radius;
        pu.balls_[i] = {balls[i].center, r, 1 / r, r * r};
    }
    {
        std::vector<Scalar> radii(n);
        for (std::size_t i = 0; i < n; ++i) radii[i] = balls[i].radius;
        std::nth_element(radii.begin(), radii.begin() + static_cast<std::ptrdiff_t>(n / 2), radii.end());
        const Scalar r_med = radii[n / 2];
        // grid cell side ~ the median radius, G a power of two in [4, 128]
        int G = 4;
        while (G < 128 && cube_side / (2 * G) > r_med) G *= 2;
        pu.grid_ = G;
    }
    const int G = pu.grid_;
    pu.to_grid_ = G / cube_side;
    const std::size_t n_grid = static_cast<std::size_t>(G) * G * G;
    // Grid cell -> balls meeting the cell: per block of balls, in parallel; then a
    // counting sort by cell in ball order (deterministic).
    const std::size_t block = 2048;
    const std::size_t n_blocks = (n + block - 1) / block;
    std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> pairs(n_blocks);
    const std::size_t blocks_per_round = 16;
    const Scalar h = cube_side / G;
    for (std::size_t b0 = 0; b0 < n_blocks; b0 += blocks_per_round) {
        const std::size_t b1 = std::min(n_blocks, b0 + blocks_per_round);
        parallel_for(b0, b1, [&](std::size_t b) {
            auto& out = pairs[b];
            for (std::size_t i = b * block, e = std::min(n, (b + 1) * block); i < e; ++i) {
                const auto& s = pu.balls_[i];
                std::array<int, 3> lo{}, hi{};
                for (int k = 0; k < 3; ++k) {
                    lo[k] = std::clamp(static_cast<int>(std::floor((s.c[k] - s.r - cube_min[k]) * pu.to_grid_)), 0, G - 1);
                    hi[k] = std::clamp(static_cast<int>(std::floor((s.c[k] + s.r - cube_min[k]) * pu.to_grid_)), 0, G - 1);
                }
                for (int z = lo[2]; z <= hi[2]; ++z)
                    for (int y = lo[1]; y <= hi[1]; ++y)
                        for (int x = lo[0]; x <= hi[0]; ++x) {
                            const Vec3 bl(x * h + cube_min[0], y * h + cube_min[1], z * h + cube_min[2]);
                            if (detail::box_squared_distance(s.c, bl, bl + Vec3::Constant(h)) >= s.r2) continue;
                            out.push_back({static_cast<std::uint32_t>((static_cast<std::size_t>(z) * G + y) * G + x),
                                           static_cast<std::uint32_t>(i)});
                        }
            }
        }, 1);
        on_progress(static_cast<double>(b1) / static_cast<double>(n_blocks));
    }
    pu.cell_offsets_.assign(n_grid + 1, 0);
    std::size_t total = 0;
    for (const auto& v : pairs) {
        total += v.size();
        for (const auto& pr : v) ++pu.cell_offsets_[pr.first + 1];
    }
    for (std::size_t c = 0; c < n_grid; ++c) pu.cell_offsets_[c + 1] += pu.cell_offsets_[c];
    pu.cell_balls_.resize(total);
    std::vector<std::size_t> fill(pu.cell_offsets_.begin(), pu.cell_offsets_.end() - 1);
    for (auto& v : pairs) {
        for (const auto& pr : v) pu.cell_balls_[fill[pr.first]++] = pr.second;
        std::vector<std::pair<std::uint32_t, std::uint32_t>>().swap(v);
    }
    return pu;
}

}  // namespace kintsugi
