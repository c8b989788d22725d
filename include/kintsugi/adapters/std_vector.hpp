// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file std_vector.hpp
/// @brief std::vector of Eigen 3-vectors as a PointSet, and `with_normals` to
/// pair it with a vector of normals as an OrientedPointSet.
///
/// @code
/// std::vector<Eigen::Vector3d> pts = ..., nrm = ...;
/// auto oriented = kintsugi::with_normals(pts, nrm);   // non-owning view
/// @endcode

#include <kintsugi/core/concepts.hpp>

#include <Eigen/Core>

#include <type_traits>
#include <vector>

namespace kintsugi {

/// std::vector<Eigen::Matrix<S,3,1>> (float, double, ...) is a GrowablePointSet.
template <class S, int Opt, class Alloc>
struct point_set_traits<std::vector<Eigen::Matrix<S, 3, 1, Opt, 3, 1>, Alloc>> {
    using Container = std::vector<Eigen::Matrix<S, 3, 1, Opt, 3, 1>, Alloc>;
    static std::size_t size(const Container& c) { return c.size(); }
    static Vec3 point(const Container& c, std::size_t i) { return c[i].template cast<Scalar>(); }
    static void clear(Container& c) { c.clear(); }
    static void push_back(Container& c, const Vec3& p, const Vec3& /*normal*/) {
        c.push_back(p.template cast<S>());
    }
};

/// Non-owning view pairing a point container with a normal container of the same
/// length. `Points` and `Normals` may be const-qualified; with a non-const
/// `Normals` the view is NormalWritablePointSet.
template <class Points, class Normals>
struct PointsWithNormals {
    Points* points;
    Normals* normals;
};

/// Pairs `points` with `normals` (same length) as an OrientedPointSet view.
template <class Points, class Normals>
[[nodiscard]] PointsWithNormals<Points, Normals> with_normals(Points& points, Normals& normals) {
    return {&points, &normals};
}

template <class Points, class Normals>
struct point_set_traits<PointsWithNormals<Points, Normals>> {
    using View = PointsWithNormals<Points, Normals>;
    using NormalValue = typename std::remove_const_t<Normals>::value_type;
    static std::size_t size(const View& v) { return v.points->size(); }
    static Vec3 point(const View& v, std::size_t i) { return detail::to_vec3((*v.points)[i]); }
    static Vec3 normal(const View& v, std::size_t i) { return detail::to_vec3((*v.normals)[i]); }
    static bool has_normals(const View& v) { return v.normals->size() == v.points->size(); }
    static void prepare_normals(const View& v)
        requires(!std::is_const_v<Normals>)
    {
        v.normals->resize(v.points->size());
    }
    static void set_normal(const View& v, std::size_t i, const Vec3& n)
        requires(!std::is_const_v<Normals>)
    {
        (*v.normals)[i] = n.template cast<typename NormalValue::Scalar>();
    }
};

}  // namespace kintsugi
