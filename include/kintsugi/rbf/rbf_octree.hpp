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
/// auto fit = kintsugi::RBFOctreeField::build(kintsugi::with_normals(pts, nrm), {.n_max = 100});
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
#include <kintsugi/core/stages.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/field/isosurface.hpp>
#include <kintsugi/field/partition_of_unity.hpp>
#include <kintsugi/rbf/detail/rbf_solve.hpp>
#include <kintsugi/spatial/bucket_grid.hpp>
#include <kintsugi/spatial/kd_tree.hpp>
#include <kintsugi/spatial/morton.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace kintsugi {

/// Parameters of RBFOctreeField::build and reconstruct_rbf_octree (aggregate; field
/// order is API, append only).
struct RBFOctreeParams {
    /// n_max >= 10: a cell splits into 8 while more centres (points and offsets) are
    /// assigned to it. 100: two thirds of the CPU of the paper's 250 at 1M points, the
    /// same accuracy (fertility, Block, Twelve; at 100K 1-4 % farther, docs).
    std::size_t n_max = 100;
    /// Overlap α in [1, 3]: a cell takes the centres within α/2 x its side of its
    /// centre along each axis. The paper's 1.3-1.4 balances seams against time.
    Scalar overlap = 1.35;
    /// Activity β in [1, 3]: a cell with no on-surface point in its β-enlarged box is dead
    /// (no RBF) unless the surface may cross it between samples (docs). The paper's 1.05.
    Scalar activity = 1.05;
    /// Side of the root cubes tiling the bounding box, as a fraction [1/64, 1] of its
    /// longest side (the paper: "smaller than 1" in the unit cube). 1: one root.
    Scalar root_size = 1;
    /// Offset distance d_i = offset_scale x the mean distance from p_i to its 6 nearest
    /// points (> 0), then halved while another point is nearer to p_i ± d_i n_i than
    /// p_i is (Carr et al. 2001). 1: offsets one sample spacing off the surface.
    Scalar offset_scale = 1;
    /// Smoothing λ >= 0 (Carr et al.'s regularised fit), dimensionless: added to the
    /// diagonal of each cell's matrix in the cell's normalised units (distances and
    /// values divided by h = α x side / 2), so a centre's value is missed by λ w_i h
    /// and cells of every size are smoothed alike. 0 interpolates every point; 0.01 to
    /// 1 for noisy scans (0.5 % noise on a sphere: 0.1 halves the error, docs).
    Scalar smoothing = 0;
    /// Cubes along the longest side of the bounding box for reconstruct_rbf_octree's
    /// polygonisation, in [8, 4096]. Ignored by RBFOctreeField::build.
    int resolution = 256;
    /// true (default): f blends the RBFs of every live cell whose overlap box holds x
    /// with C¹ weights (no seams); false: the paper's evaluation, the RBF of the cell
    /// holding x alone (seams of the size of the fit error at cell faces).
    bool blend = true;
    /// Points within this fraction (>= 0) of the bounding-box diagonal of an earlier
    /// kept point are merged into it; exact duplicates always are (also at 0).
    /// Near-duplicates would make a system singular.
    Scalar merge_distance = 1e-6;
    /// Progress callback and cancellation.
    RunControl control{};
};

/// Counts of one fit (RBFOctreeResult, RBFReconstructResult).
struct RBFOctreeStats {
    std::size_t points = 0;          ///< input points
    std::size_t merged_points = 0;   ///< dropped as (near-)duplicates of an earlier point
    std::size_t offset_points = 0;   ///< offset centres (±d), 2 per kept point, 4 at crease points
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
    /// Live cells at the depth limit (20 levels) with more than n_max centres (a cluster
    /// of near-duplicates kept by a small merge_distance), solved on an evenly spread
    /// subset of at most n_max of them so that no cell costs more than n_max³.
    std::size_t capped_cells = 0;
    std::size_t capped_centres = 0;  ///< centres those cells left out of their systems
    /// Centres added beyond sharp edges and corners (along the mean normal of a crease
    /// point's neighbours, docs), included in offset_points.
    std::size_t crease_offsets = 0;
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
/// The fit on the internal layout: detail/rbf_octree_fit.ipp (kintsugi/core/stages.hpp).
KINTSUGI_STAGE RBFOctreeResult rbf_octree_fit(std::vector<Vec3> points, std::vector<Vec3> normals,
                                              const RBFOctreeParams& params);
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

    std::vector<Scalar> surface_area;    ///< spacing² of each on-surface point: its share in side_of

    /// +1 when x lies outside the sampled surface, -1 inside: the sign of the generalised
    /// winding number (Barill et al. 2018) of the side_neighbours nearest points, each a
    /// disc of area spacing² with its normal. Not the nearest point's normal alone: near a
    /// sharp edge (a thin blade, a crease) x beyond the edge can lie behind the tangent
    /// plane of its nearest point, whose sign is then wrong for a whole dead cell (an
    /// inside box floating outside the surface, docs); the faces of both sides seen
    /// from x outvote it. Sums in the kd-tree's order (distance, then index).
    [[nodiscard]] Scalar side_of(const Vec3& x) const {
        thread_local std::vector<Neighbor> nb;
        surface->knn(x, side_neighbours, nb);
        Scalar w = 0;
        for (const Neighbor& q : nb) {
            const Scalar r2 = q.squared_distance;
            if (!(r2 > 0)) continue;
            w += surface_area[q.index] * surface_normals[q.index].dot(surface->point(q.index) - x) / (r2 * std::sqrt(r2));
        }
        if (w == 0 && !nb.empty())  // x on a point (or no vote): that point's normal
            return surface_normals[nb[0].index].dot(x - surface->point(nb[0].index)) >= 0 ? Scalar(1) : Scalar(-1);
        return w > 0 ? Scalar(-1) : Scalar(1);
    }
    static constexpr std::size_t side_neighbours = 32;

    /// The distance to the nearest on-surface point, signed by side_of (where no RBF is
    /// defined); for dead cells the cell's sign when given.
    Scalar far_value(const Vec3& x, const Scalar* sign, Vec3* grad) const {
        const Neighbor nb = surface->nearest(x);
        const Vec3 d = x - surface->point(nb.index);
        const Scalar dist = std::sqrt(nb.squared_distance);
        const Scalar s = sign ? *sign : side_of(x);
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

    /// Whether x lies in node n's box enlarged to `factor` x its side (open box).
    [[nodiscard]] bool in_box(const Node& n, const Vec3& x, Scalar factor) const {
        const Scalar h = factor * n.side / 2;
        const Vec3 c = node_center(n);
        for (int k = 0; k < 3; ++k)
            if (!(std::abs(x[k] - c[k]) / h < 1)) return false;
        return true;
    }

    /// Blends the live leaves whose overlap boxes hold x: the shared partition of unity
    /// (field/partition_of_unity.hpp) with box_weight over each α-box, Π_k (1 - t_k²)²
    /// (C¹, zero on the box), found by descending the octree. Returns false when none
    /// holds x.
    bool blend_value(const Vec3& x, const std::array<int, 3>& r, Scalar& f, Vec3* grad) const {
        PUAccumulator acc(grad != nullptr);
        std::size_t stack[256];
        std::size_t top = 0;
        for (int k = std::max(0, r[2] - 1); k <= std::min(root_count[2] - 1, r[2] + 1); ++k)
            for (int j = std::max(0, r[1] - 1); j <= std::min(root_count[1] - 1, r[1] + 1); ++j)
                for (int i = std::max(0, r[0] - 1); i <= std::min(root_count[0] - 1, r[0] + 1); ++i)
                    stack[top++] = root_index(i, j, k);
        while (top > 0) {
            const Node& n = nodes[stack[--top]];
            if (!in_box(n, x, alpha)) continue;
            if (n.child >= 0) {
                for (std::size_t o = 0; o < 8 && top < 256; ++o) stack[top++] = static_cast<std::size_t>(n.child) + o;
                continue;
            }
            const Leaf& l = leaves[static_cast<std::size_t>(n.leaf)];
            if (!l.live) continue;
            if (grad) {
                Vec3 gw, lg;
                const Scalar w = box_weight(x, node_center(n), alpha * n.side / 2, &gw);
                acc.add(w, gw, leaf_value(l, x, &lg), lg);
            } else {
                acc.add(box_weight(x, node_center(n), alpha * n.side / 2), leaf_value(l, x, nullptr));
            }
        }
        if (!acc.covered()) return false;
        f = acc.value();
        if (grad) *grad = acc.gradient();
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
/// the cell (outside the octree by the winding number of the nearest points, as the cells
/// are). Immutable, shared on copy,
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
    /// @throws invalid_input for fewer than 4 distinct points (after the merge),
    ///         missing normals, a NaN/Inf coordinate or normal, a zero normal,
    ///         n_max < 10, overlap or activity outside [1, 3], root_size outside
    ///         [1/64, 1], offset_scale <= 0, smoothing or merge_distance < 0; inputs
    ///         untouched.
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
    // Above 3 a box would reach past the 26 neighbours of its cell, which the root
    // binning and the blend visit.
    if (!(p.overlap >= 1 && p.overlap <= 3))
        throw invalid_input(fn + "overlap = " + num(p.overlap) + " must lie in [1, 3] (the paper: 1.3 to 1.4)");
    if (!(p.activity >= 1 && p.activity <= 3))
        throw invalid_input(fn + "activity = " + num(p.activity) + " must lie in [1, 3] (the paper: 1.05)");
    if (!(p.root_size >= Scalar(1) / 64 && p.root_size <= 1))
        throw invalid_input(fn + "root_size = " + num(p.root_size) +
                            " must lie in [1/64, 1] (at most 64 root cubes along the longest side; 1: one root)");
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
    check_finite_points(pts, fn + "point ");
    for (std::size_t i = 0; i < nrm.size(); ++i)
        if (!nrm[i].allFinite() || !(nrm[i].cwiseAbs().maxCoeff() > 0))
            throw invalid_input(fn + "the normal of point " + std::to_string(i) +
                                " is zero, NaN or infinite; fix or re-estimate the normals (kintsugi::estimate_normals)");
}

}  // namespace detail

template <OrientedPointSet P>
RBFOctreeResult RBFOctreeField::build(const P& points, const RBFOctreeParams& params) {
    // Missing normals come as an empty list, which the fit's checks name.
    return detail::rbf_octree_fit(gather_points(points), gather_normals(points), params);
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

#ifndef KINTSUGI_SEPARATE_STAGES
#include <kintsugi/rbf/detail/rbf_octree_fit.ipp>
#endif
