// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// UniformGrid queries with max_candidates: one query tests at most that many points,
// an evenly strided subset of its cells' points when they hold more; below the limit
// the answer is the unlimited one, element for element.
#include <doctest/doctest.h>

#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/spatial/uniform_grid.hpp>

#include <cmath>
#include <set>
#include <vector>

namespace ks = kintsugi;

TEST_CASE("UniformGrid::gather and for_each_in_cube with max_candidates") {
    // 20,000 points crowded into one cell (a fan's centroids), and a sparse grid around.
    std::vector<ks::Vec3> pts;
    for (int i = 0; i < 20000; ++i) pts.emplace_back(0.5 + 1e-6 * std::sin(i), 0.5 + 1e-6 * std::cos(i), 0.5);
    for (int i = 0; i < 10; ++i)
        for (int j = 0; j < 10; ++j) pts.emplace_back(-2.0 + 0.4 * i, -2.0 + 0.4 * j, 0.5);
    const ks::UniformGrid grid(pts, 1.0);
    std::vector<std::uint32_t> all, some;
    std::vector<ks::Scalar> d_all, d_some;
    grid.gather(ks::Vec3(0.5, 0.5, 0.5), 1.0, all, d_all);
    grid.gather(ks::Vec3(0.5, 0.5, 0.5), 1.0, some, d_some, 512);
    CHECK(all.size() > 20000);
    CHECK(some.size() <= 512);
    CHECK(some.size() >= 500);  // nearly every tested point is inside this cube
    // A strided subset of the full answer, in its order, spread over all of it.
    std::size_t at = 0;
    for (std::uint32_t i : some) {
        while (at < all.size() && all[at] != i) ++at;
        REQUIRE(at < all.size());
    }
    CHECK(*std::max_element(some.begin(), some.end()) > 19000);
    std::size_t visited = 0;
    grid.for_each_in_cube(ks::Vec3(0.5, 0.5, 0.5), 1.0, [&](ks::Index, ks::Scalar) { ++visited; }, 300);
    CHECK(visited <= 300);
    CHECK(visited >= 290);
    // Below the limit: exactly the unlimited answer.
    std::vector<std::uint32_t> a, b;
    std::vector<ks::Scalar> da, db;
    grid.gather(ks::Vec3(-1.8, -1.8, 0.5), 0.5, a, da);
    grid.gather(ks::Vec3(-1.8, -1.8, 0.5), 0.5, b, db, 512);
    CHECK(a == b);
    CHECK(da == db);
}
