// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The tool's readers and writers, instantiated here once (common.hpp declares them).
#include "common.hpp"

#include <kintsugi/io/read.hpp>
#include <kintsugi/io/write.hpp>

namespace kcli {

kintsugi::IndexedMesh read_mesh(const std::string& path, kintsugi::ReadInfo* info) {
    return kintsugi::read_mesh(path, {}, info);
}

kintsugi::PointCloud read_point_cloud(const std::string& path, kintsugi::ReadInfo* info) {
    return kintsugi::read_point_cloud(path, info);
}

void write_mesh(const std::string& path, const kintsugi::IndexedMesh& mesh, const kintsugi::WriteOptions& options) {
    kintsugi::write_mesh(path, mesh, options);
}

void write_point_cloud(const std::string& path, const kintsugi::PointCloud& cloud,
                       const kintsugi::WriteOptions& options) {
    kintsugi::write_point_cloud(path, cloud, options);
}

void write_polylines(const std::string& path, const std::vector<kintsugi::Vec3>& points,
                     const std::vector<std::array<kintsugi::Index, 2>>& edges, const kintsugi::WriteOptions& options) {
    kintsugi::write_polylines(path, points, edges, options);
}

}  // namespace kcli
