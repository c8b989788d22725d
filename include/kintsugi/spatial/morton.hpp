// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file morton.hpp
/// @brief Morton (Z-order) codes: 21 bits per axis interleaved into 63 bits (x in
/// bit 0, y in bit 1, z in bit 2), and the order of a point set along that curve.
///
/// @code
/// std::uint64_t c = kintsugi::morton_encode(x, y, z);   // integer cell coordinates
/// auto [x, y, z] = kintsugi::morton_decode(c);
/// const kintsugi::MortonBox box(points);                 // quantise in the bounding box
/// std::uint64_t k = box.code(p);
/// std::vector<kintsugi::Index> order = kintsugi::morton_order(points);  // nearby = close
/// @endcode
///
/// Sorting by Morton code puts points that are close in space mostly close in memory,
/// so later neighbourhood queries read nearby memory (the octree's cells, the
/// smoothing's renumbering, the distance queries' runs all use it).

#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>


namespace kintsugi {

/// Spreads the low 21 bits of v so that bit i moves to bit 3i (higher bits ignored).
[[nodiscard]] constexpr std::uint64_t morton_spread(std::uint64_t v) {
    v &= 0x1fffffULL;
    v = (v | v << 32) & 0x1f00000000ffffULL;
    v = (v | v << 16) & 0x1f0000ff0000ffULL;
    v = (v | v << 8) & 0x100f00f00f00f00fULL;
    v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
    v = (v | v << 2) & 0x1249249249249249ULL;
    return v;
}

/// Inverse of morton_spread: bits 0, 3, 6, ... of v gathered into the low 21 bits.
[[nodiscard]] constexpr std::uint32_t morton_compact(std::uint64_t v) {
    v &= 0x1249249249249249ULL;
    v = (v ^ (v >> 2)) & 0x10c30c30c30c30c3ULL;
    v = (v ^ (v >> 4)) & 0x100f00f00f00f00fULL;
    v = (v ^ (v >> 8)) & 0x1f0000ff0000ffULL;
    v = (v ^ (v >> 16)) & 0x1f00000000ffffULL;
    v = (v ^ (v >> 32)) & 0x1fffffULL;
    return static_cast<std::uint32_t>(v);
}

/// Morton code of integer coordinates, each in [0, 2^21) (higher bits ignored).
[[nodiscard]] constexpr std::uint64_t morton_encode(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    return morton_spread(x) | (morton_spread(y) << 1) | (morton_spread(z) << 2);
}

/// Integer coordinates {x, y, z} of a Morton code.
[[nodiscard]] constexpr std::array<std::uint32_t, 3> morton_decode(std::uint64_t c) {
    return {morton_compact(c), morton_compact(c >> 1), morton_compact(c >> 2)};
}

/// Quantises positions in an axis-aligned box to Morton codes, 2^21 - 1 steps per
/// axis: coordinates are scaled to [0, 1] per axis (on a flat axis: 0 on it, 1 above),
/// clamped, multiplied by 2^21 - 1 and truncated.
class MortonBox {
public:
    /// The bounding box of `points` (any PointSet; an empty set gives the unit cube at 0).
    template <PointSet P>
    explicit MortonBox(const P& points) {
        const std::size_t n = kintsugi::num_points(points);
        Vec3 lo = Vec3::Constant(std::numeric_limits<Scalar>::max()), hi = -lo;
        for (std::size_t i = 0; i < n; ++i) {
            const Vec3 p = kintsugi::point_at(points, i);
            lo = lo.cwiseMin(p);
            hi = hi.cwiseMax(p);
        }
        if (n == 0) lo = hi = Vec3::Zero();
        set(lo, hi);
    }
    /// The box [lo, hi] (hi >= lo per axis).
    MortonBox(const Vec3& lo, const Vec3& hi) { set(lo, hi); }

    /// Morton code of p; points outside the box are clamped to its faces. @pre p finite
    [[nodiscard]] std::uint64_t code(const Vec3& p) const {
        const Vec3 a = (p - lo_).cwiseQuotient(extent_) * top_;
        std::uint64_t key = 0;
        for (int k = 0; k < 3; ++k)
            key |= morton_spread(static_cast<std::uint64_t>(std::clamp(a[k], Scalar(0), top_))) << k;
        return key;
    }
    [[nodiscard]] const Vec3& min() const { return lo_; }

private:
    void set(const Vec3& lo, const Vec3& hi) {
        lo_ = lo;
        // A flat axis divides 0 by the smallest normal number: 0, as for any point on it.
        extent_ = (hi - lo).cwiseMax(Vec3::Constant(std::numeric_limits<Scalar>::min()));
    }
    static constexpr Scalar top_ = Scalar((1 << 21) - 1);
    Vec3 lo_ = Vec3::Zero(), extent_ = Vec3::Ones();
};


/// The indices 0..n-1 sorted by the Morton code of position_of(i) in `box`, ties by
/// index (deterministic whatever the thread count).
/// @param position_of callable Index -> Vec3 (called once per index, possibly from
///        several threads)
template <class PositionOf>
[[nodiscard]] std::vector<Index> morton_order(std::size_t n, const MortonBox& box, PositionOf&& position_of) {
    std::vector<std::pair<std::uint64_t, Index>> keyed(n);
    parallel_for(0, n, [&](std::size_t i) { keyed[i] = {box.code(position_of(i)), i}; }, 4096);
    detail::sort_maybe_parallel(keyed);
    std::vector<Index> order(n);
    for (std::size_t k = 0; k < n; ++k) order[k] = keyed[k].second;
    return order;
}

/// The point indices sorted along the Morton curve of the points' bounding box, ties
/// by index. @tparam P a PointSet. @pre finite coordinates
template <PointSet P>
[[nodiscard]] std::vector<Index> morton_order(const P& points) {
    return morton_order(kintsugi::num_points(points), MortonBox(points),
                        [&](Index i) { return Vec3(kintsugi::point_at(points, i)); });
}

}  // namespace kintsugi
