// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Morton codes: bit layout, encode/decode round trip, quantisation in a box (clamped
// outside, flat axes), and morton_order against a plain sort over two containers.
#include <doctest/doctest.h>

#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/spatial/morton.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace ks = kintsugi;

static_assert(ks::morton_encode(1, 0, 0) == 1 && ks::morton_encode(0, 1, 0) == 2 && ks::morton_encode(0, 0, 1) == 4);
static_assert(ks::morton_encode(3, 0, 0) == 0b1001 && ks::morton_encode(0, 0, 2) == 0b100000);

TEST_CASE("morton_encode interleaves x, y, z bits and morton_decode inverts it") {
    CHECK(ks::morton_encode(0x1fffff, 0x1fffff, 0x1fffff) == (std::uint64_t{1} << 63) - 1);
    CHECK(ks::morton_encode(0x1fffff, 0, 0) == 0x1249249249249249ULL);
    CHECK(ks::morton_encode(0x200000, 0, 0) == 0);  // bit 21 and above are ignored
    std::mt19937 rng(1);
    std::uniform_int_distribution<std::uint32_t> u(0, (1u << 21) - 1);
    for (int i = 0; i < 10000; ++i) {
        const std::uint32_t x = u(rng), y = u(rng), z = u(rng);
        const auto d = ks::morton_decode(ks::morton_encode(x, y, z));
        REQUIRE(d[0] == x);
        REQUIRE(d[1] == y);
        REQUIRE(d[2] == z);
    }
}

TEST_CASE("MortonBox quantises to 2^21 - 1 steps per axis, clamps outside points, maps points on a flat axis to 0") {
    const ks::MortonBox box(ks::Vec3(0, 0, 5), ks::Vec3(1, 2, 5));  // z is flat
    CHECK(box.code(ks::Vec3(0, 0, 5)) == 0);
    CHECK(box.code(ks::Vec3(1, 2, 5)) == ks::morton_encode(0x1fffff, 0x1fffff, 0));
    CHECK(box.code(ks::Vec3(0.5, 1, 5)) == ks::morton_encode(0xfffff, 0xfffff, 0));  // (2^21 - 1) / 2 truncated
    CHECK(box.code(ks::Vec3(-3, 9, 7)) == ks::morton_encode(0, 0x1fffff, 0x1fffff));  // above the flat z: its top
    const std::vector<ks::Vec3> pts = {ks::Vec3(2, 2, 2), ks::Vec3(-1, 4, 2)};
    const ks::MortonBox around(pts);
    CHECK(around.min() == ks::Vec3(-1, 2, 2));
    CHECK(around.code(pts[1]) == ks::morton_encode(0, 0x1fffff, 0));
}

TEST_CASE("morton_order of a regular grid is the Z curve; equal codes keep index order") {
    std::vector<ks::Vec3> grid;
    for (int z = 1; z >= 0; --z)
        for (int y = 1; y >= 0; --y)
            for (int x = 1; x >= 0; --x) grid.emplace_back(x, y, z);  // index 7 - zyx
    const auto order = ks::morton_order(grid);
    REQUIRE(order.size() == 8);
    for (std::size_t k = 0; k < 8; ++k) CHECK(order[k] == 7 - k);
    const std::vector<ks::Vec3> same(5, ks::Vec3(1, 1, 1));
    CHECK(ks::morton_order(same) == std::vector<ks::Index>{0, 1, 2, 3, 4});
    CHECK(ks::morton_order(std::vector<ks::Vec3>{}).empty());
}

TEST_CASE("morton_order equals a sort by (code, index), over std::vector and an Eigen view, any thread count") {
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> u(-3, 3);
    std::vector<ks::Vec3> pts(200000);  // above the parallel sort's threshold
    for (auto& p : pts) p = ks::Vec3(u(rng), std::round(u(rng)), u(rng));  // y: many equal codes
    const ks::MortonBox box(pts);
    std::vector<ks::Index> want(pts.size());
    for (std::size_t i = 0; i < want.size(); ++i) want[i] = i;
    std::stable_sort(want.begin(), want.end(), [&](ks::Index a, ks::Index b) { return box.code(pts[a]) < box.code(pts[b]); });
    CHECK(ks::morton_order(pts) == want);
    Eigen::MatrixXd M(static_cast<Eigen::Index>(pts.size()), 3);
    for (std::size_t i = 0; i < pts.size(); ++i) M.row(static_cast<Eigen::Index>(i)) = pts[i].transpose();
    CHECK(ks::morton_order(ks::eigen_points(M)) == want);
    {
        ks::ThreadLimit one(1);
        CHECK(ks::morton_order(pts) == want);
    }
}
