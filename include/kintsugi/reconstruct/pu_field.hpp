// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file pu_field.hpp
/// @brief The partition-of-unity implicit field of Nagai, Ohtake and Suzuki,
/// "Outlier robust implicit surface reconstruction using graph-cut" (IPSJ Journal,
/// 2011), steps (1)-(3): octree, support cover, PU field (eq. 1-6).
///
/// @code
/// #include <kintsugi/reconstruct/pu_field.hpp>
/// auto res = kintsugi::PUField::build(kintsugi::with_normals(pts, nrm), {.max_level = 8, .epsilon = 4e-3});
/// if (res.status == kintsugi::Status::ok) {
///     double f = res.field(x);              // < 0 inside, > 0 outside, NaN outside the cube
///     kintsugi::Vec3 g = res.field.gradient(x);
///     auto many = res.field.values(xs);     // parallel batch
/// }
/// @endcode
///
/// **Sign convention.** kintsugi's (see ScalarField in core/concepts.hpp): f < 0 INSIDE
/// the object, f > 0 outside, f = 0 on the surface, and f approximates the signed
/// distance in the caller's units. This is the paper's f with the sign flipped (the
/// paper has f > 0 inside); each support's `normal` (m_i) still points INTO the object,
/// as in the paper, and its local function is g_i(x) = m_i · (x - d_i), so
/// f = -Σ w_i g_i / Σ w_i. kintsugi's default input convention is OUTWARD normals
/// (`inward_normals = false`, as every other tool); pass `inward_normals = true` for
/// data oriented as in the paper. Both give the same field.
///
/// **Domain.** f is defined on the bounding cube (the input bounding box's longest side,
/// centred on the box; `domain_min()`, `domain_side()`), which the supports cover: every
/// point of the cube lies strictly inside at least one support. Outside the cube,
/// value() and every component of gradient() are NaN (quiet NaN, test with std::isnan).

#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/spread.hpp>
#include <kintsugi/core/stages.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/field/partition_of_unity.hpp>
#include <kintsugi/reconstruct/detail/pu_cover.hpp>
#include <kintsugi/spatial/kd_tree.hpp>
#include <kintsugi/spatial/octree.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace kintsugi {

/// Parameters of PUField::build (aggregate; field order is API, append only).
struct PUFieldParams {
    /// Octree depth in [1, 12]; every input point lies in a cell of this level.
    /// The paper uses 8 (Si-sa, bunny) and 9 (Dragon, Buddha).
    int max_level = 8;
    /// Approximation tolerance ε of eq. (6), in units of the bounding box's longest
    /// side (the paper's 4e-3 for Dragon). Must be > 0.
    Scalar epsilon = 4e-3;
    /// Seed of the random order in which candidate centres are picked.
    std::uint64_t seed = 0;
    /// false (default): normals point OUT of the object (kintsugi's convention);
    /// true: normals point INTO the object (the paper's convention).
    bool inward_normals = false;
    /// true (default): the field keeps its octree (PUField::octree()); false: the octree
    /// is released once the cover is built, and octree() is then empty. The octree is the
    /// field's largest part (2M points with 10 % outliers at level 9: 12M cells, 490 MB),
    /// and evaluating the field never reads it; reconstruct_pu_graphcut passes false.
    bool keep_octree = true;
    /// Progress callback and cancellation.
    RunControl control{};
};

/// One support of the PU field, in the caller's coordinates.
/// Local function g_i(x) = normal · (x - origin) on the open ball (center, radius).
struct PUSupport {
    Vec3 center = Vec3::Zero();  ///< c_i: the centre of an octree cell
    Scalar radius = 0;           ///< r_i (caller's units)
    Vec3 normal = Vec3::Zero();  ///< m_i, unit, pointing INTO the object
    Vec3 origin = Vec3::Zero();  ///< d_i, weighted centroid of the points in the ball
    std::size_t point_count = 0; ///< input points p_j with |p_j - c_i| < r_i
    int level = 0;               ///< octree level of the cell c_i came from
    /// Agreement of the normals in the ball, |Σ_j w_i(p_j) n_j| / Σ_j w_i(p_j) in [0, 1]:
    /// near 1 on a surface patch, about 1/sqrt(point_count) among outliers.
    Scalar coherence = 0;
};

class PUField;
struct PUFieldResult;

namespace detail {
/// Shared, immutable data of a PUField.
struct PUFieldData {
    Vec3 center = Vec3::Zero();  ///< caller's coordinates of the normalised origin
    Scalar scale = 1;            ///< normalised = (x - center) * scale
    BoundingBox box;             ///< input bounding box, caller's units
    Scalar epsilon = 0;
    Octree octree;               ///< normalised frame (unit cube centred at 0); empty unless kept
    std::size_t octree_cells = 0;  ///< its cell count, also when it was released
    /// The support balls in the normalised frame, over the unit cube.
    PartitionOfUnity pu;
    /// Local function of support i in the normalised frame: g_i(u) = m · u - md.
    struct Local {
        Vec3 m;
        Scalar md;  ///< m · d
    };
    std::vector<Local> local;
    std::vector<PUSupport> supports;  ///< caller's frame
};
}  // namespace detail

/// The PU implicit field f(x) = -Σ w_i(x) g_i(x) / Σ w_i(x) (eq. 1, negative inside) of
/// an oriented point set. Models DifferentiableScalarField. Immutable; copies share the data;
/// every query is const and thread-safe. A default-constructed field is empty
/// (every value NaN).
class PUField {
public:
    PUField() = default;

    /// @brief Builds the PU field (Nagai, Ohtake, Suzuki 2011, §2.1): octree to
    /// `max_level` with 2:1 balance; candidate centres = centres of all octree
    /// cells (leaves); in seeded random order, a linear fit per candidate (eq. 2-5)
    /// whose radius is found by bisection so that the largest |g_i(p_j)| over the
    /// points in the ball equals ε (eq. 6), never below 0.75 x the cell diagonal;
    /// every cell whose 8 corners lie in the new ball leaves the candidate set;
    /// until no candidate is left. The data are scaled so that the bounding box's
    /// longest side is 1 (ε is in that unit).
    ///
    /// A support whose ball holds no input point, or whose weighted normals cancel
    /// out (only far from the data), uses the tangent plane of the nearest input point.
    /// Normals are normalised before use.
    ///
    /// @tparam P an OrientedPointSet (read once into the internal layout)
    /// @param points positions (any unit) with normals; outward unless
    ///        params.inward_normals
    /// @param params see PUFieldParams
    /// @pre at least 4 points, normals present, non-zero and finite, points finite and
    ///      not all coplanar
    /// @throws invalid_input for fewer than 4 points, missing normals, a zero-length or
    ///         non-finite normal, a NaN/Inf coordinate, coplanar or collinear points,
    ///         max_level outside [1, 12], or epsilon <= 0 / not finite. Inputs untouched.
    /// @return the field, status (ok; cancelled when RunControl stopped the run, the
    ///         field is then empty), counts and per-stage timings ("pu_octree",
    ///         "pu_cover", "pu_index").
    ///
    /// Deterministic: the same input and seed give bit-identical supports and values
    /// whatever the number of threads.
    template <OrientedPointSet P>
    [[nodiscard]] static PUFieldResult build(const P& points, const PUFieldParams& params = {});

    /// Builds from the internal layout (positions and normals of equal length).
    [[nodiscard]] static PUFieldResult build_from(std::vector<Vec3> points, std::vector<Vec3> normals,
                                                  const PUFieldParams& params = {});

    /// @brief The same supports with the weight w_i of support i multiplied by
    /// factors[i] >= 0 (eq. 1 becomes Σ a_i w_i g_i / Σ a_i w_i): a support with a
    /// small factor only counts where no full-weight support covers x; 0 removes it
    /// (NaN where only removed supports cover x). Shares the supports with this field.
    /// The weights are blended by PartitionOfUnity (field/partition_of_unity.hpp).
    /// @throws invalid_input when factors.size() != supports().size() or a factor is
    ///         negative or not finite.
    [[nodiscard]] PUField reweighted(std::vector<Scalar> factors) const {
        if (factors.size() != supports().size())
            throw invalid_input("kintsugi::PUField::reweighted: " + std::to_string(factors.size()) +
                                " factors for " + std::to_string(supports().size()) + " supports");
        for (const Scalar a : factors)
            if (!(a >= 0) || !std::isfinite(a))
                throw invalid_input("kintsugi::PUField::reweighted: factors must be finite and >= 0");
        PUField out = *this;
        out.factors_ = std::make_shared<const std::vector<Scalar>>(std::move(factors));
        return out;
    }

    /// Whether the field holds supports (false when default-constructed or cancelled).
    [[nodiscard]] bool empty() const { return !data_ || data_->local.empty(); }

    /// f(x) in the caller's units (≈ signed distance, < 0 inside, > 0 outside); NaN
    /// outside the bounding cube or for an empty field.
    [[nodiscard]] Scalar value(const Vec3& x) const {
        Vec3 g;
        return evaluate(x, false, g);
    }
    /// Same as value(x).
    [[nodiscard]] Scalar operator()(const Vec3& x) const { return value(x); }
    /// ∇f(x) (dimensionless; points towards the outside); NaN outside the cube.
    [[nodiscard]] Vec3 gradient(const Vec3& x) const {
        Vec3 g;
        evaluate(x, true, g);
        return g;
    }
    /// f(x) and ∇f(x) in one pass.
    [[nodiscard]] Scalar value_and_gradient(const Vec3& x, Vec3& grad) const { return evaluate(x, true, grad); }

    /// f at many points, in parallel (deterministic, same as value() per point).
    [[nodiscard]] std::vector<Scalar> values(const std::vector<Vec3>& xs) const {
        std::vector<Scalar> out(xs.size());
        parallel_for(0, xs.size(), [&](std::size_t i) { out[i] = value(xs[i]); }, 512);
        return out;
    }
    /// ∇f at many points, in parallel.
    [[nodiscard]] std::vector<Vec3> gradients(const std::vector<Vec3>& xs) const {
        std::vector<Vec3> out(xs.size());
        parallel_for(0, xs.size(), [&](std::size_t i) { out[i] = gradient(xs[i]); }, 512);
        return out;
    }

    /// The supports, in the order they were created, in the caller's coordinates.
    [[nodiscard]] const std::vector<PUSupport>& supports() const {
        static const std::vector<PUSupport> none;
        return data_ ? data_->supports : none;
    }
    /// Bounding box of the input points (caller's units).
    [[nodiscard]] BoundingBox bounding_box() const { return data_ ? data_->box : BoundingBox{}; }
    /// Minimum corner of the bounding cube on which f is defined (caller's units).
    [[nodiscard]] Vec3 domain_min() const {
        return data_ ? Vec3(data_->center - Vec3::Constant(Scalar(0.5) / data_->scale)) : Vec3::Zero();
    }
    /// Side of that cube (caller's units) = the bounding box's longest side.
    [[nodiscard]] Scalar domain_side() const { return data_ ? 1 / data_->scale : 0; }
    /// Whether x lies in the bounding cube (where f is defined).
    [[nodiscard]] bool in_domain(const Vec3& x) const {
        if (!data_) return false;
        const Vec3 u = to_unit(x);
        if (data_->octree.size() > 0) return data_->octree.locate(u) != Octree::npos;
        // Without the octree: its cube, [-0.5, 0.5]^3.
        return (u.array() >= Scalar(-0.5)).all() && (u.array() <= Scalar(0.5)).all();
    }
    /// ε in the caller's units (params.epsilon x the longest side).
    [[nodiscard]] Scalar epsilon() const { return data_ ? data_->epsilon / data_->scale : 0; }
    /// Number of octree cells (= candidate centres).
    [[nodiscard]] std::size_t num_cells() const { return data_ ? data_->octree_cells : 0; }
    /// The octree, in the normalised frame (unit cube centred at the origin): x_unit =
    /// (x - bounding_box().center()) / domain_side(). Empty when built with
    /// PUFieldParams::keep_octree = false.
    [[nodiscard]] const Octree& octree() const {
        static const Octree none;
        return data_ ? data_->octree : none;
    }

private:
    friend struct PUFieldResult;
    [[nodiscard]] Vec3 to_unit(const Vec3& x) const { return (x - data_->center) * data_->scale; }

    Scalar evaluate(const Vec3& x, bool want_grad, Vec3& grad) const {
        constexpr Scalar nan = std::numeric_limits<Scalar>::quiet_NaN();
        grad = Vec3::Constant(nan);
        if (!data_ || data_->local.empty()) return nan;
        const auto& local = data_->local;
        // The paper's F/W (> 0 inside) in the normalised frame; f = -F/W / scale. Its
        // gradient w.r.t. the caller's x is minus that of F/W w.r.t. the normalised one.
        const Scalar fw = data_->pu.blend(
            to_unit(x),
            [&local](std::size_t i, const Vec3& u, Vec3* lg) {
                if (lg) *lg = local[i].m;
                return local[i].m.dot(u) - local[i].md;
            },
            factors_ ? factors_->data() : nullptr, want_grad ? &grad : nullptr);
        if (std::isnan(fw)) return nan;  // grad is NaN too (positive NaNs, like the inputs' checks expect)
        if (want_grad) grad = -grad;
        return -(fw / data_->scale);
    }

    std::shared_ptr<const detail::PUFieldData> data_;
    std::shared_ptr<const std::vector<Scalar>> factors_;  ///< per-support weight factors (none: all 1)
};

/// Result of PUField::build.
struct PUFieldResult {
    PUField field;                  ///< empty unless status == ok
    Status status = Status::ok;
    std::size_t points = 0;         ///< input points
    std::size_t octree_cells = 0;   ///< cells = candidate centres
    std::size_t supports = 0;       ///< supports in the cover
    std::size_t fits_evaluated = 0; ///< support fits computed (speculative ones included)
    std::size_t fallback_supports = 0; ///< supports with no usable fit (nearest tangent plane)
    std::size_t max_level_cells = 0;   ///< cells at max_level
    std::vector<StageTiming> timings;  ///< "pu_octree", "pu_cover", "pu_index"
};

namespace detail {

/// The checks of PUField::build that do not depend on the points' spread, with messages
/// starting with `fn`. tiny_normals: a normal whose squared length underflows (|n| near
/// 1e-200) still counts as a direction, for callers that rescale normals before use
/// (reconstruct_pu_graphcut); PUField::build normalises them itself and refuses those.
inline void pu_validate_input(const std::vector<Vec3>& pts, const std::vector<Vec3>& nrm, int max_level,
                              Scalar epsilon, const std::string& fn, bool tiny_normals) {
    if (max_level < 1 || max_level > 12)
        throw invalid_input(fn + "max_level = " + std::to_string(max_level) +
                            " is outside [1, 12]; the paper uses 8 or 9");
    if (!(epsilon > 0) || !std::isfinite(epsilon))
        throw invalid_input(fn + "epsilon = " + std::to_string(epsilon) +
                            " must be positive and finite (a fraction of the longest bounding-box side, e.g. 4e-3)");
    if (pts.size() < 4)
        throw invalid_input(fn + "needs at least 4 points, got " + std::to_string(pts.size()));
    if (nrm.size() != pts.size())
        throw invalid_input(fn + "the points have no normals (or not one per point); estimate oriented normals first "
                            "(kintsugi::estimate_normals)");
    for (std::size_t i = 0; i < pts.size(); ++i) {
        if (!pts[i].allFinite())
            throw invalid_input(fn + "point " + std::to_string(i) + " has a NaN or infinite coordinate; remove it first");
        if (!nrm[i].allFinite())
            throw invalid_input(fn + "the normal of point " + std::to_string(i) +
                                " has a NaN or infinite component; fix or re-estimate the normals");
        const bool zero = tiny_normals ? !(nrm[i].cwiseAbs().maxCoeff() > 0) : !(nrm[i].squaredNorm() > 0);
        if (zero)
            throw invalid_input(fn + "the normal of point " + std::to_string(i) +
                                " has zero length; fix or re-estimate the normals");
    }
}

inline void pu_validate(const std::vector<Vec3>& pts, const std::vector<Vec3>& nrm, const PUFieldParams& params) {
    const std::string fn = "kintsugi::PUField::build: ";
    pu_validate_input(pts, nrm, params.max_level, params.epsilon, fn, false);
    // Coincident / collinear / coplanar: smallest spread of the points relative to the
    // largest (a spread below 1e-6 of the extent is far below the finest octree cell, 2^-12).
    const Vec3 ev = require_spread_off_a_line(pts, fn, "a surface needs points spread in 3D");
    if (ev[0] <= spread_floor * ev[2])
        throw invalid_input(fn + "all points are coplanar; the PU field needs points spread in 3D (a closed or "
                            "curved scan)");
}

}  // namespace detail

template <OrientedPointSet P>
PUFieldResult PUField::build(const P& points, const PUFieldParams& params) {
    if (!has_normals(points))
        throw invalid_input("kintsugi::PUField::build: the points have no normals; estimate oriented normals first "
                            "(kintsugi::estimate_normals)");
    return build_from(gather_points(points), gather_normals(points), params);
}

static_assert(DifferentiableScalarField<PUField>);

}  // namespace kintsugi

#ifndef KINTSUGI_SEPARATE_STAGES
#include <kintsugi/reconstruct/detail/pu_field_build.ipp>
#endif
