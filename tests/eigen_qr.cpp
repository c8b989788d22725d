// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Part of the dense Eigen solvers of kintsugi/core/eigen_instances.hpp (see eigen_eigensolvers_2.cpp).
#define KINTSUGI_EIGEN_INSTANTIATE_DENSE_SOLVE
#include <kintsugi/core/eigen_instances.hpp>
