// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The dense Eigen solvers of kintsugi/core/eigen_instances.hpp, compiled once for the tool
// (the sparse ones: eigen_sparse.cpp; one file for both would take about 60 s at -O3).
#define KINTSUGI_EIGEN_INSTANTIATE_DENSE
#include <kintsugi/core/eigen_instances.hpp>
