// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The octree RBF fit (RBFOctreeField::build; its per-cell solve is in
// stage_rbf_solve.cpp), compiled in a file of its own (KINTSUGI_SEPARATE_STAGES,
// kintsugi/core/stages.hpp; docs/build.md): once for the tool, and once with the
// tests' flags for the test programs (tests/CMakeLists.txt).
#include <kintsugi/core/eigen_instances.hpp>
#include <kintsugi/rbf/rbf_octree.hpp>
#include <kintsugi/rbf/detail/rbf_octree_fit.ipp>
