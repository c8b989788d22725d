// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file surfel_coverage.hpp
/// @brief `surfel_coverage`: which points of a surface sampling some surfel (oriented
/// disk) covers, as a point-based renderer would draw them.
///
/// @code
/// kintsugi::SurfelCoverage c = kintsugi::surfel_coverage(surfels, dense_samples);
/// // c.fraction in [0, 1]; c.uncovered: the sample indices no disk covers
/// @endcode
///
/// A sample x is covered by the disk (c, n, r) when its projection onto the disk's
/// plane lies in the disk, |(x - c) - ((x - c)·n) n| <= r, and it is near the plane,
/// |(x - c)·n| <= depth_tolerance · r (the depth test of a splat renderer: a disk
/// stands for the surface within its radius, not for the other side of a thin part).
/// Measurements: docs/methods/surfel_upsampling.md.

#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/surfel_input.hpp>
#include <kintsugi/spatial/kd_tree.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace kintsugi {

/// Parameters of surfel_coverage (aggregate; field order is API, append only).
struct SurfelCoverageParams {
    /// Largest distance of a covered sample from the disk's plane, in units of the
    /// disk's radius. Range > 0; default 0.5: on a sphere of radius R a disk's rim is
    /// r²/2R off its plane (0.03 r for r = R/16), so 0.5 keeps every rim point while
    /// parts thinner than half a radius are not covered through each other.
    Scalar depth_tolerance = 0.5;
    RunControl control{};
};

/// Outcome of surfel_coverage.
struct SurfelCoverage {
    Status status = Status::ok;
    double fraction = 0;                ///< covered samples / samples, in [0, 1]
    std::size_t covered = 0;            ///< number of covered samples
    std::vector<std::size_t> uncovered; ///< indices of the samples no disk covers, increasing
};

/// @brief Fraction of the sample points covered by some surfel (see the file comment).
/// @tparam S a SurfelSet (centres, normals, radii). @tparam Q a PointSet (the samples).
/// @param surfels the disks; normals of any non-zero length.
/// @param samples points on the surface the disks should cover (e.g. a dense sampling).
/// @throws invalid_input for no surfels, missing normals or radii, a NaN/Inf
///         coordinate, a zero normal, a radius that is not finite and > 0, a NaN/Inf
///         sample, or depth_tolerance not > 0.
/// @return status ok with the counts (identical whatever the thread count);
///         cancelled: counts 0 and uncovered empty. Inputs are never modified.
template <SurfelSet S, PointSet Q>
[[nodiscard]] SurfelCoverage surfel_coverage(const S& surfels, const Q& samples, const SurfelCoverageParams& params = {}) {
    const std::string fn = "kintsugi::surfel_coverage";
    if (!(params.depth_tolerance > 0) || !std::isfinite(params.depth_tolerance))
        throw invalid_input(fn + ": params.depth_tolerance must be a finite number > 0 (default 0.5)");
    detail::SurfelInput in = detail::gather_surfels(surfels, fn, true);
    std::vector<Vec3> c = std::move(in.points), nrm = std::move(in.normals);
    std::vector<Scalar> r = std::move(in.radii);
    std::vector<Vec3> q = gather_points(samples);
    Scalar rmax = 0;
    for (std::size_t i = 0; i < q.size(); ++i)
        if (!q[i].allFinite())
            throw invalid_input(fn + ": sample " + std::to_string(i) + " has a NaN or infinite coordinate");
    const detail::ScaleFrame frame = detail::scale_frame(c, q);
    frame.to_local(c);
    frame.to_local(q);
    for (Scalar& x : r) {
        x = frame.to_local(x);
        rmax = std::max(rmax, x);
    }
    SurfelCoverage out;
    detail::Progress progress(params.control);
    try {
        progress.stage("coverage", 0.0, 1.0);
        const Scalar reach = rmax * std::sqrt(1 + params.depth_tolerance * params.depth_tolerance);
        const auto tree = KdTree::adopt(std::move(c));
        std::vector<unsigned char> hit(q.size(), 0);
        const std::size_t m = q.size();
        const std::size_t blocks = std::clamp<std::size_t>(m / 4096, 1, 50);
        for (std::size_t b = 0; b < blocks; ++b) {
            parallel_for(m * b / blocks, m * (b + 1) / blocks, [&](std::size_t s) {
                thread_local std::vector<Neighbor> nb;
                tree.radius_search_squared(q[s], reach * reach, nb);
                for (const Neighbor& x : nb) {
                    const Vec3 d = q[s] - tree.point(x.index);
                    const Scalar h = d.dot(nrm[x.index]);
                    const Scalar rr = r[x.index];
                    if (std::abs(h) <= params.depth_tolerance * rr && (d - h * nrm[x.index]).squaredNorm() <= rr * rr) {
                        hit[s] = 1;
                        return;
                    }
                }
            }, 64);
            progress.update(static_cast<double>(b + 1) / static_cast<double>(blocks));
        }
        for (std::size_t s = 0; s < m; ++s) {
            if (hit[s])
                ++out.covered;
            else
                out.uncovered.push_back(s);
        }
        out.fraction = m == 0 ? 1.0 : static_cast<double>(out.covered) / static_cast<double>(m);
        progress.finish();
    } catch (const detail::cancelled_exception&) {
        out = {};
        out.status = Status::cancelled;
    }
    return out;
}

}  // namespace kintsugi
