// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file jet_fit.hpp
/// @brief The one local polynomial ("jet") fit of the library: a height function
/// z = J(x, y) of degree 2 to 4 fitted by least squares to a neighbourhood, and the
/// differential quantities it gives at the neighbourhood's origin point: the normal,
/// the principal curvatures and the principal directions.
///
/// @code
/// std::vector<kintsugi::Vec3> nb = ...;                 // the point first, then its neighbours
/// kintsugi::JetFit j = kintsugi::fit_jet(nb, {.degree = 3});
/// kintsugi::orient_jet(j, reference_normal);            // sign: along a known normal
/// // j.normal, j.k1 >= j.k2 (positive on a sphere with outward normals), j.d1, j.d2
/// @endcode
///
/// Method: Cazals & Pouget, "Estimating differential quantities using polynomial
/// fitting of osculating jets", CAGD 22(2), 2005 — the fit of CGAL's
/// Monge_via_jet_fitting: PCA frame of the neighbourhood (x, y along the two largest
/// eigenvectors, z along the smallest), origin at the first point, x and y divided by
/// the mean of (|x| + |y|) / 2 (CGAL's preconditioning), monomials x^i y^j / (i! j!)
/// by increasing total degree, solved by column-pivoting Householder QR (6x faster
/// than CGAL's JacobiSVD per point, same normals to 3e-8 rad; see normals/).
/// The normal and curvatures are those of the fitted graph at (0, 0): the shape
/// operator I⁻¹·II of the graph surface, so no second (Monge) frame is needed.
/// normals/estimate_normals (degree 2) and mesh/curvature call this fit.

#include <kintsugi/core/types.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include <cmath>
#include <cstddef>
#include <span>
#include <utility>

namespace kintsugi {

/// Options of fit_jet (aggregate; field order is API, append only).
struct JetFitParams {
    /// Degree of the fitted polynomial, 2 to 4. 2 (the osculating quadric) suffices
    /// for normals; 3 or 4 removes the curvature bias of larger neighbourhoods
    /// (Cazals & Pouget's error O(h^(d-1))). Needs at least (d+1)(d+2)/2 points:
    /// 6, 10, 15.
    int degree = 2;
};

/// What fit_jet returns: the fitted surface's quantities at the origin point.
struct JetFit {
    bool valid = false;  ///< false when the neighbourhood is degenerate (too few or coincident points)
    Vec3 normal = Vec3::Zero();  ///< unit normal; its sign follows the PCA frame unless oriented (orient_jet)
    /// Principal curvatures (1/units), k1 >= k2, signed with respect to `normal`:
    /// positive where the surface bends away from the normal (1/R on a sphere of
    /// radius R with outward normals), negative where it bends towards it.
    Scalar k1 = 0, k2 = 0;
    Vec3 d1 = Vec3::Zero(), d2 = Vec3::Zero();  ///< unit principal directions of k1 and k2 (tangent, orthogonal)
    Vec3 point = Vec3::Zero();                  ///< the jet's surface point above the origin point
    /// Mean curvature (k1 + k2) / 2.
    [[nodiscard]] Scalar mean_curvature() const { return (k1 + k2) / 2; }
    /// Gaussian curvature k1 * k2.
    [[nodiscard]] Scalar gaussian_curvature() const { return k1 * k2; }
};

/// Number of coefficients of a bivariate polynomial of degree d: (d+1)(d+2)/2.
[[nodiscard]] constexpr std::size_t jet_coefficients(int degree) {
    return static_cast<std::size_t>((degree + 1) * (degree + 2) / 2);
}

/// Turns `j` so that its normal points along `reference` (flips the normal, negates
/// and reorders the curvatures); nothing when `j` is invalid or reference is zero.
inline void orient_jet(JetFit& j, const Vec3& reference) {
    if (!j.valid || j.normal.dot(reference) >= 0) return;
    j.normal = -j.normal;
    const Scalar k1 = -j.k2, k2 = -j.k1;
    j.k1 = k1;
    j.k2 = k2;
    std::swap(j.d1, j.d2);
}

namespace detail {

/// Eigenvectors of the covariance of the k points get(0..k-1), by increasing
/// eigenvalue (column 0 is the PCA normal). Closed form, iterative fallback.
template <class Get>
Eigen::Matrix3d pca_frame(Get&& get, std::size_t k) {
    Vec3 c = Vec3::Zero();
    for (std::size_t j = 0; j < k; ++j) c += get(j);
    c /= static_cast<Scalar>(k);
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (std::size_t j = 0; j < k; ++j) {
        const Vec3 d = get(j) - c;
        cov.selfadjointView<Eigen::Lower>().rankUpdate(d);
    }
    cov = cov.selfadjointView<Eigen::Lower>();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(cov);
    Eigen::Matrix3d frame = es.eigenvectors();
    if (!frame.allFinite() || std::abs(frame.determinant()) < 0.5) {
        // computeDirect can lose accuracy on nearly degenerate spectra; the
        // iterative solver is exact to rounding (rare path).
        es.compute(cov);
        frame = es.eigenvectors();
    }
    return frame;
}

/// The jet fit over the k points get(0..k-1), frame origin `p0` (get(0) for a
/// sample's own fit); `curvature` false computes the normal only (the normals' hot loop).
template <class Get>
JetFit fit_jet(Get&& get, std::size_t k, const Vec3& p0, int degree, bool curvature) {
    JetFit out;
    const std::size_t nc = jet_coefficients(degree);
    if (degree < 2 || degree > 4 || k < nc) return out;
    const Eigen::Matrix3d frame = pca_frame(get, k);
    // Fitting basis: x = largest eigenvector, y = middle, z = smallest.
    const Vec3 ex = frame.col(2), ey = frame.col(1), ez = frame.col(0);
    const auto rows = static_cast<Eigen::Index>(k);
    const auto cols = static_cast<Eigen::Index>(nc);
    thread_local Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic> M;
    thread_local Eigen::Matrix<Scalar, Eigen::Dynamic, 1> Z;
    thread_local Eigen::Matrix<Scalar, Eigen::Dynamic, 2> xy;
    M.resize(rows, cols);
    Z.resize(rows);
    xy.resize(rows, 2);
    Scalar h = 0;  // CGAL's preconditioning: mean of (|x| + |y|) / 2
    for (Eigen::Index j = 0; j < rows; ++j) {
        const Vec3 d = get(static_cast<std::size_t>(j)) - p0;
        xy(j, 0) = d.dot(ex);
        xy(j, 1) = d.dot(ey);
        Z(j) = d.dot(ez);
        h += std::abs(xy(j, 0)) + std::abs(xy(j, 1));
    }
    h /= 2 * static_cast<Scalar>(k);
    if (!(h > 0) || !std::isfinite(h)) return out;
    static constexpr Scalar inv_fact[5] = {1, 1, 0.5, 1.0 / 6, 1.0 / 24};
    for (Eigen::Index j = 0; j < rows; ++j) {
        const Scalar x = xy(j, 0) / h, y = xy(j, 1) / h;
        Scalar xp[5] = {1, x, 0, 0, 0}, yp[5] = {1, y, 0, 0, 0};
        for (int e = 2; e <= degree; ++e) {
            xp[e] = xp[e - 1] * x;
            yp[e] = yp[e - 1] * y;
        }
        Eigen::Index c = 0;
        for (int d = 0; d <= degree; ++d)
            for (int i = d; i >= 0; --i) M(j, c++) = xp[i] * yp[d - i] * inv_fact[i] * inv_fact[d - i];
    }
    const Eigen::Matrix<Scalar, Eigen::Dynamic, 1> a = M.colPivHouseholderQr().solve(Z);
    // Derivatives at (0, 0) in the unscaled frame: coefficient of x^i y^j / (i! j!) over h^(i+j).
    const Scalar fx = a(1) / h, fy = a(2) / h;
    const Vec3 local = Vec3(-fx, -fy, 1).normalized();
    const Vec3 n = local.x() * ex + local.y() * ey + local.z() * ez;
    const Scalar len = n.norm();
    if (!std::isfinite(len) || len < 0.5) return out;
    out.normal = n / len;
    out.point = p0 + a(0) * ez;
    out.valid = true;
    if (!curvature) return out;
    const Scalar fxx = a(3) / (h * h), fxy = a(4) / (h * h), fyy = a(5) / (h * h);
    // Shape operator of the graph (x, y, f(x, y)) at (0, 0): I⁻¹ II, with II taken
    // along -n so that a sphere with outward normal has positive curvature.
    const Scalar w = std::sqrt(1 + fx * fx + fy * fy);
    Eigen::Matrix2d I, II;
    I << 1 + fx * fx, fx * fy, fx * fy, 1 + fy * fy;
    II << -fxx / w, -fxy / w, -fxy / w, -fyy / w;
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::Matrix2d> ges(II, I);
    if (ges.info() != Eigen::Success || !ges.eigenvalues().allFinite()) {
        out.valid = false;
        return out;
    }
    // Eigenvalues increase: column 1 is k1 (the larger).
    const Vec3 tx = ex + fx * ez, ty = ey + fy * ez;  // tangent vectors of the parametrisation
    out.k1 = ges.eigenvalues()(1);
    out.k2 = ges.eigenvalues()(0);
    out.d1 = (ges.eigenvectors()(0, 1) * tx + ges.eigenvectors()(1, 1) * ty).normalized();
    out.d2 = out.normal.cross(out.d1).normalized();
    return out;
}

/// The fit over the k points get(0..k-1) at their first point get(0).
template <class Get>
JetFit fit_jet(Get&& get, std::size_t k, int degree, bool curvature) {
    if (k == 0) return {};
    const Vec3 p0 = get(0);
    return fit_jet(get, k, p0, degree, curvature);
}

}  // namespace detail

/// @brief Fits a jet to a neighbourhood and returns the normal, principal curvatures
/// and directions at its first point (Cazals & Pouget 2005; see the file comment).
/// @param points the origin point first, then its neighbours (any order); at least
///        jet_coefficients(degree) points (6, 10, 15), more for noisy data.
/// @param params degree 2..4.
/// @return the fit; `valid` is false (nothing else set) when the degree is out of
///         range, there are too few points, or they are degenerate (coincident,
///         collinear, or not a height function over their PCA plane).
[[nodiscard]] inline JetFit fit_jet(std::span<const Vec3> points, const JetFitParams& params = {}) {
    return detail::fit_jet([&](std::size_t j) -> const Vec3& { return points[j]; }, points.size(), params.degree,
                           true);
}

/// @brief Same, at a point that need not be a sample: the jet is fitted to `points`
/// only, in a frame centred at `origin`, and its quantities are those of the surface
/// point above `origin` (JetFit::point); e.g. the curvature at a new surfel from its
/// nearest input samples.
/// @param origin where the quantities are wanted (near the samples: within their spread).
/// @param points the neighbourhood, at least jet_coefficients(degree) points.
[[nodiscard]] inline JetFit fit_jet_at(const Vec3& origin, std::span<const Vec3> points,
                                       const JetFitParams& params = {}) {
    return detail::fit_jet([&](std::size_t j) -> const Vec3& { return points[j]; }, points.size(), origin,
                           params.degree, true);
}

}  // namespace kintsugi
