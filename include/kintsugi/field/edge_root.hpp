// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file edge_root.hpp
/// @brief Where a scalar field crosses zero along a segment: the first change from
/// inside (f < 0) to outside (f >= 0), bracketed by uniform samples and refined by
/// the Illinois method (regula falsi with halving of the stale end's value; Dowell and
/// Jarratt, BIT 1971). Used by extract_isosurface (field/isosurface.hpp) and by the
/// vertex placement of the PU + graph-cut reconstruction.

#include <kintsugi/core/types.hpp>

#include <optional>

namespace kintsugi {

/// Parameters of find_edge_root.
struct EdgeRootParams {
    /// Uniform samples after t = 0 that look for the sign change, >= 1. More samples
    /// find a crossing that the two ends do not show (a thin sheet); 1 trusts the ends.
    int samples = 8;
    /// Illinois iterations at most, >= 0. Each halves the bracket at least every
    /// second step; 30 reaches the tolerance on any smooth field.
    int max_iterations = 30;
    /// The refinement stops when the bracket is shorter than this (in t), > 0.
    Scalar tolerance = 1e-9;
};

/// @brief The parameter t of the first crossing from f < 0 to f >= 0 along a segment,
/// the segment being parametrised by t in [0, 1] from its inside end.
///
/// @param f  callable f(t) -> Scalar for t in [0, 1] (called with t = 0 and t = 1
///           too, so the caller can return known end values); a NaN must be mapped
///           by the caller to a number (which side it counts on is the caller's choice).
/// @param params samples, iterations, tolerance (not validated here: the callers do).
/// @return t in [0, 1] (the last secant estimate inside the final bracket), or
///         nothing when no sample goes from < 0 to >= 0.
/// Evaluations: at most samples + 1 + max_iterations calls of f.
template <class F>
[[nodiscard]] std::optional<Scalar> find_edge_root(F&& f, const EdgeRootParams& params = {}) {
    Scalar t0 = 0, f0 = f(Scalar(0));
    bool bracket = false;
    Scalar t1 = 0, f1 = 0;
    for (int k = 1; k <= params.samples; ++k) {
        const Scalar t = static_cast<Scalar>(k) / params.samples;
        const Scalar ft = f(t);
        if (f0 < 0 && ft >= 0) {
            t1 = t;
            f1 = ft;
            bracket = true;
            break;
        }
        t0 = t;
        f0 = ft;
    }
    if (!bracket) return std::nullopt;
    int side = 0;
    for (int it = 0; it < params.max_iterations && t1 - t0 > params.tolerance; ++it) {
        const Scalar t = f0 == f1 ? (t0 + t1) / 2 : t0 + f0 * (t1 - t0) / (f0 - f1);
        const Scalar ft = f(t);
        if (ft < 0) {
            t0 = t;
            f0 = ft;
            if (side == -1) f1 /= 2;
            side = -1;
        } else if (ft > 0) {
            t1 = t;
            f1 = ft;
            if (side == 1) f0 /= 2;
            side = 1;
        } else {
            t0 = t1 = t;
            break;
        }
    }
    return f0 == f1 ? (t0 + t1) / 2 : t0 + f0 * (t1 - t0) / (f0 - f1);
}

}  // namespace kintsugi
