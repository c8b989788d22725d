// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The octree RBF's per-cell solve (the dense solvers: Householder QR, Cholesky, the
// complete orthogonal decomposition), compiled in a file of its own beside the fit
// (stage_rbf_fit.cpp; KINTSUGI_SEPARATE_STAGES, kintsugi/core/stages.hpp; docs/build.md).
#include <kintsugi/core/eigen_instances.hpp>
#include <kintsugi/rbf/detail/rbf_solve.hpp>
#include <kintsugi/rbf/detail/rbf_solve.ipp>
