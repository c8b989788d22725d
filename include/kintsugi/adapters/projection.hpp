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
/// // surfels (oriented disks): a third projection gives the radius
/// struct Disk { Eigen::Vector3d p, n; float r; };
/// std::vector<Disk> disks;
/// auto surfels = kintsugi::project_surfels(disks, &Disk::p, &Disk::n, &Disk::r);
/// kintsugi::append_surfel(surfels, p, n, 0.01);   // disks.emplace_back(), then written
/// @endcode
/// A projection may return an Eigen vector, std::array<T,3>, T[3], a type with
/// x()/y()/z() or with .x/.y/.z; a radius projection returns any arithmetic type.
/// When the normal projection yields a non-const lvalue reference to an Eigen vector
/// or std::array, the view is also NormalWritablePointSet. When the range is a
/// container with clear() and emplace_back() of a default-constructible element and
/// every projection yields a writable lvalue (indexable vectors: Eigen, std::array,
/// T[3]; an arithmetic radius), the view is a GrowablePointSet (GrowableSurfelSet
/// with a radius projection). The range must be random access and outlive the view.

#include <kintsugi/core/concepts.hpp>

#include <functional>
#include <iterator>
#include <ranges>
#include <type_traits>

namespace kintsugi {

/// Tag for "no normal projection".
struct no_normals {};
/// Tag for "no radius projection".
struct no_radii {};

/// Non-owning view of a random-access range through projections.
template <class Range, class PosProj, class NormalProj = no_normals, class RadiusProj = no_radii>
struct ProjectedPoints {
    Range* range;
    PosProj position;
    NormalProj normal;
    RadiusProj radius;
};

/// Views `range` as a point set whose positions are `std::invoke(position, element)`.
template <std::ranges::random_access_range Range, class PosProj>
[[nodiscard]] ProjectedPoints<Range, PosProj> project_points(Range& range, PosProj position) {
    return {&range, std::move(position), {}, {}};
}
/// Same with normals `std::invoke(normal, element)`: an OrientedPointSet.
template <std::ranges::random_access_range Range, class PosProj, class NormalProj>
[[nodiscard]] ProjectedPoints<Range, PosProj, NormalProj> project_points(Range& range, PosProj position,
                                                                         NormalProj normal) {
    return {&range, std::move(position), std::move(normal), {}};
}
/// Views `range` as surfels: positions, normals and radii `std::invoke(radius, element)`
/// (a SurfelSet; a GrowableSurfelSet when the range and projections allow, see above).
template <std::ranges::random_access_range Range, class PosProj, class NormalProj, class RadiusProj>
[[nodiscard]] ProjectedPoints<Range, PosProj, NormalProj, RadiusProj> project_surfels(Range& range, PosProj position,
                                                                                      NormalProj normal,
                                                                                      RadiusProj radius) {
    return {&range, std::move(position), std::move(normal), std::move(radius)};
}

namespace detail {
template <class Range>
decltype(auto) element(Range* r, std::size_t i) {
    return std::ranges::begin(*r)[static_cast<std::ranges::range_difference_t<Range>>(i)];
}

/// Whether invoking `Proj` on an element of `Range` yields a writable lvalue.
template <class Range, class Proj>
constexpr bool projects_to_writable_lvalue() {
    if constexpr (!std::is_invocable_v<const Proj&, std::ranges::range_reference_t<Range>>) {
        return false;
    } else {
        using Ref = std::invoke_result_t<const Proj&, std::ranges::range_reference_t<Range>>;
        return std::is_lvalue_reference_v<Ref> && !std::is_const_v<std::remove_reference_t<Ref>>;
    }
}

/// Writes v into an indexable 3-vector (Eigen vector, std::array, T[3]).
template <class Dst>
void assign_vec3(Dst& dst, const Vec3& v) {
    for (int c = 0; c < 3; ++c) dst[c] = static_cast<std::remove_cvref_t<decltype(dst[0])>>(v[c]);
}

/// Whether the range can be cleared and grown by one default-constructed element.
template <class Range>
concept ClearableAppendableRange =
    !std::is_const_v<Range> && requires(Range& r) {
        r.clear();
        r.emplace_back();
    };
}  // namespace detail

template <class Range, class PosProj, class NormalProj, class RadiusProj>
struct point_set_traits<ProjectedPoints<Range, PosProj, NormalProj, RadiusProj>> {
    using View = ProjectedPoints<Range, PosProj, NormalProj, RadiusProj>;
    static constexpr bool oriented = !std::is_same_v<NormalProj, no_normals>;
    static constexpr bool surfels = !std::is_same_v<RadiusProj, no_radii>;
    static constexpr bool writable_positions = detail::projects_to_writable_lvalue<Range, PosProj>();
    static constexpr bool writable_normals = oriented && detail::projects_to_writable_lvalue<Range, NormalProj>();
    static constexpr bool writable_radii = surfels && detail::projects_to_writable_lvalue<Range, RadiusProj>();
    static constexpr bool growable = detail::ClearableAppendableRange<Range> && writable_positions &&
                                     (!oriented || writable_normals) && (!surfels || writable_radii);

    static std::size_t size(const View& v) { return static_cast<std::size_t>(std::ranges::size(*v.range)); }
    static Vec3 point(const View& v, std::size_t i) {
        return detail::to_vec3(std::invoke(v.position, detail::element(v.range, i)));
    }
    static Vec3 normal(const View& v, std::size_t i)
        requires oriented
    {
        return detail::to_vec3(std::invoke(v.normal, detail::element(v.range, i)));
    }
    static void set_normal(const View& v, std::size_t i, const Vec3& n)
        requires writable_normals
    {
        detail::assign_vec3(std::invoke(v.normal, detail::element(v.range, i)), n);
    }
    static Scalar radius(const View& v, std::size_t i)
        requires surfels
    {
        return static_cast<Scalar>(std::invoke(v.radius, detail::element(v.range, i)));
    }
    static void clear(const View& v)
        requires growable
    {
        v.range->clear();
    }
    /// Appends a default-constructed element and writes p (and n when oriented) into it.
    static void push_back(const View& v, const Vec3& p, const Vec3& n)
        requires growable
    {
        v.range->emplace_back();
        auto&& e = detail::element(v.range, size(v) - 1);
        detail::assign_vec3(std::invoke(v.position, e), p);
        if constexpr (oriented) detail::assign_vec3(std::invoke(v.normal, e), n);
    }
    /// Appends a surfel: as above, and writes the radius r.
    static void push_back(const View& v, const Vec3& p, const Vec3& n, Scalar r)
        requires(growable && surfels)
    {
        push_back(v, p, n);
        auto& dst = std::invoke(v.radius, detail::element(v.range, size(v) - 1));
        dst = static_cast<std::remove_cvref_t<decltype(dst)>>(r);
    }
};

}  // namespace kintsugi
