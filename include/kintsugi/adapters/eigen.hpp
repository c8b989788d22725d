// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file eigen.hpp
/// @brief libigl-style non-owning views of Eigen matrices: V (n×3 positions) and
/// F (m×3 vertex indices) as a TriangleMesh; P (n×3) and optional N (n×3) as a point set.
///
/// @code
/// Eigen::MatrixXd V; Eigen::MatrixXi F;          // as libigl reads them
/// auto mesh = kintsugi::eigen_mesh(V, F);         // MutableTriangleMesh (V is non-const)
/// auto cloud = kintsugi::eigen_points(P, N);      // OrientedPointSet
/// @endcode
/// The view keeps pointers: the matrices must outlive it. Rows are elements.

#include <kintsugi/core/concepts.hpp>

#include <Eigen/Core>

#include <type_traits>

namespace kintsugi {

namespace detail {
/// Row i of an n x 3 matrix as a Vec3 (any scalar type).
template <class Mat>
[[nodiscard]] Vec3 row_vec3(const Mat& A, std::size_t i) {
    const auto r = static_cast<Eigen::Index>(i);
    return Vec3(static_cast<Scalar>(A(r, 0)), static_cast<Scalar>(A(r, 1)), static_cast<Scalar>(A(r, 2)));
}
/// Writes p into row i of an n x 3 matrix (any scalar type).
template <class Mat>
void set_row(Mat& A, std::size_t i, const Vec3& p) {
    const auto r = static_cast<Eigen::Index>(i);
    for (int c = 0; c < 3; ++c) A(r, c) = static_cast<typename Mat::Scalar>(p[c]);
}
}  // namespace detail

/// Non-owning V/F view. `MatV` may be const (read-only view).
template <class MatV, class MatF>
struct EigenMeshView {
    MatV* V;
    const MatF* F;
};

/// Views V (n×3) and F (m×3) as a triangle mesh. Writable positions when V is non-const.
template <class DV, class DF>
[[nodiscard]] EigenMeshView<DV, DF> eigen_mesh(Eigen::MatrixBase<DV>& V, const Eigen::MatrixBase<DF>& F) {
    return {&V.derived(), &F.derived()};
}
/// Read-only overload for a const V.
template <class DV, class DF>
[[nodiscard]] EigenMeshView<const DV, DF> eigen_mesh(const Eigen::MatrixBase<DV>& V,
                                                     const Eigen::MatrixBase<DF>& F) {
    return {&V.derived(), &F.derived()};
}

template <class MatV, class MatF>
struct mesh_traits<EigenMeshView<MatV, MatF>> {
    using View = EigenMeshView<MatV, MatF>;
    static std::size_t num_vertices(const View& m) { return static_cast<std::size_t>(m.V->rows()); }
    static std::size_t num_faces(const View& m) { return static_cast<std::size_t>(m.F->rows()); }
    static Vec3 position(const View& m, Index v) { return detail::row_vec3(*m.V, v); }
    static Face face(const View& m, Index f) {
        const auto r = static_cast<Eigen::Index>(f);
        return {static_cast<Index>((*m.F)(r, 0)), static_cast<Index>((*m.F)(r, 1)), static_cast<Index>((*m.F)(r, 2))};
    }
    static void set_position(const View& m, Index v, const Vec3& p)
        requires(!std::is_const_v<MatV>)
    {
        detail::set_row(*m.V, v, p);
    }
};

/// Non-owning view of an n×3 point matrix, with an optional n×3 normal matrix.
template <class MatP, class MatN = const Eigen::MatrixXd>
struct EigenPointsView {
    const MatP* P;
    MatN* N = nullptr;
};

/// Views P (n×3) as a point set without normals.
template <class DP>
[[nodiscard]] EigenPointsView<DP> eigen_points(const Eigen::MatrixBase<DP>& P) {
    return {&P.derived(), nullptr};
}
/// Views P (n×3) with normals N (n×3); N writable when non-const.
template <class DP, class DN>
[[nodiscard]] EigenPointsView<DP, DN> eigen_points(const Eigen::MatrixBase<DP>& P, Eigen::MatrixBase<DN>& N) {
    return {&P.derived(), &N.derived()};
}
template <class DP, class DN>
[[nodiscard]] EigenPointsView<DP, const DN> eigen_points(const Eigen::MatrixBase<DP>& P,
                                                         const Eigen::MatrixBase<DN>& N) {
    return {&P.derived(), &N.derived()};
}

template <class MatP, class MatN>
struct point_set_traits<EigenPointsView<MatP, MatN>> {
    using View = EigenPointsView<MatP, MatN>;
    static std::size_t size(const View& v) { return static_cast<std::size_t>(v.P->rows()); }
    static Vec3 point(const View& v, std::size_t i) { return detail::row_vec3(*v.P, i); }
    static Vec3 normal(const View& v, std::size_t i) { return detail::row_vec3(*v.N, i); }
    static bool has_normals(const View& v) {
        return v.N != nullptr && v.N->rows() == v.P->rows() && v.N->cols() == 3 && v.P->rows() > 0;
    }
    static void prepare_normals(const View& v)
        requires(!std::is_const_v<MatN>)
    {
        v.N->resize(v.P->rows(), 3);
    }
    static void set_normal(const View& v, std::size_t i, const Vec3& n)
        requires(!std::is_const_v<MatN>)
    {
        detail::set_row(*v.N, i, n);
    }
};

}  // namespace kintsugi
