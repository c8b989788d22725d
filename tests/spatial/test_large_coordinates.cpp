// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The octree at any magnitude: cells and point order of a copy scaled by 2^e equal the
// unscaled ones; a point set spanning more than the largest double is refused clearly.
#include <doctest/doctest.h>

#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/spatial/octree.hpp>

#include <cmath>
#include <vector>

namespace ks = kintsugi;

TEST_CASE("Octree: a copy scaled by 2^512, 2^665, 2^997, 2^-997 or 2^1020 has the same cells") {
    std::vector<ks::Vec3> base;
    for (int i = 0; i < 3000; ++i) {
        const double t = 0.37 * i, z = std::fmod(0.618 * i, 2.0) - 1.0, r = std::sqrt(1 - z * z);
        base.emplace_back(r * std::cos(t), r * std::sin(t), z);
    }
    const ks::Octree ref(base, ks::OctreeParams{.max_level = 6});
    for (const int e : {512, 665, 997, -997, 1020}) {
        CAPTURE(e);
        const double s = std::ldexp(1.0, e);
        std::vector<ks::Vec3> p = base;
        for (auto& x : p) x *= s;
        const ks::Octree t(p, ks::OctreeParams{.max_level = 6});
        REQUIRE(t.size() == ref.size());
        std::size_t same = 0;
        for (std::size_t c = 0; c < t.size(); ++c)
            same += t.cell(c).code == ref.cell(c).code && t.cell(c).level == ref.cell(c).level &&
                    t.cell_side(c) == ref.cell_side(c) * s;
        CHECK(same == t.size());
        CHECK(t.point_indices() == ref.point_indices());
        CHECK(t.locate(base[17] * s) == ref.locate(base[17]));
    }
    // Two points near both ends of double's range: their span overflows.
    const std::vector<ks::Vec3> wide = {ks::Vec3(-1.5e308, 0, 0), ks::Vec3(1.5e308, 0, 0)};
    CHECK_THROWS_WITH_AS((void)ks::Octree(wide, ks::OctreeParams{}), doctest::Contains("span more than the largest double"), ks::invalid_input);
    // Two points near the top of the range (2^1023 and 1.25 * 2^1023): the centre does not overflow.
    const double t = std::ldexp(1.0, 1023);
    const std::vector<ks::Vec3> top = {ks::Vec3(t, 0, 0), ks::Vec3(1.25 * t, t / 8, 0)};
    const ks::Octree tt(top, ks::OctreeParams{.max_level = 3});
    CHECK(tt.locate(top[0]) != ks::Octree::npos);
    CHECK(tt.locate(top[1]) != ks::Octree::npos);
}
