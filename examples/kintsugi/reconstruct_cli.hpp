// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi reconstruct` spans three translation units so that each instantiates one
// method header: cmd_reconstruct.cpp (options, PU + graph cut), cmd_reconstruct_rbf.cpp
// (the octree RBF) and cmd_normals.cpp (normal estimation, shared with `normals`).
#pragma once

#include "common.hpp"

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace kcli::reconstruct {

/// The `--method rbf` options, defined with the library's defaults in cmd_reconstruct_rbf.cpp.
struct RbfOptions;

/// Adds --n-max, --overlap, --activity, --resolution and --no-blend to `cmd`; each is also
/// appended to `rbf_only` (refused with another method).
std::shared_ptr<RbfOptions> add_rbf_options(CLI::App& cmd, std::vector<CLI::Option*>& rbf_only);

/// The RBF's default smoothing λ (RBFOctreeParams::smoothing), for --smoothing's help text.
double rbf_default_smoothing();

/// What `--method rbf` needs besides its own options.
struct RbfRun {
    std::string input, output;
    bool inward = false;               ///< --inward-normals: flip the normals first
    std::optional<double> smoothing;   ///< --smoothing when given
    bool normals_estimated = false;    ///< for the JSON
};

/// The fit, its polygonisation, the output, the JSON and the summary line.
void run_rbf(const RbfOptions& options, const RbfRun& run, Context& ctx, kintsugi::PointCloud& cloud);

/// The surface's topology, then the mesh written to `output` (cmd_reconstruct.cpp).
kintsugi::TopologyReport write_surface(Context& ctx, const std::string& output, const kintsugi::IndexedMesh& m);

/// Estimates and orients the normals of `cloud` with the library's defaults when it has
/// none, with a notice, progress and timings; true when it did (cmd_normals.cpp).
bool estimate_missing_normals(Context& ctx, kintsugi::PointCloud& cloud, const std::string& input);

}  // namespace kcli::reconstruct
