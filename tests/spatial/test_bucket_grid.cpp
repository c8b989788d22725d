// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// BucketGrid against brute force: ball queries of every size (inside one cell, a few
// cells, wider than the filled cells), found at once after each insertion, in the
// documented order, with the values kept beside their points; points outside the
// grid's range; bad input.
#include <doctest/doctest.h>

#include "spatial/random_cloud.hpp"

#include <kintsugi/spatial/bucket_grid.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <tuple>
#include <utility>
#include <vector>

namespace ks = kintsugi;

namespace {

using ks::test::cloud;

struct Value {  // a caller's payload: kept beside its point
    ks::Index id;
    double tag;
};

// The points a ball query must find, in the documented order: cells by (z, y, x),
// insertion order (here: index) within a cell.
std::vector<ks::Index> expected(const ks::BucketGrid<Value>& g, const std::vector<ks::Vec3>& pts, std::size_t count,
                                const ks::Vec3& c, double r) {
    std::vector<std::tuple<std::int64_t, std::int64_t, std::int64_t, ks::Index>> hits;
    for (std::size_t i = 0; i < count; ++i)
        if ((pts[i] - c).squaredNorm() <= r * r) {
            const auto q = g.coord(pts[i]);
            hits.emplace_back(q[2], q[1], q[0], i);
        }
    std::sort(hits.begin(), hits.end());
    std::vector<ks::Index> out;
    for (const auto& h : hits) out.push_back(std::get<3>(h));
    return out;
}

std::vector<ks::Index> found(const ks::BucketGrid<Value>& g, const std::vector<ks::Vec3>& pts, const ks::Vec3& c,
                             double r) {
    std::vector<ks::Index> out;
    g.for_each_in_ball(c, r, [&](const ks::Vec3& p, const Value& v) {
        CHECK(p == pts[v.id]);  // the value travels with its point
        CHECK(v.tag == 0.5 * static_cast<double>(v.id));
        out.push_back(v.id);
    });
    return out;
}

}  // namespace

TEST_CASE("BucketGrid finds every inserted point at once, in (z, y, x) cell order, with its value") {
    const auto pts = cloud(4000, 7);
    for (const bool boxed : {false, true}) {
        CAPTURE(boxed);
        ks::BucketGrid<Value> grid = boxed ? ks::BucketGrid<Value>(ks::Vec3::Constant(-1), ks::Vec3::Constant(1), 0.1)
                                           : ks::BucketGrid<Value>(ks::Vec3::Constant(-1.5), 0.1);
        CHECK(grid.cell_size() == 0.1);
        const auto queries = cloud(25, 8, 1.2);
        std::size_t total = 0, checks = 0;
        for (std::size_t i = 0; i < pts.size(); ++i) {
            grid.insert(pts[i], Value{i, 0.5 * static_cast<double>(i)});
            if (i + 1 != 1 && i + 1 != 50 && i + 1 != 1000 && i + 1 != pts.size()) continue;
            CHECK(grid.size() == i + 1);
            for (const auto& q : queries)
                // Inside one cell, a few cells, many cells, wider than all filled cells.
                for (const double r : {0.0, 0.04, 0.1, 0.25, 0.7, 5.0, 1e300}) {
                    const auto want = expected(grid, pts, i + 1, q, r);
                    CHECK(found(grid, pts, q, r) == want);
                    CHECK(grid.any_in_ball(q, r) == !want.empty());
                    total += want.size();
                    ++checks;
                }
            // A point finds itself at radius 0.
            CHECK(grid.any_in_ball(pts[i], 0.0));
        }
        CHECK(checks == 4 * 25 * 7);
        CHECK(total > 100000);
        CHECK(grid.cell_count() > 1000);
        CHECK(grid.cell_count() <= 21 * 21 * 21);
    }
}

TEST_CASE("BucketGrid keeps points outside its range in border cells, still found") {
    // Range: 2^21 cells of side 1 from the origin; points below it and far above it.
    ks::BucketGrid<Value> grid(ks::Vec3::Zero(), 1.0);
    const std::vector<ks::Vec3> pts = {ks::Vec3(0.5, 0.5, 0.5), ks::Vec3(-3, 0.5, 0.5), ks::Vec3(-1e9, -1e9, 2),
                                       ks::Vec3(1e12, 0, 0), ks::Vec3(1e12, 0.25, 0), ks::Vec3(2.5e6, 1, 1)};
    for (std::size_t i = 0; i < pts.size(); ++i) grid.insert(pts[i], Value{i, 0.5 * static_cast<double>(i)});
    CHECK(grid.in_range(pts[0]));
    CHECK_FALSE(grid.in_range(pts[1]));
    CHECK_FALSE(grid.in_range(pts[3]));
    CHECK(grid.cells_in_cube(pts[0], 0.2) == 1.0);
    CHECK(grid.cells_in_cube(ks::Vec3(1.5, 1.5, 1.5), 0.6) == 27.0);
    CHECK(std::isinf(grid.cells_in_cube(pts[0], 1.0)));  // [-0.5, 1.5]: reaches below the range
    CHECK(std::isinf(grid.cells_in_cube(pts[3], 0.1)));
    for (const auto& q : pts)
        for (const double r : {0.0, 0.3, 4.0, 1e10})
            CHECK(found(grid, pts, q, r) == expected(grid, pts, pts.size(), q, r));
    CHECK(found(grid, pts, ks::Vec3(1e12, 0.1, 0), 0.2) == std::vector<ks::Index>{3, 4});
}

TEST_CASE("BucketGrid over a box of any magnitude") {
    // (Up to 1e150: beyond, squared distances overflow, for brute force as for the grid.)
    for (const double s : {1e-150, 1e-3, 1.0, 1e6, 1e150}) {
        CAPTURE(s);
        const ks::Vec3 lo = ks::Vec3::Constant(-s), hi = ks::Vec3::Constant(s);
        ks::BucketGrid<Value> grid(lo, hi, s * 1e-3);
        CHECK(std::isfinite(grid.cell_size()));
        CHECK(grid.cell_size() >= s * 1e-3);
        auto pts = cloud(300, 9);
        for (auto& p : pts) p *= s;
        for (std::size_t i = 0; i < pts.size(); ++i) grid.insert(pts[i], Value{i, 0.5 * static_cast<double>(i)});
        for (std::size_t i = 0; i < pts.size(); i += 37)
            CHECK(found(grid, pts, pts[i], 0.3 * s) == expected(grid, pts, pts.size(), pts[i], 0.3 * s));
    }
}

TEST_CASE("BucketGrid over the largest finite box") {
    const double big = std::numeric_limits<double>::max();
    ks::BucketGrid<int> grid(ks::Vec3::Constant(-big), ks::Vec3::Constant(big), 1.0);
    CHECK(std::isfinite(grid.cell_size()));
    CHECK(grid.origin().allFinite());
    const std::vector<ks::Vec3> pts = {ks::Vec3::Constant(-big), ks::Vec3::Zero(), ks::Vec3(big, 0, -big), ks::Vec3(1, 2, 3)};
    for (std::size_t i = 0; i < pts.size(); ++i) grid.insert(pts[i], static_cast<int>(i));
    for (std::size_t i = 0; i < pts.size(); ++i) {
        std::vector<int> hit;
        grid.for_each_in_ball(pts[i], 0.0, [&](const ks::Vec3&, int v) { hit.push_back(v); });
        CHECK(hit == std::vector<int>{static_cast<int>(i)});
    }
}

TEST_CASE("BucketGrid rejects bad input with a clear message and stays as it was") {
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
    CHECK_THROWS_WITH_AS(ks::BucketGrid<int>(ks::Vec3::Zero(), 0.0), doctest::Contains("cell side"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::BucketGrid<int>(ks::Vec3::Zero(), -1.0), doctest::Contains("cell side"), ks::invalid_input);
    CHECK_THROWS_AS(ks::BucketGrid<int>(ks::Vec3::Zero(), nan), ks::invalid_input);
    CHECK_THROWS_AS(ks::BucketGrid<int>(ks::Vec3::Zero(), inf), ks::invalid_input);
    CHECK_THROWS_AS(ks::BucketGrid<int>(ks::Vec3::Zero(), 1e-320), ks::invalid_input);  // 1 / side overflows
    CHECK_THROWS_WITH_AS(ks::BucketGrid<int>(ks::Vec3(nan, 0, 0), 1.0), doctest::Contains("origin"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::BucketGrid<int>(ks::Vec3::Ones(), ks::Vec3::Zero(), 1.0), doctest::Contains("box"),
                         ks::invalid_input);
    CHECK_THROWS_AS(ks::BucketGrid<int>(ks::Vec3::Zero(), ks::Vec3(inf, 0, 0), 1.0), ks::invalid_input);
    ks::BucketGrid<int> grid(ks::Vec3::Zero(), 1.0);
    grid.insert(ks::Vec3(0.5, 0.5, 0.5), 1);
    CHECK_THROWS_WITH_AS(grid.insert(ks::Vec3(0, nan, 0), 2), doctest::Contains("NaN"), ks::invalid_input);
    CHECK_THROWS_AS(grid.insert(ks::Vec3(inf, 0, 0), 2), ks::invalid_input);
    CHECK(grid.size() == 1);
    CHECK(grid.cell_count() == 1);
    // A NaN query finds nothing (and does not loop over the range).
    CHECK_FALSE(grid.any_in_ball(ks::Vec3(nan, 0, 0), 1.0));
    CHECK_FALSE(grid.any_in_ball(ks::Vec3(0.5, 0.5, 0.5), nan));
    CHECK(grid.any_in_ball(ks::Vec3(0.5, 0.5, 0.5), 0.0));
}
