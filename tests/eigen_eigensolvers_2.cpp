// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Part of the dense Eigen solvers of kintsugi/core/eigen_instances.hpp, compiled once for
// every test program: the header's dense half in one file takes about 115 s of CPU under
// ASan + UBSan, so the test programs define it in three (eigen_eigensolvers_2.cpp,
// eigen_eigensolvers_3.cpp, eigen_qr.cpp), each one of the header's groups.
#define KINTSUGI_EIGEN_INSTANTIATE_DENSE_2X2
#include <kintsugi/core/eigen_instances.hpp>
