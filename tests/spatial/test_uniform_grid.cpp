// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// UniformGrid against brute force: cube and ball queries of every size (one cell,
// many cells, the whole set), the single-precision gather, the keep filter, bad input,
// over std::vector, an Eigen matrix view and a user struct through a projection.
#include <doctest/doctest.h>

#include "spatial/random_cloud.hpp"

#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/adapters/projection.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/spatial/kd_tree.hpp>
#include <kintsugi/spatial/uniform_grid.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cmath>
#include <limits>
#include <random>
#include <utility>
#include <vector>

namespace ks = kintsugi;

namespace {

using Hits = std::vector<std::pair<ks::Index, double>>;

using ks::test::cloud;

// What a cube (ball = false) or ball query must find, by index.
Hits brute(const std::vector<ks::Vec3>& pts, const ks::Vec3& c, double h, bool ball) {
    Hits out;
    for (std::size_t i = 0; i < pts.size(); ++i) {
        const ks::Vec3 d = pts[i] - c;
        if (ball ? d.squaredNorm() <= h * h : d.cwiseAbs().maxCoeff() <= h) out.emplace_back(i, d.squaredNorm());
    }
    return out;
}

Hits by_index(Hits h) {
    std::sort(h.begin(), h.end());
    return h;
}

template <class Grid>
Hits cube(const Grid& g, const ks::Vec3& c, double h) {
    Hits out;
    g.for_each_in_cube(c, h, [&](ks::Index i, double d2) { out.emplace_back(i, d2); });
    return out;
}

template <class Grid>
Hits ball(const Grid& g, const ks::Vec3& c, double r) {
    Hits out;
    g.for_each_in_ball(c, r, [&](ks::Index i, double d2) { out.emplace_back(i, d2); });
    return out;
}

struct VecPts {
    std::vector<ks::Vec3> p;
    explicit VecPts(const std::vector<ks::Vec3>& x) : p(x) {}
    const auto& set() const { return p; }
};
struct EigenPts {
    Eigen::MatrixXd P;
    explicit EigenPts(const std::vector<ks::Vec3>& x) : P(static_cast<Eigen::Index>(x.size()), 3) {
        for (std::size_t i = 0; i < x.size(); ++i) P.row(static_cast<Eigen::Index>(i)) = x[i].transpose();
    }
    auto set() const { return ks::eigen_points(P); }
};
struct Sample {
    double xyz[3];
    int label;
};
struct UserPts {
    std::vector<Sample> s;
    explicit UserPts(const std::vector<ks::Vec3>& x) {
        for (const auto& q : x) s.push_back({{q.x(), q.y(), q.z()}, 0});
    }
    auto set() const { return ks::project_points(s, &Sample::xyz); }
};

}  // namespace

TEST_CASE_TEMPLATE("UniformGrid cube and ball queries equal brute force, from one cell to the whole set", C, VecPts,
                   EigenPts, UserPts) {
    const auto pts = cloud(3000, 1);
    const C holder(pts);
    const ks::UniformGrid grid(holder.set(), 0.1);
    CHECK(grid.size() == pts.size());
    CHECK(grid.cell_size() == 0.1);
    std::size_t found = 0;
    for (const auto& q : cloud(60, 2, 1.3))  // some queries outside the points' box
        for (double h : {0.0, 0.03, 0.1, 0.25, 0.7, 3.0}) {
            const Hits c = cube(grid, q, h), b = ball(grid, q, h);
            CHECK(by_index(c) == brute(pts, q, h, false));
            CHECK(by_index(b) == brute(pts, q, h, true));
            found += b.size();
        }
    CHECK(found > 10000);  // the queries are not all empty
}

TEST_CASE("UniformGrid visits a query's points by cell in (z, y, x) order, and by index within a cell") {
    const auto pts = cloud(2000, 3);
    const ks::UniformGrid a(pts, 0.2), b(pts, 0.2);
    ks::Vec3 lo = pts[0];
    for (const auto& p : pts) lo = lo.cwiseMin(p);
    const double inv = 1 / 0.2;
    auto rank = [&](ks::Index i) {
        const ks::Vec3 g = ((pts[i] - lo) * inv).array().floor();
        return std::array<double, 4>{g.z(), g.y(), g.x(), double(i)};
    };
    for (const auto& q : cloud(20, 4)) {
        const Hits x = cube(a, q, 0.2);
        CHECK(x == cube(b, q, 0.2));
        Hits want = brute(pts, q, 0.2, false);
        std::sort(want.begin(), want.end(), [&](const auto& u, const auto& v) { return rank(u.first) < rank(v.first); });
        CHECK(x == want);
    }
}

TEST_CASE("UniformGrid radius search equals KdTree's, sorted and unsorted") {
    const auto pts = cloud(2500, 5);
    const ks::UniformGrid grid(pts, 0.15);
    const ks::KdTree tree(pts);
    std::vector<ks::Neighbor> g, t;
    for (const auto& q : cloud(50, 6))
        for (double r : {0.05, 0.15, 0.4}) {
            grid.radius_search_squared(q, r * r, g);
            tree.radius_search_squared(q, r * r, t);
            REQUIRE(g.size() == t.size());
            for (std::size_t k = 0; k < g.size(); ++k) {
                CHECK(g[k].index == t[k].index);
                CHECK(g[k].squared_distance == doctest::Approx(t[k].squared_distance).epsilon(1e-14));
            }
            grid.radius_search_squared(q, r * r, g, false);
            CHECK(g.size() == t.size());
        }
    grid.radius_search_squared(ks::Vec3::Zero(), -1, g);
    CHECK(g.empty());
}

TEST_CASE("UniformGrid gather: the cube's points in for_each_in_cube's order, in single precision") {
    const auto pts = cloud(4000, 7);
    const ks::UniformGrid grid(pts, 0.12);
    std::vector<std::uint32_t> idx;
    std::vector<double> d2;
    std::size_t total = 0;
    for (const auto& q : cloud(80, 8))
        for (double h : {0.05, 0.12, 0.3}) {
            grid.gather(q, h, idx, d2);
            // Points farther than float round-off from the cube's faces decide alike.
            Hits exact;
            for (const auto& [i, d] : cube(grid, q, h))
                if (std::abs((pts[i] - q).cwiseAbs().maxCoeff() - h) > 1e-6) exact.emplace_back(i, d);
            Hits fast;
            for (std::size_t k = 0; k < idx.size(); ++k)
                if (std::abs((pts[idx[k]] - q).cwiseAbs().maxCoeff() - h) > 1e-6) {
                    fast.emplace_back(idx[k], d2[k]);
                    CHECK(std::abs(d2[k] - (pts[idx[k]] - q).squaredNorm()) < 1e-6);
                }
            REQUIRE(fast.size() == exact.size());
            for (std::size_t k = 0; k < fast.size(); ++k) CHECK(fast[k].first == exact[k].first);
            total += fast.size();
        }
    CHECK(total > 1000);
}

TEST_CASE("UniformGrid leaves out the points its keep filter rejects, keeping the others' indices") {
    const auto pts = cloud(1000, 9);
    const ks::UniformGrid grid(pts, 0.2, [](std::size_t i) { return i % 3 != 0; });
    CHECK(grid.size() == 1000 - 334);
    for (const auto& q : cloud(20, 10)) {
        Hits want;
        for (const auto& h : brute(pts, q, 0.3, true))
            if (h.first % 3 != 0) want.push_back(h);
        CHECK(by_index(ball(grid, q, 0.3)) == want);
    }
}

TEST_CASE("UniformGrid: an empty set finds nothing; a very wide extent enlarges the cells") {
    const ks::UniformGrid empty(std::vector<ks::Vec3>{}, 1.0);
    CHECK(empty.size() == 0);
    CHECK(cube(empty, ks::Vec3::Zero(), 5).empty());
    std::vector<ks::Vec3> far = {ks::Vec3(0, 0, 0), ks::Vec3(1e9, 0, 0), ks::Vec3(1e9, 1, 0)};
    const ks::UniformGrid wide(far, 1e-3);
    CHECK(wide.cell_size() > 1e-3);
    CHECK(by_index(ball(wide, ks::Vec3(1e9, 0.5, 0), 0.6)) == brute(far, ks::Vec3(1e9, 0.5, 0), 0.6, true));
}

TEST_CASE("UniformGrid rejects NaN and infinite points, a bad cell side and NaN queries") {
    auto pts = cloud(30, 11);
    pts[7].x() = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH_AS(ks::UniformGrid(pts, 0.1), doctest::Contains("point 7"), ks::invalid_input);
    pts[7].x() = std::numeric_limits<double>::infinity();
    CHECK_THROWS_WITH_AS(ks::UniformGrid(pts, 0.1), doctest::Contains("point 7"), ks::invalid_input);
    pts[7].x() = 0;
    CHECK_THROWS_WITH_AS(ks::UniformGrid(pts, 0.0), doctest::Contains("cell side"), ks::invalid_input);
    CHECK_THROWS_AS(ks::UniformGrid(pts, -1.0), ks::invalid_input);
    CHECK_THROWS_AS(ks::UniformGrid(pts, std::numeric_limits<double>::quiet_NaN()), ks::invalid_input);

    const ks::UniformGrid grid(pts, 0.1);
    const ks::Vec3 bad(0, std::numeric_limits<double>::quiet_NaN(), 0);
    std::vector<ks::Neighbor> out;
    std::vector<std::uint32_t> idx;
    std::vector<double> d2;
    auto noop = [](ks::Index, double) {};
    CHECK_THROWS_WITH_AS(grid.for_each_in_cube(bad, 0.1, noop), doctest::Contains("NaN"), ks::invalid_input);
    CHECK_THROWS_AS(grid.for_each_in_ball(bad, 0.1, noop), ks::invalid_input);
    CHECK_THROWS_AS(grid.for_each_in_ball(ks::Vec3::Zero(), std::nan(""), noop), ks::invalid_input);
    CHECK_THROWS_AS(grid.gather(bad, 0.1, idx, d2), ks::invalid_input);
    CHECK_THROWS_AS(grid.radius_search_squared(bad, 0.1, out), ks::invalid_input);
    CHECK_THROWS_AS(grid.radius_search_squared(ks::Vec3::Zero(), std::nan(""), out), ks::invalid_input);
}

namespace {
// Every query kind against brute force over `pts` (indices = positions).
void check_all_queries(const ks::UniformGrid& grid, const std::vector<ks::Vec3>& pts, unsigned seed) {
    REQUIRE(grid.size() == pts.size());
    std::vector<ks::Neighbor> nn;
    std::vector<std::uint32_t> idx;
    std::vector<double> d2;
    for (const auto& q : cloud(15, seed, 1.2))
        for (double h : {0.04, 0.1, 0.5}) {
            CHECK(by_index(cube(grid, q, h)) == brute(pts, q, h, false));
            CHECK(by_index(ball(grid, q, h)) == brute(pts, q, h, true));
            grid.radius_search_squared(q, h * h, nn);
            Hits got;
            for (const auto& n : nn) got.emplace_back(n.index, n.squared_distance);
            CHECK(by_index(got) == brute(pts, q, h, true));
            grid.gather(q, h, idx, d2);
            std::vector<std::uint32_t> want;
            for (const auto& [i, d] : brute(pts, q, h, false))
                if (std::abs((pts[i] - q).cwiseAbs().maxCoeff() - h) > 1e-6) want.push_back(static_cast<std::uint32_t>(i));
            std::vector<std::uint32_t> fast;
            for (std::uint32_t i : idx)
                if (std::abs((pts[i] - q).cwiseAbs().maxCoeff() - h) > 1e-6) fast.push_back(i);
            std::sort(fast.begin(), fast.end());
            CHECK(fast == want);
        }
}
}  // namespace

TEST_CASE("UniformGrid grows: appended points are found at once, before and after each merge") {
    const auto pts = cloud(5000, 20);
    ks::UniformGrid grid(0.1);
    CHECK(grid.size() == 0);
    std::vector<ks::Vec3> so_far;
    std::size_t checked = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
        CHECK(grid.append(pts[i]) == i);
        so_far.push_back(pts[i]);
        // Around the first merges (1024, 2048 points) and at the end.
        if (i + 1 == 7 || i + 1 == 1023 || i + 1 == 1024 || i + 1 == 1025 || i + 1 == 2049 || i + 1 == 5000) {
            check_all_queries(grid, so_far, static_cast<unsigned>(i));
            ++checked;
        }
    }
    CHECK(checked == 6);
    CHECK(grid.cell_size() == 0.1);
}

TEST_CASE("UniformGrid grows beyond its box and keeps the built points' indices and the keep filter") {
    auto pts = cloud(1500, 21);
    ks::UniformGrid grid(pts, 0.1, [](std::size_t i) { return i % 5 != 0; });
    std::vector<ks::Vec3> kept;
    std::vector<ks::Index> kept_index;
    for (std::size_t i = 0; i < pts.size(); ++i)
        if (i % 5 != 0) {
            kept.push_back(pts[i]);
            kept_index.push_back(i);
        }
    // Outside the first box, near and very far (beyond the appended points' key range).
    const std::vector<ks::Vec3> more = {ks::Vec3(3, 3, 3), ks::Vec3(-2.5, 0, 1), ks::Vec3(3.05, 3, 3), ks::Vec3(1e6, 0, 0),
                                        ks::Vec3(1e6, 0.05, 0)};
    for (const auto& p : more) {
        const ks::Index id = grid.append(p);
        CHECK(id == pts.size());
        pts.push_back(p);
        kept.push_back(p);
        kept_index.push_back(id);
    }
    CHECK(grid.size() == kept.size());
    for (const auto& q : {more[0], more[1], more[3], ks::Vec3(0.2, 0.1, 0.0)}) {
        Hits want;
        for (const auto& [k, d] : brute(kept, q, 0.3, true)) want.emplace_back(kept_index[k], d);
        CHECK(by_index(ball(grid, q, 0.3)) == by_index(want));
    }
    CHECK(by_index(ball(grid, ks::Vec3(1e6, 0, 0), 0.1)) == Hits{{1503, 0.0}, {1504, 0.05 * 0.05}});
}

namespace {

// Slots: a permutation of the points with their positions; a ball query by slot finds
// for_each_in_ball's points in its order; data kept in slot order is read back right.
void check_slots(const ks::UniformGrid& grid, const std::vector<ks::Vec3>& pts, const std::vector<ks::Index>& kept,
                 unsigned seed) {
    REQUIRE(grid.size() == kept.size());
    std::vector<ks::Index> seen;
    std::vector<double> label(grid.size());  // a caller's data per point, in slot order
    for (std::size_t s = 0; s < grid.size(); ++s) {
        const ks::Index i = grid.slot_index(s);
        seen.push_back(i);
        CHECK(grid.slot_point(s) == pts[i]);
        label[s] = 10.0 * static_cast<double>(i);
    }
    std::sort(seen.begin(), seen.end());
    CHECK(seen == kept);
    std::size_t found = 0;
    for (const auto& q : cloud(30, seed, 1.2))
        for (double r : {0.0, 0.05, 0.1, 0.3, 3.0}) {
            Hits by_slot;
            grid.for_each_slot_in_ball(q, r, [&](std::size_t s, double d2) {
                CHECK(label[s] == 10.0 * static_cast<double>(grid.slot_index(s)));
                by_slot.emplace_back(grid.slot_index(s), d2);
            });
            CHECK(by_slot == ball(grid, q, r));
            found += by_slot.size();
        }
    CHECK(found > 1000);
}

}  // namespace

TEST_CASE("UniformGrid slots: the points in storage order, a ball query by slot as for_each_in_ball") {
    const auto pts = cloud(3000, 30);
    std::vector<ks::Index> all(pts.size()), kept;
    for (std::size_t i = 0; i < pts.size(); ++i) {
        all[i] = i;
        if (i % 3 != 0) kept.push_back(i);
    }
    const ks::UniformGrid grid(pts, 0.1);
    check_slots(grid, pts, all, 31);
    // Built points are stored by cell in (z, y, x) order, by index within a cell.
    ks::Vec3 lo = pts[0];
    for (const auto& p : pts) lo = lo.cwiseMin(p);
    auto rank = [&](ks::Index i) {
        const ks::Vec3 g = ((pts[i] - lo) / 0.1).array().floor();
        return std::array<double, 4>{g.z(), g.y(), g.x(), double(i)};
    };
    bool sorted = true;
    for (std::size_t s = 1; s < grid.size(); ++s) sorted = sorted && rank(grid.slot_index(s - 1)) < rank(grid.slot_index(s));
    CHECK(sorted);
    check_slots(ks::UniformGrid(pts, 0.1, [](std::size_t i) { return i % 3 != 0; }), pts, kept, 32);
    // Appended points: before a merge they come after the built ones, in append order.
    ks::UniformGrid grown(std::vector<ks::Vec3>(pts.begin(), pts.begin() + 1500), 0.1);
    std::vector<ks::Index> so_far(all.begin(), all.begin() + 1500);
    for (std::size_t i = 1500; i < 1600; ++i) {
        grown.append(pts[i]);
        so_far.push_back(i);
    }
    CHECK(grown.slot_index(1500) == 1500);
    CHECK(grown.slot_index(1599) == 1599);
    check_slots(grown, pts, so_far, 33);
    for (std::size_t i = 1600; i < pts.size(); ++i) grown.append(pts[i]);  // merges at 3000
    check_slots(grown, pts, all, 34);
    CHECK_THROWS_AS(grid.for_each_slot_in_ball(ks::Vec3(std::nan(""), 0, 0), 0.1, [](std::size_t, double) {}),
                    ks::invalid_input);
}

TEST_CASE("UniformGrid append rejects NaN points and a grid without a cell side") {
    ks::UniformGrid grid(0.5);
    CHECK_THROWS_WITH_AS(grid.append(ks::Vec3(0, std::numeric_limits<double>::quiet_NaN(), 0)), doctest::Contains("NaN"),
                         ks::invalid_input);
    CHECK(grid.size() == 0);
    ks::UniformGrid none;
    CHECK_THROWS_WITH_AS(none.append(ks::Vec3::Zero()), doctest::Contains("cell side"), ks::invalid_input);
    CHECK_THROWS_AS(ks::UniformGrid(0.0), ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)grid.nearest(ks::Vec3::Zero()), doctest::Contains("empty"), ks::invalid_input);
    std::vector<ks::Neighbor> out;
    grid.knn(ks::Vec3::Zero(), 3, out);
    CHECK(out.empty());
}

namespace {
template <ks::SpatialIndex S>
std::vector<ks::Neighbor> knn_of(const S& index, const ks::Vec3& q, std::size_t k) {
    std::vector<ks::Neighbor> out;
    index.knn(q, k, out);
    return out;
}
struct KdMaker {
    static ks::KdTree make(const std::vector<ks::Vec3>& p) { return ks::KdTree(p); }
};
struct GridMaker {
    static ks::UniformGrid make(const std::vector<ks::Vec3>& p) { return ks::UniformGrid(p, 0.05); }
};
struct GrownGridMaker {  // half built, half appended
    static ks::UniformGrid make(const std::vector<ks::Vec3>& p) {
        ks::UniformGrid g(std::vector<ks::Vec3>(p.begin(), p.begin() + static_cast<std::ptrdiff_t>(p.size() / 2)), 0.05);
        for (std::size_t i = p.size() / 2; i < p.size(); ++i) g.append(p[i]);
        return g;
    }
};
}  // namespace

TEST_CASE_TEMPLATE("every SpatialIndex gives the brute-force k nearest, ties by index", M, KdMaker, GridMaker,
                   GrownGridMaker) {
    // Points on an integer lattice scaled by 1/16: many exactly equal distances.
    std::mt19937 rng(30);
    std::uniform_int_distribution<int> u(-16, 16);
    std::vector<ks::Vec3> pts(3000);
    for (auto& p : pts) p = ks::Vec3(u(rng), u(rng), u(rng)) / 16.0;
    const auto index = M::make(pts);
    static_assert(ks::SpatialIndex<std::remove_cvref_t<decltype(index)>>);
    for (const auto& q : cloud(40, 31, 1.5))
        for (std::size_t k : {1, 5, 30}) {
            std::vector<std::pair<double, ks::Index>> all;
            for (std::size_t i = 0; i < pts.size(); ++i) all.emplace_back((pts[i] - q).squaredNorm(), i);
            std::sort(all.begin(), all.end());
            const auto got = knn_of(index, q, k);
            REQUIRE(got.size() == k);
            for (std::size_t j = 0; j < k; ++j) {
                CHECK(got[j].index == all[j].second);
                CHECK(got[j].squared_distance == doctest::Approx(all[j].first).epsilon(1e-12));
            }
            CHECK(index.nearest(q).index == all[0].second);
        }
    CHECK(knn_of(index, ks::Vec3::Zero(), 5000).size() == pts.size());
}
