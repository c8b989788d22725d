// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file rbf_octree.hpp
/// @brief Octree-partitioned triharmonic RBF implicit surfaces: Miura, Sone, Masuda,
/// "Octree-based RBF reconstruction" (the digest in METHODS.md §2), with offsets after
/// Carr et al. (SIGGRAPH 2001) and, beyond the paper, a partition-of-unity blend of the
/// overlapping cells so that cell borders leave no seams.
/// Method, departures and measurements: docs/methods/rbf_octree.md.
///
/// @code
/// #include <kintsugi/rbf/rbf_octree.hpp>
/// auto fit = kintsugi::RBFOctreeField::build(kintsugi::with_normals(pts, nrm), {.n_max = 250});
/// double f = fit.field(x);                 // < 0 inside, > 0 outside, ≈ signed distance
/// kintsugi::Vec3 g = fit.field.gradient(x);
/// auto rec = kintsugi::reconstruct_rbf_octree(kintsugi::with_normals(pts, nrm), {.resolution = 256});
/// // rec.mesh, rec.stats.live_cells, rec.timings
/// @endcode

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/field/isosurface.hpp>
#include <kintsugi/rbf/detail/rbf_solve.hpp>
#include <kintsugi/spatial/kd_tree.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

/// Parameters of RBFOctreeField::build and reconstruct_rbf_octree (aggregate; field
/// order is API, append only).
struct RBFOctreeParams {
    /// n_max >= 10: a cell splits into 8 while more centres (points and offsets) are
    /// assigned to it. 250: the paper's optimum (time ∝ (a²/6 + c0 a + c1 + c2/a) N).
    std::size_t n_max = 250;
    /// Overlap α >= 1: a cell takes the centres within α/2 x its side of its centre
    /// along each axis. The paper's 1.3-1.4 balances seams against time.
    Scalar overlap = 1.35;
    /// Activity β >= 1: a cell with no on-surface point in its β-enlarged box is dead
    /// (no RBF) unless the surface may cross it between samples (docs). The paper's 1.05.
    Scalar activity = 1.05;
    /// Side of the root cubes tiling the bounding box, as a fraction (0, 1] of its
    /// longest side (the paper: "smaller than 1" in the unit cube). 1: one root.
    Scalar root_size = 1;
    /// Offset distance d_i = offset_scale x the mean distance from p_i to its 6 nearest
    /// points (> 0), then halved while another point is nearer to p_i ± d_i n_i than
    /// p_i is (Carr et al. 2001). 1: offsets one sample spacing off the surface.
    Scalar offset_scale = 1;
    /// Smoothing λ >= 0 (Carr et al.'s regularised fit): added to the diagonal of each
    /// cell's interpolation matrix in the cell's normalised coordinates (its overlap
    /// box is [-1, 1]³). 0 interpolates every point; 1e-3 to 1e-1 for noisy scans.
    Scalar smoothing = 0;
    /// Cubes along the longest side of the bounding box for reconstruct_rbf_octree's
    /// polygonisation, in [8, 4096]. Ignored by RBFOctreeField::build.
    int resolution = 256;
    /// true (default): f blends the RBFs of every live cell whose overlap box holds x
    /// with C¹ weights (no seams); false: the paper's evaluation, the RBF of the cell
    /// holding x alone (seams of the size of the fit error at cell faces).
    bool blend = true;
    /// Points closer than this fraction of the bounding-box diagonal to an earlier
    /// point are merged into it (>= 0): near-duplicates would make a system singular.
    Scalar merge_distance = 1e-6;
    /// Progress callback and cancellation.
    RunControl control{};
};

/// Counts of one fit (RBFOctreeResult, RBFReconstructResult).
struct RBFOctreeStats {
    std::size_t points = 0;          ///< input points
    std::size_t merged_points = 0;   ///< dropped as (near-)duplicates of an earlier point
    std::size_t offset_points = 0;   ///< offset centres (±d), at most 2 per kept point
    std::size_t shrunk_offsets = 0;  ///< offsets whose d was halved at least once
    std::size_t dropped_offsets = 0; ///< offsets still wrong after 8 halvings, left out
    std::size_t cells = 0;           ///< octree leaves
    std::size_t live_cells = 0;      ///< leaves with an RBF
    std::size_t dead_cells = 0;      ///< leaves without (no on-surface point in the β box)
    std::size_t max_points_per_cell = 0;   ///< centres of the largest live system
    double mean_points_per_cell = 0;       ///< mean centres per live cell
    std::size_t padded_cells = 0;    ///< live cells with < 20 centres, padded with the nearest ones
    std::size_t ill_conditioned_cells = 0; ///< systems that needed jitter or least squares
    int depth = 0;                   ///< deepest leaf level below the roots
};

/// One leaf of the octree (caller's coordinates).
struct RBFCell {
    Vec3 min = Vec3::Zero();
    Scalar side = 0;
    bool live = false;
    std::size_t centres = 0;  ///< centres of its system (0 when dead)
};

class RBFOctreeField;
struct RBFOctreeResult;
namespace detail {
RBFOctreeResult rbf_octree_fit(std::vector<Vec3> points, std::vector<Vec3> normals, const RBFOctreeParams& params);
}

namespace detail {

/// Shared, immutable data of an RBFOctreeField, in the scaled frame.
struct RBFOctreeData {
    ScaleFrame frame;
    Scalar alpha = 1.35;
    bool blend = true;
    std::vector<Vec3> centres;           ///< points and offsets
    std::shared_ptr<const KdTree> surface;  ///< on-surface points (dead cells, outside the roots)
    std::vector<Vec3> surface_normals;   ///< unit, outward
    // Octree: nodes with 8 consecutive children; roots tile [root_min, + root_count * root_side].
    struct Node {
        Vec3 min;
        Scalar side;
        std::int64_t child = -1;  ///< first of 8 children, -1 for a leaf
        std::int64_t leaf = -1;   ///< index into leaves for a leaf
    };
    std::vector<Node> nodes;
    Vec3 root_min = Vec3::Zero();
    Scalar root_side = 1;
    std::array<int, 3> root_count{1, 1, 1};
    struct Leaf {
        std::size_t node = 0;
        bool live = false;
        Scalar dead_sign = 1;                  ///< dead cells: +1 outside, -1 inside
        std::size_t begin = 0, end = 0;        ///< range in ids / weights (live)
        Eigen::Vector4d poly = Eigen::Vector4d::Zero();
    };
    std::vector<Leaf> leaves;
    std::vector<std::uint32_t> ids;  ///< centre indices of every live cell, concatenated
    std::vector<Scalar> weights;     ///< their RBF weights

    [[nodiscard]] Vec3 node_center(const Node& n) const { return n.min + Vec3::Constant(n.side / 2); }

    /// Value (scaled frame) and gradient of live leaf l's RBF at x.
    Scalar leaf_value(const Leaf& l, const Vec3& x, Vec3* grad) const {
        const Node& n = nodes[l.node];
        const Scalar h = alpha * n.side / 2;
        const Scalar inv = 1 / h;
        const Vec3 u = (x - node_center(n)) * inv;
        Scalar g = l.poly[0] + l.poly[1] * u.x() + l.poly[2] * u.y() + l.poly[3] * u.z();
        Vec3 dg(l.poly[1], l.poly[2], l.poly[3]);
        for (std::size_t k = l.begin; k < l.end; ++k) {
            const Vec3 d = (x - centres[ids[k]]) * inv;
            const Scalar r = d.norm();
            g += weights[k] * r * r * r;
            if (grad) dg += (3 * weights[k] * r) * d;
        }
        if (grad) *grad = dg;
        return g * h;
    }

    /// The signed distance to the nearest on-surface point, signed by its normal (where
    /// no RBF is defined); for dead cells the cell's sign when given.
    Scalar far_value(const Vec3& x, const Scalar* sign, Vec3* grad) const {
        const Neighbor nb = surface->nearest(x);
        const Vec3 d = x - surface->point(nb.index);
        const Scalar dist = std::sqrt(nb.squared_distance);
        const Scalar s = sign ? *sign : (surface_normals[nb.index].dot(d) >= 0 ? Scalar(1) : Scalar(-1));
        if (grad) *grad = dist > 0 ? Vec3(s * d / dist) : Vec3(s * surface_normals[nb.index]);
        return s * dist;
    }

    /// The root holding x (clamped indices) and whether x lies inside the tiling.
    [[nodiscard]] bool root_of(const Vec3& x, std::array<int, 3>& r) const {
        bool inside = true;
        for (int k = 0; k < 3; ++k) {
            const Scalar t = std::floor((x[k] - root_min[k]) / root_side);
            if (!(t >= 0 && t < root_count[k])) inside = false;
            r[k] = static_cast<int>(std::clamp<Scalar>(t, 0, root_count[k] - 1));
        }
        return inside;
    }
    [[nodiscard]] std::size_t root_index(int i, int j, int k) const {
        return (static_cast<std::size_t>(k) * root_count[1] + j) * root_count[0] + i;
    }

    /// The leaf holding x (x inside the tiling).
    [[nodiscard]] const Leaf& locate(const Vec3& x, const std::array<int, 3>& r) const {
        std::size_t c = root_index(r[0], r[1], r[2]);
        while (nodes[c].child >= 0) {
            const Vec3 mid = node_center(nodes[c]);
            const std::size_t o = (x.x() >= mid.x() ? 1u : 0u) | (x.y() >= mid.y() ? 2u : 0u) | (x.z() >= mid.z() ? 4u : 0u);
            c = static_cast<std::size_t>(nodes[c].child) + o;
        }
        return leaves[static_cast<std::size_t>(nodes[c].leaf)];
    }

    /// Whether x lies in node n's box enlarged to `factor` x its side, and the weight
    /// coordinates t_k = |x_k - c_k| / (factor side / 2).
    [[nodiscard]] bool in_box(const Node& n, const Vec3& x, Scalar factor, Vec3& t) const {
        const Scalar h = factor * n.side / 2;
        const Vec3 c = node_center(n);
        for (int k = 0; k < 3; ++k) {
            t[k] = std::abs(x[k] - c[k]) / h;
            if (!(t[k] < 1)) return false;
        }
        return true;
    }

    /// Blends the live leaves whose overlap boxes hold x: weights Π_k (1 - t_k²)²
    /// (C¹, zero on the box). Returns false when none holds x.
    bool blend_value(const Vec3& x, const std::array<int, 3>& r, Scalar& f, Vec3* grad) const {
        Scalar W = 0, F = 0;
        Vec3 dW = Vec3::Zero(), dF = Vec3::Zero();
        std::size_t stack[256];
        std::size_t top = 0;
        for (int k = std::max(0, r[2] - 1); k <= std::min(root_count[2] - 1, r[2] + 1); ++k)
            for (int j = std::max(0, r[1] - 1); j <= std::min(root_count[1] - 1, r[1] + 1); ++j)
                for (int i = std::max(0, r[0] - 1); i <= std::min(root_count[0] - 1, r[0] + 1); ++i)
                    stack[top++] = root_index(i, j, k);
        Vec3 t;
        while (top > 0) {
            const Node& n = nodes[stack[--top]];
            if (!in_box(n, x, alpha, t)) continue;
            if (n.child >= 0) {
                for (std::size_t o = 0; o < 8 && top < 256; ++o) stack[top++] = static_cast<std::size_t>(n.child) + o;
                continue;
            }
            const Leaf& l = leaves[static_cast<std::size_t>(n.leaf)];
            if (!l.live) continue;
            Vec3 s, ds;
            for (int k = 0; k < 3; ++k) {
                const Scalar q = 1 - t[k] * t[k];
                s[k] = q * q;
                ds[k] = -4 * t[k] * q / (alpha * n.side / 2) * (x[k] >= node_center(n)[k] ? 1 : -1);
            }
            const Scalar w = s.prod();
            Vec3 lg;
            const Scalar g = leaf_value(l, x, grad ? &lg : nullptr);
            W += w;
            F += w * g;
            if (grad) {
                const Vec3 gw(ds[0] * s[1] * s[2], s[0] * ds[1] * s[2], s[0] * s[1] * ds[2]);
                dW += gw;
                dF += gw * g + w * lg;
            }
        }
        if (!(W > 0)) return false;
        f = F / W;
        if (grad) *grad = (dF * W - F * dW) / (W * W);
        return true;
    }

    /// f (scaled frame) and ∇f at x (scaled frame).
    Scalar evaluate(const Vec3& x, Vec3* grad) const {
        std::array<int, 3> r{};
        const bool inside = root_of(x, r);
        if (blend) {  // the overlap boxes reach past the tiling
            Scalar f = 0;
            if (blend_value(x, r, f, grad)) return f;
        }
        if (!inside) return far_value(x, nullptr, grad);
        const Leaf& l = locate(x, r);
        if (blend) return far_value(x, l.live ? nullptr : &l.dead_sign, grad);
        if (l.live) return leaf_value(l, x, grad);
        return far_value(x, &l.dead_sign, grad);
    }
};

}  // namespace detail

/// The octree RBF implicit field of an oriented point set (see RBFOctreeField::build).
/// f < 0 inside, > 0 outside, ≈ signed distance near the surface, in the caller's
/// units; ∇f dimensionless, pointing out. Defined everywhere: where no RBF reaches
/// (dead cells, outside the octree) f is the distance to the nearest point, signed by
/// the cell (by that point's normal outside the octree). Immutable, shared on copy,
/// const queries thread-safe; empty (NaN) when default-constructed or cancelled.
class RBFOctreeField {
public:
    /// f(x); NaN for an empty field or a NaN x.
    [[nodiscard]] Scalar operator()(const Vec3& x) const { return eval(x, nullptr); }
    [[nodiscard]] Scalar value(const Vec3& x) const { return eval(x, nullptr); }
    /// ∇f(x); NaN components for an empty field or a NaN x.
    [[nodiscard]] Vec3 gradient(const Vec3& x) const {
        Vec3 g;
        (void)eval(x, &g);
        return g;
    }
    /// f(x), with ∇f(x) written to grad.
    [[nodiscard]] Scalar value_and_gradient(const Vec3& x, Vec3& grad) const { return eval(x, &grad); }
    [[nodiscard]] bool empty() const { return !data_; }

    /// @brief Fits the field: Miura, Sone, Masuda (octree RBF), with Carr, Beatson et
    /// al., "Reconstruction and representation of 3D objects with radial basis
    /// functions" (SIGGRAPH 2001) for the offsets and the smoothing λ.
    /// 1) (near-)duplicates merged into the lowest index; offsets ±d_i along the
    /// normals, halved while another point is nearer; 2) root cubes, a cell splits
    /// while more than n_max centres lie in its α-box, dead cells; 3) per live cell
    /// φ = r³ + linear polynomial by null-space Cholesky (bad cells: jitter or least
    /// squares, counted); 4) evaluation blended (default) or per cell.
    /// @tparam P an OrientedPointSet (read once); normals outward, any non-zero length.
    /// @param params RBFOctreeParams (resolution unused here).
    /// @throws invalid_input for fewer than 4 points, missing normals, a NaN/Inf
    ///         coordinate or normal, a zero normal, n_max < 10, overlap or activity < 1,
    ///         root_size outside (0, 1], offset_scale <= 0, smoothing or merge_distance
    ///         < 0; inputs untouched.
    /// @return field (empty unless ok), Status::cancelled when stopped through
    ///         params.control, counts, timings "rbf_offsets", "rbf_octree", "rbf_solve".
    ///         Bit-identical whatever the number of threads.
    template <OrientedPointSet P>
    [[nodiscard]] static RBFOctreeResult build(const P& points, const RBFOctreeParams& params = {});

    /// Whether f blends overlapping cells (RBFOctreeParams::blend).
    [[nodiscard]] bool blended() const { return data_ && data_->blend; }
    /// The same fit evaluated the other way (blend, or the paper's single cell).
    [[nodiscard]] RBFOctreeField with_blend(bool blend) const {
        RBFOctreeField out;
        if (!data_) return out;
        auto d = std::make_shared<detail::RBFOctreeData>(*data_);
        d->blend = blend;
        out.data_ = std::move(d);
        return out;
    }
    /// The octree's leaves (caller's coordinates), in build order.
    [[nodiscard]] std::vector<RBFCell> cells() const {
        std::vector<RBFCell> out;
        if (!data_) return out;
        for (const auto& l : data_->leaves) {
            const auto& n = data_->nodes[l.node];
            out.push_back({data_->frame.to_world(n.min), data_->frame.to_world(n.side), l.live, l.end - l.begin});
        }
        return out;
    }
    /// The centres the field interpolates (points kept and offsets), caller's units.
    [[nodiscard]] std::vector<Vec3> centres() const {
        std::vector<Vec3> out = data_ ? data_->centres : std::vector<Vec3>{};
        if (data_) data_->frame.to_world(out);
        return out;
    }

private:
    friend RBFOctreeResult detail::rbf_octree_fit(std::vector<Vec3>, std::vector<Vec3>, const RBFOctreeParams&);
    Scalar eval(const Vec3& x, Vec3* grad) const {
        constexpr Scalar nan = std::numeric_limits<Scalar>::quiet_NaN();
        if (!data_ || !x.allFinite()) {
            if (grad) *grad = Vec3::Constant(nan);
            return nan;
        }
        return data_->frame.to_world(data_->evaluate(data_->frame.to_local(x), grad));
    }
    std::shared_ptr<const detail::RBFOctreeData> data_;
};

static_assert(DifferentiableScalarField<RBFOctreeField>);

/// Result of RBFOctreeField::build.
struct RBFOctreeResult {
    RBFOctreeField field;            ///< empty unless status == ok
    Status status = Status::ok;
    RBFOctreeStats stats;
    std::vector<StageTiming> timings;  ///< "rbf_offsets", "rbf_octree", "rbf_solve"
};

/// Result of reconstruct_rbf_octree.
struct RBFReconstructResult {
    IndexedMesh mesh;                ///< empty when cancelled or written into the caller's mesh
    Status status = Status::ok;
    RBFOctreeStats stats;
    IsosurfaceResult isosurface;     ///< its counts (field evaluations, cubes, faces)
    std::vector<StageTiming> timings;  ///< the field's stages, then "rbf_polygonise"
};

namespace detail {

inline void rbf_validate(const std::vector<Vec3>& pts, const std::vector<Vec3>& nrm, const RBFOctreeParams& p,
                         const std::string& fn) {
    auto num = [](Scalar x) { return format_number(x); };
    if (p.n_max < 10)
        throw invalid_input(fn + "n_max = " + std::to_string(p.n_max) + " is below 10; use 10 or more (the paper: 250)");
    if (!(p.overlap >= 1) || !std::isfinite(p.overlap))
        throw invalid_input(fn + "overlap = " + num(p.overlap) + " must be >= 1 and finite (the paper: 1.3 to 1.4)");
    if (!(p.activity >= 1) || !std::isfinite(p.activity))
        throw invalid_input(fn + "activity = " + num(p.activity) + " must be >= 1 and finite (the paper: 1.05)");
    if (!(p.root_size > 0 && p.root_size <= 1))
        throw invalid_input(fn + "root_size = " + num(p.root_size) + " must lie in (0, 1] (1: one root cube)");
    if (!(p.offset_scale > 0) || !std::isfinite(p.offset_scale))
        throw invalid_input(fn + "offset_scale = " + num(p.offset_scale) + " must be positive and finite (e.g. 1)");
    if (!(p.smoothing >= 0) || !std::isfinite(p.smoothing))
        throw invalid_input(fn + "smoothing = " + num(p.smoothing) + " must be >= 0 and finite (0 interpolates)");
    if (!(p.merge_distance >= 0) || !std::isfinite(p.merge_distance))
        throw invalid_input(fn + "merge_distance = " + num(p.merge_distance) + " must be >= 0 and finite (e.g. 1e-6)");
    if (pts.size() < 4) throw invalid_input(fn + "needs at least 4 points, got " + std::to_string(pts.size()));
    if (nrm.size() != pts.size())
        throw invalid_input(fn + "the points have no normals (or not one per point); estimate oriented normals "
                                 "first (kintsugi::estimate_normals)");
    for (std::size_t i = 0; i < pts.size(); ++i) {
        const std::string which = "point " + std::to_string(i);
        if (!pts[i].allFinite()) throw invalid_input(fn + which + " has a NaN or infinite coordinate; remove it first");
        if (!nrm[i].allFinite() || !(nrm[i].cwiseAbs().maxCoeff() > 0))
            throw invalid_input(fn + "the normal of " + which +
                                " is zero, NaN or infinite; fix or re-estimate the normals (kintsugi::estimate_normals)");
    }
}

/// Keeps point i unless an earlier kept point lies within `dist` (deterministic).
inline std::vector<std::uint8_t> rbf_merge(const std::vector<Vec3>& pts, Scalar dist) {
    const std::size_t n = pts.size();
    std::vector<std::uint8_t> keep(n, 1);
    if (!(dist > 0)) return keep;
    const KdTree tree(pts);
    std::vector<std::vector<Index>> earlier(n);
    parallel_for(0, n, [&](std::size_t i) {
        thread_local std::vector<Neighbor> nb;
        tree.radius_search_squared(pts[i], dist * dist, nb);
        for (const Neighbor& q : nb)
            if (q.index < i) earlier[i].push_back(q.index);
    }, 1024);
    for (std::size_t i = 0; i < n; ++i)
        for (const Index j : earlier[i])
            if (keep[j]) {
                keep[i] = 0;
                break;
            }
    return keep;
}

}  // namespace detail

template <OrientedPointSet P>
RBFOctreeResult RBFOctreeField::build(const P& points, const RBFOctreeParams& params) {
    // Missing normals come as an empty list, which the fit's checks name.
    return detail::rbf_octree_fit(gather_points(points), gather_normals(points), params);
}

/// The fit on the internal layout (positions and normals of equal length).
inline RBFOctreeResult detail::rbf_octree_fit(std::vector<Vec3> pts, std::vector<Vec3> nrm,
                                              const RBFOctreeParams& params) {
    detail::rbf_validate(pts, nrm, params, "kintsugi::RBFOctreeField::build: ");
    RBFOctreeResult res;
    res.stats.points = pts.size();
    detail::Progress progress(params.control);
    try {
        auto data = std::make_shared<detail::RBFOctreeData>();
        data->frame = detail::scale_frame(pts);
        data->alpha = params.overlap;
        data->blend = params.blend;
        data->frame.to_local(pts);

        // ---------------------------------------------------------- 1) offsets
        progress.stage("rbf_offsets", 0.0, 0.15);
        BoundingBox box;
        for (const Vec3& p : pts) box.extend(p);
        const auto keep = detail::rbf_merge(pts, params.merge_distance * box.diagonal());
        std::vector<Vec3> sp, sn;
        for (std::size_t i = 0; i < pts.size(); ++i)
            if (keep[i]) {
                sp.push_back(pts[i]);
                const Vec3 n = nrm[i] / nrm[i].cwiseAbs().maxCoeff();  // no underflow in norm()
                sn.push_back(n.normalized());
            }
        res.stats.merged_points = pts.size() - sp.size();
        progress.check();
        const std::size_t ns = sp.size();
        data->surface = std::make_shared<const KdTree>(sp);
        const KdTree& tree = *data->surface;
        // Per point: d for the + and - offsets (0: dropped) and whether it was shrunk.
        std::vector<std::array<Scalar, 2>> off(ns);
        std::vector<std::array<std::uint8_t, 2>> shrunk(ns);
        std::vector<Scalar> spacing_of(ns);
        parallel_for(0, ns, [&](std::size_t i) {
            thread_local std::vector<Neighbor> nb;
            tree.knn(sp[i], 7, nb);
            Scalar sum = 0;
            std::size_t cnt = 0;
            for (const Neighbor& q : nb)
                if (q.index != i) {
                    sum += std::sqrt(q.squared_distance);
                    ++cnt;
                }
            const Scalar spacing = cnt > 0 ? sum / static_cast<Scalar>(cnt) : Scalar(1);
            spacing_of[i] = spacing;
            for (int s = 0; s < 2; ++s) {
                Scalar d = params.offset_scale * spacing;
                const Scalar sign = s == 0 ? Scalar(1) : Scalar(-1);
                off[i][s] = 0;
                shrunk[i][s] = 0;
                for (int it = 0; it < 9; ++it) {
                    const Vec3 q = sp[i] + sign * d * sn[i];
                    const Neighbor nn = tree.nearest(q);
                    const Scalar own = (q - sp[i]).squaredNorm();
                    if (nn.index == i || !(nn.squared_distance < own)) {
                        off[i][s] = d;
                        break;
                    }
                    shrunk[i][s] = 1;
                    d /= 2;
                }
            }
        }, 512);
        progress.check();
        // Centres: point i, then its + and - offsets, in point order.
        std::vector<Vec3>& C = data->centres;
        std::vector<Scalar> value;
        std::vector<std::uint8_t> on_surface;
        C.reserve(3 * ns);
        for (std::size_t i = 0; i < ns; ++i) {
            C.push_back(sp[i]);
            value.push_back(0);
            on_surface.push_back(1);
            for (int s = 0; s < 2; ++s) {
                res.stats.shrunk_offsets += shrunk[i][s];
                if (off[i][s] == 0) {
                    ++res.stats.dropped_offsets;
                    continue;
                }
                const Scalar sign = s == 0 ? Scalar(1) : Scalar(-1);
                C.push_back(sp[i] + sign * off[i][s] * sn[i]);
                value.push_back(sign * off[i][s]);
                on_surface.push_back(0);
            }
        }
        res.stats.offset_points = C.size() - ns;
        data->surface_normals = std::move(sn);

        // ---------------------------------------------------------- 2) octree
        progress.stage("rbf_octree", 0.15, 0.25);
        BoundingBox cb;
        for (const Vec3& c : C) cb.extend(c);
        const Scalar L = std::max(cb.extent().maxCoeff(), Scalar(1e-300));
        // A margin so that no centre lies on the far faces of the tiling.
        const Vec3 lo = cb.min - Vec3::Constant(Scalar(0.01) * L), hi = cb.max + Vec3::Constant(Scalar(0.01) * L);
        data->root_side = params.root_size * (hi - lo).maxCoeff();
        for (int k = 0; k < 3; ++k)
            data->root_count[k] = std::max(1, static_cast<int>(std::ceil((hi[k] - lo[k]) / data->root_side)));
        const Vec3 span(data->root_count[0] * data->root_side, data->root_count[1] * data->root_side,
                        data->root_count[2] * data->root_side);
        data->root_min = (lo + hi) / 2 - span / 2;
        const Scalar alpha = params.overlap, beta = params.activity, gamma = std::max(alpha, beta);
        // Level-by-level subdivision; a node's list holds the centres in its γ-box
        // (γ = max(α, β)), a child's list is a subset of its parent's.
        auto& nodes = data->nodes;
        const std::size_t n_roots =
            static_cast<std::size_t>(data->root_count[0]) * data->root_count[1] * data->root_count[2];
        std::vector<std::vector<std::uint32_t>> lists(n_roots);
        for (int k = 0; k < data->root_count[2]; ++k)
            for (int j = 0; j < data->root_count[1]; ++j)
                for (int i = 0; i < data->root_count[0]; ++i)
                    nodes.push_back({data->root_min + data->root_side * Vec3(i, j, k), data->root_side, -1, -1});
        auto in_factor_box = [](const detail::RBFOctreeData::Node& n, const Vec3& p, Scalar factor) {
            const Scalar h = factor * n.side / 2;
            const Vec3 c = n.min + Vec3::Constant(n.side / 2);
            return std::abs(p.x() - c.x()) <= h && std::abs(p.y() - c.y()) <= h && std::abs(p.z() - c.z()) <= h;
        };
        {
            // Roots: bin every centre into the roots whose γ-boxes hold it.
            std::vector<std::vector<std::uint32_t>> per_root(n_roots);
            for (std::size_t c = 0; c < C.size(); ++c) {
                std::array<int, 3> r{};
                (void)data->root_of(C[c], r);
                for (int k = std::max(0, r[2] - 1); k <= std::min(data->root_count[2] - 1, r[2] + 1); ++k)
                    for (int j = std::max(0, r[1] - 1); j <= std::min(data->root_count[1] - 1, r[1] + 1); ++j)
                        for (int i = std::max(0, r[0] - 1); i <= std::min(data->root_count[0] - 1, r[0] + 1); ++i) {
                            const std::size_t id = data->root_index(i, j, k);
                            if (in_factor_box(nodes[id], C[c], gamma)) per_root[id].push_back(static_cast<std::uint32_t>(c));
                        }
            }
            lists = std::move(per_root);
        }
        constexpr int max_depth = 20;  // 2^-20 of the root: far below any merged spacing
        std::vector<std::size_t> level(n_roots);
        for (std::size_t i = 0; i < n_roots; ++i) level[i] = i;
        // Final lists of the leaves, by node.
        std::vector<std::vector<std::uint32_t>> node_list(n_roots);
        for (int depth = 0; !level.empty(); ++depth) {
            progress.check();
            res.stats.depth = depth;
            // Which nodes of this level split, in parallel; children appended in order.
            std::vector<std::array<std::vector<std::uint32_t>, 8>> kids(level.size());
            std::vector<std::uint8_t> split(level.size(), 0);
            parallel_for(0, level.size(), [&](std::size_t q) {
                const auto& node = nodes[level[q]];
                const auto& list = lists[q];
                std::size_t in_alpha = 0;
                for (const auto c : list) in_alpha += in_factor_box(node, C[c], alpha) ? 1 : 0;
                if (in_alpha <= params.n_max || depth >= max_depth) return;
                split[q] = 1;
                const Scalar hs = node.side / 2;
                for (std::size_t o = 0; o < 8; ++o) {
                    const detail::RBFOctreeData::Node child{
                        node.min + hs * Vec3(o & 1 ? 1 : 0, o & 2 ? 1 : 0, o & 4 ? 1 : 0), hs, -1, -1};
                    for (const auto c : list)
                        if (in_factor_box(child, C[c], gamma)) kids[q][o].push_back(c);
                }
            }, 1);
            std::vector<std::size_t> next;
            std::vector<std::vector<std::uint32_t>> next_lists;
            for (std::size_t q = 0; q < level.size(); ++q) {
                const std::size_t id = level[q];
                if (!split[q]) {
                    if (node_list.size() < nodes.size()) node_list.resize(nodes.size());
                    node_list[id] = std::move(lists[q]);
                    continue;
                }
                const auto first = static_cast<std::int64_t>(nodes.size());
                nodes[id].child = first;
                const Scalar hs = nodes[id].side / 2;
                const Vec3 mn = nodes[id].min;
                for (std::size_t o = 0; o < 8; ++o) {
                    nodes.push_back({mn + hs * Vec3(o & 1 ? 1 : 0, o & 2 ? 1 : 0, o & 4 ? 1 : 0), hs, -1, -1});
                    next.push_back(static_cast<std::size_t>(first) + o);
                    next_lists.push_back(std::move(kids[q][o]));
                }
                std::vector<std::uint32_t>().swap(lists[q]);
            }
            level = std::move(next);
            lists = std::move(next_lists);
        }
        node_list.resize(nodes.size());
        // Leaves in node order; liveness from the β-box; the α-box centres for the system.
        std::vector<std::vector<std::uint32_t>> leaf_centres;
        for (std::size_t id = 0; id < nodes.size(); ++id) {
            if (nodes[id].child >= 0) continue;
            nodes[id].leaf = static_cast<std::int64_t>(data->leaves.size());
            detail::RBFOctreeData::Leaf leaf;
            leaf.node = id;
            std::vector<std::uint32_t> mine;
            for (const auto c : node_list[id]) {
                if (on_surface[c] && in_factor_box(nodes[id], C[c], beta)) leaf.live = true;
                if (in_factor_box(nodes[id], C[c], alpha)) mine.push_back(c);
            }
            std::vector<std::uint32_t>().swap(node_list[id]);
            data->leaves.push_back(leaf);
            leaf_centres.push_back(std::move(mine));
        }
        res.stats.cells = data->leaves.size();
        // Beyond the paper: a cell the surface may cross between samples is live too
        // (its nearest point closer to its centre than β x the half diagonal plus
        // twice that point's spacing); the β-box rule alone leaves dead cells, with
        // the far value's error, on the surface where the samples are sparse.
        parallel_for(0, data->leaves.size(), [&](std::size_t l) {
            auto& leaf = data->leaves[l];
            if (leaf.live) return;
            const auto& node = nodes[leaf.node];
            const Neighbor nb = tree.nearest(data->node_center(node));
            const Scalar reach = beta * std::sqrt(Scalar(3)) / 2 * node.side + 2 * spacing_of[nb.index];
            if (nb.squared_distance <= reach * reach) leaf.live = true;
            else std::vector<std::uint32_t>().swap(leaf_centres[l]);
        }, 64);
        progress.check();

        // ---------------------------------------------------------- 3) solves
        progress.stage("rbf_solve", 0.25, 1.0);
        const KdTree centre_tree(C);
        const std::size_t nl = data->leaves.size();
        std::vector<std::vector<Scalar>> leaf_w(nl);
        std::vector<std::uint8_t> bad(nl, 0), padded(nl, 0);
        constexpr std::size_t min_centres = 20;  // a well-posed r³ + linear fit
        const std::size_t block = 256;
        for (std::size_t b0 = 0; b0 < nl; b0 += block) {
            const std::size_t b1 = std::min(nl, b0 + block);
            parallel_for(b0, b1, [&](std::size_t l) {
                auto& leaf = data->leaves[l];
                if (!leaf.live) {
                    const Vec3 c = data->node_center(nodes[leaf.node]);
                    leaf.dead_sign = data->far_value(c, nullptr, nullptr) >= 0 ? Scalar(1) : Scalar(-1);
                    return;
                }
                auto& ids = leaf_centres[l];
                const Vec3 c = data->node_center(nodes[leaf.node]);
                if (ids.size() < min_centres) {
                    padded[l] = 1;
                    thread_local std::vector<Neighbor> nb;
                    centre_tree.knn(c, min_centres, nb);
                    for (const Neighbor& q : nb)
                        if (std::find(ids.begin(), ids.end(), static_cast<std::uint32_t>(q.index)) == ids.end())
                            ids.push_back(static_cast<std::uint32_t>(q.index));
                    std::sort(ids.begin(), ids.end());
                }
                const Scalar h = alpha * nodes[leaf.node].side / 2;
                std::vector<Vec3> u(ids.size());
                std::vector<Scalar> v(ids.size());
                for (std::size_t k = 0; k < ids.size(); ++k) {
                    u[k] = (C[ids[k]] - c) / h;
                    v[k] = value[ids[k]] / h;
                }
                const auto info = detail::rbf_solve_cell(u, v, params.smoothing, leaf_w[l], leaf.poly);
                bad[l] = info.ill_conditioned ? 1 : 0;
            }, 1);
            progress.update(static_cast<double>(b1) / static_cast<double>(nl));
        }
        std::size_t total = 0;
        for (std::size_t l = 0; l < nl; ++l) {
            auto& leaf = data->leaves[l];
            if (!leaf.live) {
                ++res.stats.dead_cells;
                continue;
            }
            ++res.stats.live_cells;
            res.stats.ill_conditioned_cells += bad[l];
            res.stats.padded_cells += padded[l];
            res.stats.max_points_per_cell = std::max(res.stats.max_points_per_cell, leaf_centres[l].size());
            leaf.begin = data->ids.size();
            data->ids.insert(data->ids.end(), leaf_centres[l].begin(), leaf_centres[l].end());
            data->weights.insert(data->weights.end(), leaf_w[l].begin(), leaf_w[l].end());
            leaf.end = data->ids.size();
            total += leaf_centres[l].size();
        }
        res.stats.mean_points_per_cell =
            res.stats.live_cells > 0 ? static_cast<double>(total) / static_cast<double>(res.stats.live_cells) : 0.0;
        res.timings = progress.finish();
        res.field.data_ = std::move(data);
    } catch (const detail::cancelled_exception&) {
        res.status = Status::cancelled;  // the field is set last: still empty
    }
    return res;
}

/// @brief Reconstructs a surface from oriented points: RBFOctreeField::build, then
/// extract_isosurface on a grid of params.resolution cubes along the longest side,
/// seeded at the cubes holding the points (only the surface's neighbourhood is
/// evaluated). Where the data are closed (holes included, which the RBF fills) the
/// mesh is closed.
/// @tparam P an OrientedPointSet; @tparam M a TopologyMutableMesh (cleared and filled
///         on success, untouched on cancellation or error).
/// @throws invalid_input as RBFOctreeField::build, and for resolution outside [8, 4096].
/// @return counts, the isosurface counts and timings (the field's stages, then
///         "rbf_polygonise"). Status::cancelled: `out` untouched.
template <OrientedPointSet P, TopologyMutableMesh M>
RBFReconstructResult reconstruct_rbf_octree(const P& points, M& out, const RBFOctreeParams& params = {}) {
    const std::string fn = "kintsugi::reconstruct_rbf_octree: ";
    if (params.resolution < 8 || params.resolution > 4096)
        throw invalid_input(fn + "resolution = " + std::to_string(params.resolution) +
                            " is outside [8, 4096] (cubes along the longest side, e.g. 256)");
    std::vector<Vec3> pts = gather_points(points);
    std::vector<Vec3> nrm = gather_normals(points);
    detail::rbf_validate(pts, nrm, params, fn);
    RBFReconstructResult res;
    // The field's progress covers [0, 0.7), the polygonisation [0.7, 1].
    RunControl field_control = params.control;
    if (params.control.progress)
        field_control.progress = [&params](const ProgressEvent& e) {
            return params.control.progress(ProgressEvent{e.stage, 0.7 * e.fraction});
        };
    RBFOctreeParams fp = params;
    fp.control = field_control;
    auto fit = detail::rbf_octree_fit(pts, std::move(nrm), fp);
    res.stats = fit.stats;
    res.timings = fit.timings;
    if (fit.status != Status::ok) {
        res.status = fit.status;
        return res;
    }
    BoundingBox box;
    for (const Vec3& p : pts) box.extend(p);
    // A margin of 5 % on each side: the RBF closes holes with caps that may bulge
    // past the points' box.
    const IsoGrid grid = IsoGrid::fit(box, params.resolution, std::max(2, params.resolution / 20));
    IsosurfaceParams ip;
    // Roots to 1e-4 of a cube side (the fit is far less accurate than that): half
    // the evaluations of the default 1e-7 on the bunny.
    ip.root.tolerance = 1e-4;
    ip.control = params.control;
    if (params.control.progress)
        ip.control.progress = [&params](const ProgressEvent& e) {
            return params.control.progress(ProgressEvent{"rbf_polygonise", 0.7 + 0.3 * e.fraction});
        };
    const auto start = std::chrono::steady_clock::now();
    res.isosurface = extract_isosurface(fit.field, IsoRegion::narrow_band(grid, pts, 0), out, ip);
    res.timings.push_back({"rbf_polygonise", std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()});
    res.status = res.isosurface.status;
    return res;
}

/// Same, returning the mesh in RBFReconstructResult::mesh.
template <OrientedPointSet P>
[[nodiscard]] RBFReconstructResult reconstruct_rbf_octree(const P& points, const RBFOctreeParams& params = {}) {
    IndexedMesh mesh;
    RBFReconstructResult res = reconstruct_rbf_octree(points, mesh, params);
    if (res.status == Status::ok) res.mesh = std::move(mesh);
    return res;
}

}  // namespace kintsugi
