// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The sparse Eigen solvers of kintsugi/core/eigen_instances.hpp, compiled once for every
// test program (the precompiled header declares them extern; see CMakeLists.txt).
#define KINTSUGI_EIGEN_INSTANTIATE_SPARSE
#include <kintsugi/core/eigen_instances.hpp>
