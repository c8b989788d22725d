// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file spread.hpp
/// @brief How far points spread along their principal directions (internal): the checks
/// that refuse points all at one place or on one line (the PU field, normal estimation).

#include <kintsugi/core/error.hpp>
#include <kintsugi/core/types.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <string>
#include <vector>

namespace kintsugi::detail {

/// The eigenvalues, increasing, of the points' scatter matrix about their mean, for the
/// points scaled by their largest coordinate offset from their box's centre (so that any
/// finite coordinates, 1e300 as 1e-300, give finite sums; only ratios of them are meant to be
/// read). All zero when the points coincide.
inline Vec3 spread_eigenvalues(const std::vector<Vec3>& pts) {
    if (pts.empty()) return Vec3::Zero();
    Vec3 lo = pts[0], hi = pts[0];
    for (const auto& p : pts) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    const Vec3 half_centre = lo / 2 + hi / 2;  // halves: no overflow at the ends of the range
    Scalar m = 0;
    for (const auto& p : pts) m = std::max(m, (p / 2 - half_centre / 2).cwiseAbs().maxCoeff());
    if (!(m > 0)) return Vec3::Zero();
    auto scaled = [&](const Vec3& p) -> Vec3 { return (p / 2 - half_centre / 2) / m; };
    Vec3 mean = Vec3::Zero();
    for (const auto& p : pts) mean += scaled(p);
    mean /= static_cast<Scalar>(pts.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : pts) {
        const Vec3 q = scaled(p) - mean;
        cov += q * q.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov, Eigen::EigenvaluesOnly);
    return es.eigenvalues();
}

/// A spread below this share of the largest is none: the eigen solver's accuracy is about
/// 1e-15, and a spread of 1e-6 of the extent is far below any scale the methods resolve.
inline constexpr Scalar spread_floor = 1e-12;

/// Throws invalid_input(`fn` + ...) when all `pts` coincide or lie on one line; `need`
/// ends the message (what the caller needs, e.g. "a surface needs points spread in 3D").
/// @return spread_eigenvalues(pts), for further checks (coplanar: ev[0] <= spread_floor * ev[2])
inline Vec3 require_spread_off_a_line(const std::vector<Vec3>& pts, const std::string& fn, const std::string& need) {
    const Vec3 ev = spread_eigenvalues(pts);
    if (!(ev[2] > 0)) throw invalid_input(fn + "all points coincide; " + need);
    if (ev[1] <= spread_floor * ev[2]) throw invalid_input(fn + "all points are collinear; " + need);
    return ev;
}

}  // namespace kintsugi::detail
