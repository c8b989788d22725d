// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file traits.hpp
/// @brief The traits class templates users specialise to plug in their containers.
///
/// kintsugi never asks a container to have particular member functions: it goes
/// through `point_set_traits<T>` and `mesh_traits<M>`, which users specialise for
/// their own types (argument-dependent lookup cannot reach std::vector). The
/// adapters in `kintsugi/adapters/` specialise them for std::vector, Eigen
/// matrices, the built-in PointCloud/IndexedMesh and CGAL's containers.
///
/// point_set_traits<T> — every member is static:
///   required (PointSet):        std::size_t size(const T&);
///                               Vec3 point(const T&, std::size_t i);
///   OrientedPointSet:           Vec3 normal(const T&, std::size_t i);
///                               optional bool has_normals(const T&)  (default: true)
///   NormalWritablePointSet:     void set_normal(T&, std::size_t i, const Vec3&);
///                               optional void prepare_normals(T&)  (allocate storage)
///   GrowablePointSet:           void clear(T&); void push_back(T&, const Vec3& p, const Vec3& n);
///   SurfelSet (surfels):        Scalar radius(const T&, std::size_t i);
///                               optional bool has_radii(const T&)  (default: true)
///   GrowableSurfelSet:          void push_back(T&, const Vec3& p, const Vec3& n, Scalar radius);
///
/// mesh_traits<M> — every member is static:
///   required (TriangleMesh):    std::size_t num_vertices(const M&); std::size_t num_faces(const M&);
///                               Vec3 position(const M&, Index v); Face face(const M&, Index f);
///   MutableTriangleMesh:        void set_position(M&, Index v, const Vec3&);
///   TopologyMutableMesh:        void clear(M&); Index add_vertex(M&, const Vec3&);
///                               void add_face(M&, const Face&);
///                               optional void reserve(M&, std::size_t nv, std::size_t nf)

#include <kintsugi/core/types.hpp>

#include <array>
#include <concepts>
#include <cstddef>
#include <functional>
#include <type_traits>

namespace kintsugi {

/// Point-set access for T. The primary template is empty: a type that has no
/// specialisation does not model PointSet. Specialise it for your type.
template <class T, class Enable = void>
struct point_set_traits {};

/// Triangle-mesh access for M. The primary template is empty: specialise it.
template <class M, class Enable = void>
struct mesh_traits {};

namespace detail {

/// Converts a coordinate to Scalar: arithmetic types by cast, number types of
/// exact kernels (CGAL) through their ADL-found to_double().
template <class T>
[[nodiscard]] Scalar to_scalar(const T& x) {
    if constexpr (std::is_convertible_v<T, Scalar>) {
        return static_cast<Scalar>(x);
    } else {
        return static_cast<Scalar>(to_double(x));
    }
}

/// Converts anything that looks like a 3-vector to Vec3: Eigen vectors of any
/// scalar, std::array<T,3>, C arrays T[3], types with x()/y()/z() (CGAL points)
/// or with .x/.y/.z members.
template <class V>
[[nodiscard]] Vec3 to_vec3(const V& v) {
    if constexpr (requires { v.template cast<Scalar>(); v.size(); }) {
        return Vec3(static_cast<Scalar>(v[0]), static_cast<Scalar>(v[1]), static_cast<Scalar>(v[2]));
    } else if constexpr (requires { v.x(); v.y(); v.z(); }) {
        return Vec3(to_scalar(v.x()), to_scalar(v.y()), to_scalar(v.z()));
    } else if constexpr (requires { v.x; v.y; v.z; }) {
        return Vec3(static_cast<Scalar>(v.x), static_cast<Scalar>(v.y), static_cast<Scalar>(v.z));
    } else {
        static_assert(requires { v[0]; v[1]; v[2]; },
                      "kintsugi::detail::to_vec3: the projection must return a 3-vector "
                      "(Eigen vector, std::array<T,3>, T[3], a type with x()/y()/z() or .x/.y/.z)");
        return Vec3(static_cast<Scalar>(v[0]), static_cast<Scalar>(v[1]), static_cast<Scalar>(v[2]));
    }
}

}  // namespace detail
}  // namespace kintsugi
