// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The PU + graph-cut reconstruction's regular triangulation (CGAL, step 4), compiled once
// for the tool in a file of its own (KINTSUGI_SEPARATE_STAGES, kintsugi/core/stages.hpp;
// docs/build.md).
#include <kintsugi/core/eigen_instances.hpp>
#include <kintsugi/reconstruct/pu_graphcut.hpp>
#include <kintsugi/reconstruct/detail/pu_triangulation.ipp>
