// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Shared by the octree RBF's two test files (test_rbf_field.cpp: the field;
// test_rbf_surface.cpp: the meshes), split so that neither translation unit compiles
// the other's instantiations (docs/build.md).
#pragma once
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/geometry.hpp>

#include <cstdint>
#include <random>
#include <vector>

namespace kintsugi::rbf_test {

namespace ks = kintsugi;
using V = std::vector<ks::Vec3>;

/// n points on the sphere |x - c| = R with outward normals.
inline void sphere_points(std::size_t n, std::uint64_t seed, V& p, V& nrm, const ks::Vec3& c = {0.2, -0.1, 0.3},
                   double R = 1.0) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> g;
    for (std::size_t i = 0; i < n; ++i) {
        const ks::Vec3 v = ks::Vec3(g(rng), g(rng), g(rng)).normalized();
        p.push_back(c + R * v);
        nrm.push_back(v);
    }
}

inline double diagonal(const V& pts) {
    ks::BoundingBox b;
    for (const auto& p : pts) b.extend(p);
    return b.diagonal();
}

}  // namespace kintsugi::rbf_test
