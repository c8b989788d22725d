// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file eigen_instances.hpp
/// @brief Optional, for programs with many translation units: explicit instantiation
/// declarations of the Eigen solvers the library instantiates with its Scalar (double)
/// — the sparse LU and LDLT of the fairing (mesh/fair.hpp), the 2×2 and 3×3 symmetric
/// eigensolvers of the jet fit and the PCA frames, the jet fit's column-pivoting QR, the
/// 6×6 LDLT of the completion's quadric fits. A translation unit that includes this
/// header first does not compile those solvers; exactly one translation unit of the
/// program defines them:
///
/// @code
/// #define KINTSUGI_EIGEN_INSTANTIATE   // one .cpp file of the program
/// #include <kintsugi/core/eigen_instances.hpp>
/// @endcode
///
/// The code is Eigen's own, compiled once with the same flags: results are identical.
/// Measured on the `kintsugi` command-line tool (GCC 12, -O3): the `complete` command's
/// translation unit 113 s / 2.0 GB -> 91 s / 1.4 GB (docs/build.md).
/// KINTSUGI_EIGEN_INSTANTIATE_SPARSE / _DENSE define one half each (two smaller files);
/// the dense half splits further into _DENSE_2X2 (the 2×2 eigensolvers), _DENSE_3X3 (the
/// 3×3 one) and _DENSE_SOLVE (the QR and the 6×6 LDLT), for builds whose compile flags make
/// one file too long (the tests under the sanitizers: 115 s for the dense half).

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseLU>

#if defined(KINTSUGI_EIGEN_INSTANTIATE) || defined(KINTSUGI_EIGEN_INSTANTIATE_SPARSE)
#define KINTSUGI_EIGEN_EXTERN_SPARSE
#else
#define KINTSUGI_EIGEN_EXTERN_SPARSE extern
#endif
#if defined(KINTSUGI_EIGEN_INSTANTIATE) || defined(KINTSUGI_EIGEN_INSTANTIATE_DENSE) || \
    defined(KINTSUGI_EIGEN_INSTANTIATE_DENSE_2X2)
#define KINTSUGI_EIGEN_EXTERN_2X2
#else
#define KINTSUGI_EIGEN_EXTERN_2X2 extern
#endif
#if defined(KINTSUGI_EIGEN_INSTANTIATE) || defined(KINTSUGI_EIGEN_INSTANTIATE_DENSE) || \
    defined(KINTSUGI_EIGEN_INSTANTIATE_DENSE_3X3)
#define KINTSUGI_EIGEN_EXTERN_3X3
#else
#define KINTSUGI_EIGEN_EXTERN_3X3 extern
#endif
#if defined(KINTSUGI_EIGEN_INSTANTIATE) || defined(KINTSUGI_EIGEN_INSTANTIATE_DENSE) || \
    defined(KINTSUGI_EIGEN_INSTANTIATE_DENSE_SOLVE)
#define KINTSUGI_EIGEN_EXTERN_SOLVE
#else
#define KINTSUGI_EIGEN_EXTERN_SOLVE extern
#endif

// Sparse: FairSystem::solve's SparseLU (bilaplacian_fill) and SimplicialLDLT (biharmonic_fill).
KINTSUGI_EIGEN_EXTERN_SPARSE template class Eigen::SparseLU<Eigen::SparseMatrix<double>, Eigen::COLAMDOrdering<int>>;
KINTSUGI_EIGEN_EXTERN_SPARSE template class Eigen::internal::SparseLUImpl<double, int>;
KINTSUGI_EIGEN_EXTERN_SPARSE template class Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>;
KINTSUGI_EIGEN_EXTERN_SPARSE template class Eigen::SimplicialCholeskyBase<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>>;

// Dense: the jet fit (spatial/jet_fit.hpp), the PCA frames, the 6×6 quadric fits.
KINTSUGI_EIGEN_EXTERN_2X2 template class Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::Matrix2d>;
KINTSUGI_EIGEN_EXTERN_2X2 template class Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>;
KINTSUGI_EIGEN_EXTERN_2X2 template Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>&
Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>::compute<Eigen::Matrix2d>(const Eigen::EigenBase<Eigen::Matrix2d>&, int);
KINTSUGI_EIGEN_EXTERN_3X3 template class Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>;
KINTSUGI_EIGEN_EXTERN_3X3 template Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>&
Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>::compute<Eigen::Matrix3d>(const Eigen::EigenBase<Eigen::Matrix3d>&, int);
KINTSUGI_EIGEN_EXTERN_SOLVE template class Eigen::ColPivHouseholderQR<Eigen::MatrixXd>;
KINTSUGI_EIGEN_EXTERN_SOLVE template void Eigen::ColPivHouseholderQR<Eigen::MatrixXd>::_solve_impl<Eigen::VectorXd, Eigen::VectorXd>(
    const Eigen::VectorXd&, Eigen::VectorXd&) const;
KINTSUGI_EIGEN_EXTERN_SOLVE template Eigen::LDLT<Eigen::Matrix<double, 6, 6>>&
Eigen::LDLT<Eigen::Matrix<double, 6, 6>>::compute<Eigen::Matrix<double, 6, 6>>(
    const Eigen::EigenBase<Eigen::Matrix<double, 6, 6>>&);
KINTSUGI_EIGEN_EXTERN_SOLVE template void Eigen::LDLT<Eigen::Matrix<double, 6, 6>>::_solve_impl<
    Eigen::Matrix<double, 6, 1>, Eigen::Matrix<double, 6, 1>>(const Eigen::Matrix<double, 6, 1>&,
                                                              Eigen::Matrix<double, 6, 1>&) const;

#undef KINTSUGI_EIGEN_EXTERN_SPARSE
#undef KINTSUGI_EIGEN_EXTERN_2X2
#undef KINTSUGI_EIGEN_EXTERN_3X3
#undef KINTSUGI_EIGEN_EXTERN_SOLVE
