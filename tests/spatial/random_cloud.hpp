// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Seeded uniform random points in a cube, for the spatial structures' tests.
#pragma once
#include <kintsugi/core/types.hpp>

#include <random>
#include <vector>

namespace kintsugi::test {

/// n points uniform in [-spread, spread]³ (std::mt19937 with `seed`).
inline std::vector<Vec3> cloud(std::size_t n, unsigned seed, double spread = 1) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-spread, spread);
    std::vector<Vec3> p(n);
    for (auto& x : p) x = Vec3(u(rng), u(rng), u(rng));
    return p;
}

}  // namespace kintsugi::test
