// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Octree: tiling, point lists, 2:1 balance, neighbours and location against brute
// force, containers, bad input, determinism.
#include <doctest/doctest.h>

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/projection.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/spatial/octree.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace ks = kintsugi;

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using PointSet3 = CGAL::Point_set_3<K::Point_3, K::Vector_3>;

struct UserPoint {
    double p[3];
    int tag;
};

// Points on a sphere of radius 1 (centre (0.1, -0.2, 0.3)) plus a tight cluster,
// so that the tree is deep in places and coarse elsewhere.
std::vector<Eigen::Vector3d> sample_points(std::size_t n, unsigned seed = 7) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> g(0.0, 1.0);
    std::vector<Eigen::Vector3d> pts;
    for (std::size_t i = 0; i < n; ++i) {
        Eigen::Vector3d v(g(rng), g(rng), g(rng));
        pts.push_back(Eigen::Vector3d(0.1, -0.2, 0.3) + v.normalized());
    }
    for (std::size_t i = 0; i < n / 10; ++i) pts.push_back(Eigen::Vector3d(0.5, 0.5, 0.5) + 1e-3 * Eigen::Vector3d(g(rng), g(rng), g(rng)));
    return pts;
}

struct Box {
    std::array<std::int64_t, 3> lo, hi;
};
Box int_box(const ks::Octree& t, ks::Index c) {
    const auto a = t.cell_anchor(c);
    const std::int64_t s = t.cell_extent(c);
    return {{a[0], a[1], a[2]}, {a[0] + s, a[1] + s, a[2] + s}};
}
// Independent contact computation: 2 face, 1 edge, 0 vertex, -1 none.
int brute_contact(const Box& a, const Box& b) {
    int dim = 0;
    for (int k = 0; k < 3; ++k) {
        const auto lo = std::max(a.lo[k], b.lo[k]);
        const auto hi = std::min(a.hi[k], b.hi[k]);
        if (hi < lo) return -1;
        if (hi > lo) ++dim;
    }
    return dim == 3 ? -1 : dim;
}

bool is_balanced(const ks::Octree& t) {
    for (ks::Index a = 0; a < t.size(); ++a)
        for (ks::Index b = a + 1; b < t.size(); ++b)
            if (brute_contact(int_box(t, a), int_box(t, b)) >= 0 &&
                std::abs(int(t.cell(a).level) - int(t.cell(b).level)) > 1)
                return false;
    return true;
}

void check_tiling_and_points(const ks::Octree& t, const std::vector<Eigen::Vector3d>& pts) {
    // Cells are Morton-sorted and contiguous: together they tile the cube exactly.
    const std::uint64_t total = std::uint64_t{1} << (3 * t.max_level());
    std::uint64_t expect = 0;
    for (ks::Index c = 0; c < t.size(); ++c) {
        REQUIRE(t.cell(c).code == expect);
        expect += std::uint64_t{1} << (3 * (t.max_level() - int(t.cell(c).level)));
    }
    CHECK(expect == total);
    // Every point is listed exactly once, in the cell whose box contains it.
    std::vector<int> seen(pts.size(), 0);
    for (ks::Index c = 0; c < t.size(); ++c) {
        const ks::Vec3 lo = t.cell_min(c), hi = t.cell_max(c);
        const double tol = 1e-12 * t.cube_side();
        for (ks::Index i : t.cell_points(c)) {
            ++seen[i];
            CHECK((pts[i].array() >= lo.array() - tol).all());
            CHECK((pts[i].array() <= hi.array() + tol).all());
        }
    }
    for (int s : seen) REQUIRE(s == 1);
    CHECK(t.num_points() == pts.size());
}

}  // namespace

TEST_CASE("Octree: every point lies in a max-level cell; cells tile the cube") {
    const auto pts = sample_points(3000);
    const ks::Octree t(pts, {.max_level = 6});
    CHECK(t.max_level() == 6);
    check_tiling_and_points(t, pts);
    std::size_t nonempty = 0;
    for (ks::Index c = 0; c < t.size(); ++c)
        if (!t.cell_points(c).empty()) {
            ++nonempty;
            CHECK(int(t.cell(c).level) == 6);
        }
    CHECK(nonempty > 100);
    // the cube is the bounding box's longest side, centred on the box
    ks::BoundingBox box;
    for (const auto& p : pts) box.extend(p);
    CHECK(t.cube_side() == doctest::Approx(box.extent().maxCoeff()));
    CHECK((t.cube_min() + ks::Vec3::Constant(t.cube_side() / 2) - box.center()).norm() < 1e-12);
    // levels are mixed: coarse cells exist away from the data
    const auto per_level = t.cells_per_level();
    CHECK(per_level[2] + per_level[3] > 0);
}

TEST_CASE("Octree: 2:1 balance holds, and fails without balancing") {
    // A single tight cluster in a big box makes deep cells next to coarse ones.
    std::vector<Eigen::Vector3d> pts = {{0, 0, 0}, {1, 1, 1}, {0.3, 0.31, 0.32}, {0.3001, 0.3102, 0.3203}};
    const ks::Octree balanced(pts, {.max_level = 7});
    const ks::Octree raw(pts, {.max_level = 7, .balance = false});
    CHECK(is_balanced(balanced));
    CHECK_FALSE(is_balanced(raw));
    CHECK(balanced.size() > raw.size());
    check_tiling_and_points(balanced, pts);
    check_tiling_and_points(raw, pts);

    const auto many = sample_points(1500, 3);
    const ks::Octree t2(many, {.max_level = 5});
    CHECK(is_balanced(t2));
}

TEST_CASE("Octree: neighbours by face, edge and vertex match brute force") {
    for (bool balance : {true, false}) {
        const auto pts = sample_points(800, 11);
        const ks::Octree t(pts, {.max_level = 5, .balance = balance});
        REQUIRE(t.size() < 9000);
        std::vector<ks::Index> got;
        std::size_t checked = 0;
        for (ks::Index c = 0; c < t.size(); c += 3) {
            std::array<std::vector<ks::Index>, 3> expect;
            std::vector<ks::Index> any;
            for (ks::Index j = 0; j < t.size(); ++j) {
                const int d = brute_contact(int_box(t, c), int_box(t, j));
                if (j == c || d < 0) continue;
                expect[std::size_t(d)].push_back(j);
                any.push_back(j);
            }
            t.neighbors(c, ks::Adjacency::face, got);
            REQUIRE(got == expect[2]);
            t.neighbors(c, ks::Adjacency::edge, got);
            REQUIRE(got == expect[1]);
            t.neighbors(c, ks::Adjacency::vertex, got);
            REQUIRE(got == expect[0]);
            REQUIRE(t.neighbors(c) == any);
            ++checked;
            if (balance) {
                for (ks::Index j : any) CHECK(std::abs(int(t.cell(j).level) - int(t.cell(c).level)) <= 1);
            }
        }
        CHECK(checked > 100);
    }
}

TEST_CASE("Octree: point location, centres, corners and box queries") {
    const auto pts = sample_points(1000, 5);
    const ks::Octree t(pts, {.max_level = 5});
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> u(-0.2, 1.2);
    for (int q = 0; q < 500; ++q) {
        const ks::Vec3 x = t.cube_min() + t.cube_side() * ks::Vec3(u(rng), u(rng), u(rng));
        ks::Index expect = ks::Octree::npos;
        for (ks::Index c = 0; c < t.size() && expect == ks::Octree::npos; ++c) {
            const ks::Vec3 lo = t.cell_min(c), hi = t.cell_max(c);
            // half-open cells, except on the upper faces of the cube
            bool in = true;
            for (int k = 0; k < 3; ++k) {
                const bool top = hi[k] >= t.cube_min()[k] + t.cube_side();
                in = in && x[k] >= lo[k] && (x[k] < hi[k] || (top && x[k] <= hi[k]));
            }
            if (in) expect = c;
        }
        CHECK(t.locate(x) == expect);
    }
    for (const auto& p : pts) {
        const ks::Index c = t.locate(p);
        REQUIRE(c != ks::Octree::npos);
        CHECK(int(t.cell(c).level) == 5);
        CHECK(t.cell_level(c) == 5);
    }
    CHECK(t.locate(ks::Vec3::Constant(std::numeric_limits<double>::quiet_NaN())) == ks::Octree::npos);
    // upper corner of the cube belongs to the last cell
    CHECK(t.locate(t.cube_min() + ks::Vec3::Constant(t.cube_side())) != ks::Octree::npos);

    for (ks::Index c = 0; c < t.size(); c += 7) {
        const auto corners = t.cell_corners(c);
        ks::Vec3 mean = ks::Vec3::Zero();
        for (const auto& k : corners) mean += k / 8;
        CHECK((mean - t.cell_center(c)).norm() < 1e-12);
        CHECK((corners[7] - corners[0]).norm() == doctest::Approx(t.cell_diagonal(c)));
        CHECK(t.cell_side(c) == doctest::Approx(t.cube_side() / double(1u << t.cell(c).level)));
    }

    const ks::Vec3 lo(0.0, -0.5, 0.2), hi(0.6, 0.3, 0.9);
    std::vector<ks::Index> got, expect;
    t.cells_in_box(lo, hi, got);
    for (ks::Index c = 0; c < t.size(); ++c)
        if ((t.cell_min(c).array() <= hi.array()).all() && (lo.array() <= t.cell_max(c).array()).all()) expect.push_back(c);
    CHECK(got == expect);
    CHECK(got.size() > 10);
}

TEST_CASE("Octree: max_points_per_cell subdivision rule") {
    const auto pts = sample_points(2000, 9);
    const std::size_t n = 20;
    const ks::Octree t(pts, {.max_level = 8, .max_points_per_cell = n, .balance = false});
    check_tiling_and_points(t, pts);
    std::size_t deep = 0;
    for (ks::Index c = 0; c < t.size(); ++c) {
        if (int(t.cell(c).level) < 8) CHECK(t.cell_points(c).size() <= n);
        if (int(t.cell(c).level) == 8) ++deep;
    }
    CHECK(deep > 0);  // the tight cluster reaches the max level
    CHECK(t.size() < ks::Octree(pts, {.max_level = 8, .balance = false}).size());
}

TEST_CASE("Octree: explicit cube, and a point outside it is rejected") {
    std::vector<Eigen::Vector3d> pts = {{0.1, 0.1, 0.1}, {0.9, 0.2, 0.3}};
    const ks::Octree t(pts, {.max_level = 3, .cube_side = 2.0, .cube_min = ks::Vec3(-1, -1, -1)});
    CHECK(t.cube_side() == 2.0);
    CHECK(t.cube_min() == ks::Vec3(-1, -1, -1));
    check_tiling_and_points(t, pts);
    CHECK_THROWS_WITH_AS(ks::Octree(pts, {.max_level = 3, .cube_side = 0.5, .cube_min = ks::Vec3(0, 0, 0)}),
                         doctest::Contains("outside the given cube"), ks::invalid_input);
}

TEST_CASE("Octree: bad input") {
    const std::vector<Eigen::Vector3d> empty;
    CHECK_THROWS_WITH_AS(ks::Octree{empty}, doctest::Contains("empty"), ks::invalid_input);
    std::vector<Eigen::Vector3d> pts = {{0, 0, 0}, {1, 1, 1}};
    CHECK_THROWS_WITH_AS(ks::Octree(pts, {.max_level = 0}), doctest::Contains("max_level = 0"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::Octree(pts, {.max_level = 13}), doctest::Contains("[1, 12]"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::Octree(pts, {.max_level = 4, .cube_side = -1}), doctest::Contains("cube_side"),
                         ks::invalid_input);
    pts.push_back({0, std::numeric_limits<double>::quiet_NaN(), 0});
    CHECK_THROWS_WITH_AS(ks::Octree{pts}, doctest::Contains("point 2"), ks::invalid_input);
    pts.back() = {std::numeric_limits<double>::infinity(), 0, 0};
    CHECK_THROWS_AS(ks::Octree{pts}, ks::invalid_input);
    // a single point (or coincident points) still gives a valid tree
    const std::vector<Eigen::Vector3d> one = {{2, 3, 4}};
    const ks::Octree t(one, {.max_level = 12});
    CHECK(t.cube_side() == 1.0);
    REQUIRE(t.locate(one[0]) != ks::Octree::npos);
    CHECK(int(t.cell(t.locate(one[0])).level) == 12);
    check_tiling_and_points(t, one);
}

TEST_CASE("Octree: identical with 1 and 2 threads") {
    const auto pts = sample_points(200000, 21);
    auto build = [&](int threads) {
        ks::ThreadLimit lim(threads);
        return ks::Octree(pts, {.max_level = 8});
    };
    const ks::Octree a = build(1), b = build(2);
    REQUIRE(a.size() == b.size());
    bool same = a.point_indices() == b.point_indices();
    for (ks::Index c = 0; c < a.size(); ++c)
        same = same && a.cell(c).code == b.cell(c).code && a.cell(c).level == b.cell(c).level &&
               a.cell(c).point_begin == b.cell(c).point_begin && a.cell(c).point_end == b.cell(c).point_end;
    CHECK(same);
}

using VecPts = std::vector<Eigen::Vector3d>;
using UserPts = std::vector<UserPoint>;
TEST_CASE_TEMPLATE("Octree: over any PointSet container", Container, VecPts, PointSet3, UserPts) {
    const auto base = sample_points(500, 13);
    Container c;
    for (const auto& p : base) {
        if constexpr (std::is_same_v<Container, VecPts>)
            c.push_back(p);
        else if constexpr (std::is_same_v<Container, PointSet3>)
            c.insert(K::Point_3(p.x(), p.y(), p.z()));
        else
            c.push_back(UserPoint{{p.x(), p.y(), p.z()}, 0});
    }
    auto build = [&]() {
        if constexpr (std::is_same_v<Container, UserPts>)
            return ks::Octree(ks::project_points(c, &UserPoint::p), {.max_level = 6});
        else
            return ks::Octree(c, {.max_level = 6});
    };
    const ks::Octree t = build();
    const ks::Octree ref(base, {.max_level = 6});
    REQUIRE(t.size() == ref.size());
    CHECK(t.point_indices() == ref.point_indices());
    check_tiling_and_points(t, base);
}

// The cells of a ball with their 8 corners inside, among a wanted subset, as the PU
// cover asks for them: visit_cells_in_ball, visit_cells_sparse (with a classify that
// says 2 for nodes inside the ball) and visit_cells with a skip must all give the
// brute-force answer.
TEST_CASE("Octree: sparse visits of the cells inside a ball match brute force") {
    const auto pts = sample_points(3000, 21);
    const ks::Octree t(pts, {.max_level = 7});
    std::mt19937 rng(5);
    std::vector<char> wanted(t.size());
    for (auto& w : wanted) w = (rng() % 3 != 0) ? 1 : 0;  // two thirds still wanted
    // next(first, last): the first wanted cell in [first, last), else last.
    auto next = [&](ks::Index f, ks::Index l) {
        while (f < l && !wanted[f]) ++f;
        return f;
    };
    auto skip = [&](ks::Index f, ks::Index l) { return next(f, l) >= l; };
    auto far2 = [](const ks::Vec3& c, const ks::Vec3& lo, const ks::Vec3& hi) {
        double d = 0;
        for (int k = 0; k < 3; ++k) {
            const double a = std::max(std::abs(c[k] - lo[k]), std::abs(c[k] - hi[k]));
            d += a * a;
        }
        return d;
    };
    std::uniform_real_distribution<double> u(0, 1);
    std::size_t total = 0;
    for (int q = 0; q < 60; ++q) {
        const ks::Vec3 c = t.cube_min() + t.cube_side() * ks::Vec3(u(rng), u(rng), u(rng));
        const double r = t.cube_side() * (q < 30 ? 0.02 + 0.1 * u(rng) : 0.3 * u(rng));
        std::vector<ks::Index> expect;
        for (ks::Index i = 0; i < t.size(); ++i)
            if (wanted[i] && far2(c, t.cell_min(i), t.cell_max(i)) < r * r) expect.push_back(i);
        for (int variant = 0; variant < 3; ++variant) {
            std::vector<ks::Index> got;
            auto classify = [&](const ks::Vec3& lo, const ks::Vec3& hi) {
                ks::Vec3 n = c.cwiseMax(lo).cwiseMin(hi);
                if (!((n - c).squaredNorm() < r * r)) return 0;
                return far2(c, lo, hi) < r * r ? 2 : 1;
            };
            // visit_cells*: the cells whose box classified non-zero; keep those inside
            auto visit = [&](ks::Index i) {
                if (wanted[i] && far2(c, t.cell_min(i), t.cell_max(i)) < r * r) got.push_back(i);
            };
            const ks::Vec3 lo = c - ks::Vec3::Constant(r), hi = c + ks::Vec3::Constant(r);
            if (variant == 0)
                t.visit_cells_sparse(lo, hi, classify, visit, next);
            else if (variant == 1)
                t.visit_cells(lo, hi, classify, visit, skip);
            else  // only cells inside the ball; those `next` does not offer are filtered here
                t.visit_cells_in_ball(c, r, [&](ks::Index i) {
                    if (wanted[i]) got.push_back(i);
                }, next);
            CHECK(got == expect);  // Morton order = index order, each once
        }
        total += expect.size();
    }
    CHECK(total > 100);
    // A ball of radius 0, negative or NaN holds no cell.
    for (const double r : {0.0, -1.0, std::nan("")}) {
        std::size_t seen = 0;
        t.visit_cells_in_ball(t.cell_center(0), r, [&](ks::Index) { ++seen; }, next);
        CHECK(seen == 0);
    }
}
