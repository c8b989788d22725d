// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file projection.hpp
/// @brief Any user range of structs as a point set, through projections
/// (member pointers or callables), in the style of std::ranges projections.
///
/// @code
/// struct Sample { float xyz[3]; Eigen::Vector3f n; int label; };
/// std::vector<Sample> samples = ...;
/// auto pts = kintsugi::project_points(samples, &Sample::xyz, &Sample::n);
/// // or with lambdas:
/// auto pts2 = kintsugi::project_points(samples, [](const Sample& s) { return s.xyz; });
/// @endcode
/// A projection may return an Eigen vector, std::array<T,3>, T[3], a type with
/// x()/y()/z() or with .x/.y/.z. When the normal projection yields a non-const
/// lvalue reference to an Eigen vector or std::array, the view is also
/// NormalWritablePointSet. The range must be random access and outlive the view.

#include <kintsugi/core/concepts.hpp>

#include <functional>
#include <iterator>
#include <ranges>
#include <type_traits>

namespace kintsugi {

/// Tag for "no normal projection".
struct no_normals {};

/// Non-owning view of a random-access range through projections.
template <class Range, class PosProj, class NormalProj = no_normals>
struct ProjectedPoints {
    Range* range;
    PosProj position;
    NormalProj normal;
};

/// Views `range` as a point set whose positions are `std::invoke(position, element)`.
template <std::ranges::random_access_range Range, class PosProj>
[[nodiscard]] ProjectedPoints<Range, PosProj> project_points(Range& range, PosProj position) {
    return {&range, std::move(position), {}};
}
/// Same with normals `std::invoke(normal, element)`: an OrientedPointSet.
template <std::ranges::random_access_range Range, class PosProj, class NormalProj>
[[nodiscard]] ProjectedPoints<Range, PosProj, NormalProj> project_points(Range& range, PosProj position,
                                                                         NormalProj normal) {
    return {&range, std::move(position), std::move(normal)};
}

namespace detail {
template <class Range>
decltype(auto) element(Range* r, std::size_t i) {
    return std::ranges::begin(*r)[static_cast<std::ranges::range_difference_t<Range>>(i)];
}
}  // namespace detail

template <class Range, class PosProj>
struct point_set_traits<ProjectedPoints<Range, PosProj, no_normals>> {
    using View = ProjectedPoints<Range, PosProj, no_normals>;
    static std::size_t size(const View& v) { return static_cast<std::size_t>(std::ranges::size(*v.range)); }
    static Vec3 point(const View& v, std::size_t i) {
        return detail::to_vec3(std::invoke(v.position, detail::element(v.range, i)));
    }
};

template <class Range, class PosProj, class NormalProj>
struct point_set_traits<ProjectedPoints<Range, PosProj, NormalProj>> {
    using View = ProjectedPoints<Range, PosProj, NormalProj>;
    static std::size_t size(const View& v) { return static_cast<std::size_t>(std::ranges::size(*v.range)); }
    static Vec3 point(const View& v, std::size_t i) {
        return detail::to_vec3(std::invoke(v.position, detail::element(v.range, i)));
    }
    static Vec3 normal(const View& v, std::size_t i) {
        return detail::to_vec3(std::invoke(v.normal, detail::element(v.range, i)));
    }
    using NormalRef = std::invoke_result_t<const NormalProj&, std::ranges::range_reference_t<Range>>;
    static constexpr bool writable_normals =
        std::is_lvalue_reference_v<NormalRef> && !std::is_const_v<std::remove_reference_t<NormalRef>>;
    static void set_normal(const View& v, std::size_t i, const Vec3& n)
        requires writable_normals
    {
        auto& dst = std::invoke(v.normal, detail::element(v.range, i));
        for (int c = 0; c < 3; ++c) dst[c] = static_cast<std::remove_cvref_t<decltype(dst[0])>>(n[c]);
    }
};

}  // namespace kintsugi
