// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file types.hpp
/// @brief Basic value types shared by every kintsugi module.

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <limits>

namespace kintsugi {

/// Floating-point type of the internal layout. Every algorithm reads the user's
/// container once into this precision.
using Scalar = double;
/// A point, vector or normal in 3D.
using Vec3 = Eigen::Matrix<Scalar, 3, 1>;
/// Index of a vertex, face or point.
using Index = std::size_t;
/// A triangle as three vertex indices, counter-clockwise seen from outside.
using Face = std::array<Index, 3>;

/// Axis-aligned bounding box.
struct BoundingBox {
    Vec3 min = Vec3::Constant(std::numeric_limits<Scalar>::infinity());
    Vec3 max = Vec3::Constant(-std::numeric_limits<Scalar>::infinity());

    void extend(const Vec3& p) {
        min = min.cwiseMin(p);
        max = max.cwiseMax(p);
    }
    [[nodiscard]] bool empty() const { return !(min.array() <= max.array()).all(); }
    [[nodiscard]] Vec3 extent() const { return empty() ? Vec3::Zero() : Vec3(max - min); }
    [[nodiscard]] Scalar diagonal() const { return extent().norm(); }
    [[nodiscard]] Vec3 center() const { return empty() ? Vec3::Zero() : Vec3((min + max) / 2); }
};

}  // namespace kintsugi
