// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file frame.hpp
/// @brief Internal: the power-of-two rescaling every algorithm applies to its copy of
/// the input so that coordinates of any finite magnitude work.
///
/// Squared distances overflow double above about 1.3e154 and underflow below about
/// 1e-154; the smoothing's single-precision neighbour tests have narrower limits. An
/// algorithm reads the user's points into its own layout, multiplies them by 2^-shift
/// (chosen so the extent lands in [1, 2)), runs, and maps lengths and positions back
/// by 2^shift. Multiplying by a power of two is exact (no rounding) and commutes with
/// every rounding the algorithms do, so a rescaled run gives the same bits as the
/// unscaled run of the same shape. Inputs whose extent is already in
/// [2^-32, 2^32] are not touched (shift 0).

#include <kintsugi/core/types.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace kintsugi::detail {

/// A length for a message, in %g form ("1e+300", not std::to_string's 300 digits).
[[nodiscard]] inline std::string format_number(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", x);
    return buf;
}

/// p -> p · 2^-shift (local) and back (world).
struct ScaleFrame {
    int shift = 0;  ///< 0: identity

    [[nodiscard]] bool identity() const { return shift == 0; }
    [[nodiscard]] Scalar to_local(Scalar x) const { return std::ldexp(x, -shift); }
    [[nodiscard]] Scalar to_world(Scalar x) const { return std::ldexp(x, shift); }
    /// For squared lengths and areas.
    [[nodiscard]] Scalar to_world_squared(Scalar x) const { return std::ldexp(x, 2 * shift); }
    [[nodiscard]] Scalar to_local_squared(Scalar x) const { return std::ldexp(x, -2 * shift); }
    [[nodiscard]] Vec3 to_local(const Vec3& p) const {
        return {std::ldexp(p.x(), -shift), std::ldexp(p.y(), -shift), std::ldexp(p.z(), -shift)};
    }
    [[nodiscard]] Vec3 to_world(const Vec3& p) const {
        return {std::ldexp(p.x(), shift), std::ldexp(p.y(), shift), std::ldexp(p.z(), shift)};
    }
    void to_local(std::vector<Vec3>& pts) const {
        if (shift != 0)
            for (Vec3& p : pts) p = to_local(p);
    }
    void to_world(std::vector<Vec3>& pts) const {
        if (shift != 0)
            for (Vec3& p : pts) p = to_world(p);
    }
};

/// The frame for one or more sets of points taken together: extent E = the largest
/// side of their bounding box (the largest |coordinate| when they all coincide).
/// shift = 0 when E is 0, or in [2^-32, 2^32]; otherwise the exponent that brings E
/// into [1, 2). Non-finite coordinates are ignored (callers reject them).
template <class... Sets>
[[nodiscard]] ScaleFrame scale_frame(const std::vector<Vec3>& first, const Sets&... more) {
    BoundingBox box;
    Scalar largest = 0;
    auto add = [&](const std::vector<Vec3>& pts) {
        for (const Vec3& p : pts)
            if (p.allFinite()) {
                box.extend(p);
                largest = std::max(largest, p.cwiseAbs().maxCoeff());
            }
    };
    add(first);
    (add(more), ...);
    // Half the extent: max - min itself may overflow for points near +-DBL_MAX.
    Scalar half = box.empty() ? Scalar(0) : (box.max / 2 - box.min / 2).maxCoeff();
    if (!(half > 0)) half = largest / 2;
    if (!(half > 0) || !std::isfinite(half)) return {};
    if (half >= std::ldexp(Scalar(1), -33) && half <= std::ldexp(Scalar(1), 31)) return {};
    return {std::ilogb(half) + 1};
}

}  // namespace kintsugi::detail
