// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file surfel_input.hpp
/// @brief Internal: the one gather-and-check of a surfel input (centres, normals,
/// optional radii) shared by fill_surfel_gaps and surfel_coverage, so both reject the
/// same inputs with the same messages.

#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>

#include <cmath>
#include <string>
#include <vector>

namespace kintsugi::detail {

/// Surfels copied into the internal layout; normals of unit length; radii empty when
/// the input has none.
struct SurfelInput {
    std::vector<Vec3> points, normals;
    std::vector<Scalar> radii;
};

/// Copies and checks a surfel input. Throws invalid_input "<fn>: ..." for no surfels,
/// missing normals, missing radii (when `require_radii`), a NaN/Inf coordinate
/// ("surfel i"), a zero, NaN or infinite normal ("the normal of surfel i") or a radius
/// that is not finite and > 0 ("the radius of surfel i"). The input is not modified.
template <OrientedPointSet S>
[[nodiscard]] SurfelInput gather_surfels(const S& surfels, const std::string& fn, bool require_radii) {
    const std::size_t n = num_points(surfels);
    if (n == 0) throw invalid_input(fn + ": there are no surfels; pass at least one oriented point");
    if (!has_normals(surfels))
        throw invalid_input(fn + ": the surfels have no normals; estimate and orient them first (kintsugi::estimate_normals)");
    SurfelInput in{gather_points(surfels), gather_normals(surfels), gather_radii(surfels)};
    if (require_radii && in.radii.empty())
        throw invalid_input(fn + ": the surfels have no radii; every disk needs one");
    for (std::size_t i = 0; i < n; ++i) {
        if (!in.points[i].allFinite())
            throw invalid_input(fn + ": surfel " + std::to_string(i) + " has a NaN or infinite coordinate; remove it first");
        const Scalar len = in.normals[i].norm();
        if (!(len > 0) || !std::isfinite(len))
            throw invalid_input(fn + ": the normal of surfel " + std::to_string(i) +
                                " is zero, NaN or infinite; estimate normals first or remove the surfel");
        in.normals[i] /= len;
        if (!in.radii.empty() && (!(in.radii[i] > 0) || !std::isfinite(in.radii[i])))
            throw invalid_input(fn + ": the radius of surfel " + std::to_string(i) + " is " + format_number(in.radii[i]) +
                                "; radii must be finite and > 0");
    }
    return in;
}

}  // namespace kintsugi::detail
