// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file concepts.hpp
/// @brief The concepts every kintsugi algorithm is written against, and the
/// uniform accessors built on the traits (see traits.hpp).

#include <kintsugi/core/traits.hpp>
#include <kintsugi/core/types.hpp>

#include <algorithm>
#include <concepts>
#include <cstddef>
#include <optional>
#include <vector>

namespace kintsugi {

// ---------------------------------------------------------------- point sets

/// A finite sequence of 3D points, read through point_set_traits<T>.
template <class T>
concept PointSet = requires(const T& t, std::size_t i) {
    { point_set_traits<T>::size(t) } -> std::convertible_to<std::size_t>;
    { point_set_traits<T>::point(t, i) } -> std::convertible_to<Vec3>;
};

/// A PointSet whose points carry normals. Whether the normals are present at
/// run time is asked with has_normals() (e.g. a CGAL::Point_set_3 without a
/// normal map models the concept but has none).
template <class T>
concept OrientedPointSet = PointSet<T> && requires(const T& t, std::size_t i) {
    { point_set_traits<T>::normal(t, i) } -> std::convertible_to<Vec3>;
};

/// A PointSet into which normals can be written (normal estimation's output).
template <class T>
concept NormalWritablePointSet = PointSet<T> && requires(T& t, std::size_t i, const Vec3& n) {
    point_set_traits<T>::set_normal(t, i, n);
};

/// A point set that can be cleared and appended to (an output of point-based methods).
template <class T>
concept GrowablePointSet = PointSet<T> && requires(T& t, const Vec3& p) {
    point_set_traits<T>::clear(t);
    point_set_traits<T>::push_back(t, p, p);
};

/// Surfels: an OrientedPointSet whose points also carry a radius (oriented disks
/// of centre point(i), normal normal(i), radius radius(i)). Whether the radii are
/// present at run time is asked with has_radii().
template <class T>
concept SurfelSet = OrientedPointSet<T> && requires(const T& t, std::size_t i) {
    { point_set_traits<T>::radius(t, i) } -> std::convertible_to<Scalar>;
};

/// A GrowablePointSet that appends surfels, radius included (an up-sampler's output):
/// point_set_traits<T>::push_back(t, position, normal, radius).
template <class T>
concept GrowableSurfelSet = GrowablePointSet<T> && SurfelSet<T> &&
                            requires(T& t, const Vec3& p, Scalar r) { point_set_traits<T>::push_back(t, p, p, r); };

/// Number of points.
template <PointSet T>
[[nodiscard]] std::size_t num_points(const T& t) {
    return static_cast<std::size_t>(point_set_traits<T>::size(t));
}

/// Position of point i.
template <PointSet T>
[[nodiscard]] Vec3 point_at(const T& t, std::size_t i) {
    return point_set_traits<T>::point(t, i);
}

/// Normal of point i. @pre has_normals(t)
template <OrientedPointSet T>
[[nodiscard]] Vec3 normal_at(const T& t, std::size_t i) {
    return point_set_traits<T>::normal(t, i);
}

/// Whether t stores a normal for every point (false for any non-oriented type).
template <PointSet T>
[[nodiscard]] bool has_normals(const T& t) {
    if constexpr (!OrientedPointSet<T>) {
        return false;
    } else if constexpr (requires { point_set_traits<T>::has_normals(t); }) {
        return point_set_traits<T>::has_normals(t);
    } else {
        return true;
    }
}

/// Whether t stores a radius for every point (surfels). A type with a radius()
/// trait and no has_radii() trait always has them.
template <PointSet T>
[[nodiscard]] bool has_radii(const T& t) {
    if constexpr (requires { point_set_traits<T>::has_radii(t); }) {
        return point_set_traits<T>::has_radii(t);
    } else if constexpr (requires { point_set_traits<T>::radius(t, std::size_t{0}); }) {
        return true;
    } else {
        return false;
    }
}

/// Radius of surfel i. @pre has_radii(t)
template <SurfelSet T>
[[nodiscard]] Scalar radius_at(const T& t, std::size_t i) {
    return static_cast<Scalar>(point_set_traits<T>::radius(t, i));
}

/// Appends the surfel (p, n, r) to t.
template <GrowableSurfelSet T>
void append_surfel(T& t, const Vec3& p, const Vec3& n, Scalar r) {
    point_set_traits<T>::push_back(t, p, n, r);
}

namespace detail {
/// {at(0), ..., at(n - 1)}.
template <class V, class At>
[[nodiscard]] std::vector<V> gather_each(std::size_t n, At&& at) {
    std::vector<V> out(n);
    for (std::size_t i = 0; i < n; ++i) out[i] = at(i);
    return out;
}
}  // namespace detail

/// Copies the positions into a contiguous vector (the internal layout).
template <PointSet T>
[[nodiscard]] std::vector<Vec3> gather_points(const T& t) {
    return detail::gather_each<Vec3>(kintsugi::num_points(t), [&](std::size_t i) { return kintsugi::point_at(t, i); });
}

/// Copies the normals into a contiguous vector; empty when t has none.
template <PointSet T>
[[nodiscard]] std::vector<Vec3> gather_normals(const T& t) {
    if constexpr (OrientedPointSet<T>)
        if (kintsugi::has_normals(t))
            return detail::gather_each<Vec3>(kintsugi::num_points(t),
                                             [&](std::size_t i) { return kintsugi::normal_at(t, i); });
    return {};
}

/// Copies the radii into a contiguous vector; empty when t has none.
template <PointSet T>
[[nodiscard]] std::vector<Scalar> gather_radii(const T& t) {
    if constexpr (SurfelSet<T>)
        if (kintsugi::has_radii(t))
            return detail::gather_each<Scalar>(kintsugi::num_points(t),
                                               [&](std::size_t i) { return kintsugi::radius_at(t, i); });
    return {};
}

// ---------------------------------------------------------------- meshes

/// An indexed triangle mesh, read through mesh_traits<M>.
template <class M>
concept TriangleMesh = requires(const M& m, Index i) {
    { mesh_traits<M>::num_vertices(m) } -> std::convertible_to<std::size_t>;
    { mesh_traits<M>::num_faces(m) } -> std::convertible_to<std::size_t>;
    { mesh_traits<M>::position(m, i) } -> std::convertible_to<Vec3>;
    { mesh_traits<M>::face(m, i) } -> std::convertible_to<Face>;
};

/// A TriangleMesh whose vertex positions can be written (smoothing's output).
template <class M>
concept MutableTriangleMesh = TriangleMesh<M> && requires(M& m, Index i, const Vec3& p) {
    mesh_traits<M>::set_position(m, i, p);
};

/// A TriangleMesh that can be cleared and built (reconstruction's output).
template <class M>
concept TopologyMutableMesh = TriangleMesh<M> && requires(M& m, const Vec3& p, const Face& f) {
    mesh_traits<M>::clear(m);
    { mesh_traits<M>::add_vertex(m, p) } -> std::convertible_to<Index>;
    mesh_traits<M>::add_face(m, f);
};

template <TriangleMesh M>
[[nodiscard]] std::size_t num_vertices(const M& m) {
    return static_cast<std::size_t>(mesh_traits<M>::num_vertices(m));
}
template <TriangleMesh M>
[[nodiscard]] std::size_t num_faces(const M& m) {
    return static_cast<std::size_t>(mesh_traits<M>::num_faces(m));
}
/// Position of vertex v.
template <TriangleMesh M>
[[nodiscard]] Vec3 vertex_position(const M& m, Index v) {
    return mesh_traits<M>::position(m, v);
}
/// Vertex indices of face f.
template <TriangleMesh M>
[[nodiscard]] Face face_at(const M& m, Index f) {
    return mesh_traits<M>::face(m, f);
}
/// Writes the position of vertex v.
template <MutableTriangleMesh M>
void set_vertex_position(M& m, Index v, const Vec3& p) {
    mesh_traits<M>::set_position(m, v, p);
}

// ---------------------------------------------------------------- scalar fields

/// A scalar field f: R^3 -> R, called as f(x). Its gradient is optional.
///
/// **Sign convention, the same for every kintsugi field and algorithm:** f < 0 INSIDE
/// the solid, f > 0 OUTSIDE, the surface is the zero set, like a signed distance (whose
/// gradient points outward). A field approximating a distance gives it in the caller's
/// units. A point with f == 0 exactly counts as outside wherever a side must be chosen.
/// Outside its domain (e.g. the bounding cube of PUField) a field returns a quiet NaN;
/// algorithms treat NaN as "no value" and say what they do with it (extract_isosurface
/// counts it as outside). A field of the opposite sign is adapted by negating it, e.g.
/// `[&](const Vec3& x) { return -g(x); }`. f(x) must be thread-safe for const f.
template <class F>
concept ScalarField = requires(const F& f, const Vec3& x) {
    { f(x) } -> std::convertible_to<Scalar>;
};

/// A ScalarField that also gives its gradient: f.gradient(x) -> Vec3.
template <class F>
concept DifferentiableScalarField = ScalarField<F> && requires(const F& f, const Vec3& x) {
    { f.gradient(x) } -> std::convertible_to<Vec3>;
};

// ---------------------------------------------------------------- spatial indices

/// One neighbour found by a spatial query. The distance is squared.
struct Neighbor {
    Index index = 0;
    Scalar squared_distance = 0;
};

namespace detail {
/// The order every SpatialIndex returns: increasing distance, ties by index.
inline void sort_neighbors(std::vector<Neighbor>& out) {
    std::sort(out.begin(), out.end(), [](const Neighbor& a, const Neighbor& b) {
        return a.squared_distance < b.squared_distance ||
               (a.squared_distance == b.squared_distance && a.index < b.index);
    });
}
}  // namespace detail

/// A spatial index over a point set: k-nearest and radius queries returning
/// Neighbor{index, squared_distance}, sorted by increasing distance, ties by index (so
/// that every model gives the same answer): knn(q, k, out) the min(k, size()) nearest,
/// radius_search_squared(q, r², out) every point at squared distance <= r², nearest(q)
/// (invalid_input on an empty index or a NaN query). Models: KdTree, UniformGrid.
template <class S>
concept SpatialIndex = requires(const S& s, const Vec3& q, std::size_t k, Scalar r,
                                std::vector<Neighbor>& out) {
    { s.size() } -> std::convertible_to<std::size_t>;
    s.knn(q, k, out);
    s.radius_search_squared(q, r, out);
    { s.nearest(q) } -> std::convertible_to<Neighbor>;
};

}  // namespace kintsugi
