// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Part of the dense Eigen solvers of kintsugi/core/eigen_instances.hpp (see eigen_eigensolvers_2.cpp).
#include <kintsugi/core/eigen_instances.hpp>

template class Eigen::ColPivHouseholderQR<Eigen::MatrixXd>;
template void Eigen::ColPivHouseholderQR<Eigen::MatrixXd>::_solve_impl<Eigen::VectorXd, Eigen::VectorXd>(
    const Eigen::VectorXd&, Eigen::VectorXd&) const;
template Eigen::LDLT<Eigen::Matrix<double, 6, 6>>& Eigen::LDLT<Eigen::Matrix<double, 6, 6>>::compute<
    Eigen::Matrix<double, 6, 6>>(const Eigen::EigenBase<Eigen::Matrix<double, 6, 6>>&);
template void Eigen::LDLT<Eigen::Matrix<double, 6, 6>>::_solve_impl<Eigen::Matrix<double, 6, 1>, Eigen::Matrix<double, 6, 1>>(
    const Eigen::Matrix<double, 6, 1>&, Eigen::Matrix<double, 6, 1>&) const;
