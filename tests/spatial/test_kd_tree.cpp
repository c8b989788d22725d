// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// KdTree against brute force: k-nearest (with ties and k > n), inclusive radius
// boundary, nearest, empty and moved-from trees, bad input, every point-set adapter.
#include <doctest/doctest.h>

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/adapters/projection.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/spatial/kd_tree.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <utility>
#include <vector>

namespace ks = kintsugi;

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using PointSet3 = CGAL::Point_set_3<K::Point_3, K::Vector_3>;

// Same arithmetic as nanoflann's L2_Simple_Adaptor, so distances compare bitwise.
double sq_dist(const ks::Vec3& a, const ks::Vec3& b) {
    double r = 0;
    for (int d = 0; d < 3; ++d) {
        const double diff = a[d] - b[d];
        r += diff * diff;
    }
    return r;
}

std::vector<ks::Neighbor> brute_sorted(const std::vector<ks::Vec3>& pts, const ks::Vec3& q) {
    std::vector<ks::Neighbor> all(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) all[i] = {i, sq_dist(q, pts[i])};
    std::sort(all.begin(), all.end(), [](const ks::Neighbor& a, const ks::Neighbor& b) {
        return a.squared_distance < b.squared_distance ||
               (a.squared_distance == b.squared_distance && a.index < b.index);
    });
    return all;
}

std::vector<ks::Neighbor> brute_knn(const std::vector<ks::Vec3>& pts, const ks::Vec3& q, std::size_t k) {
    auto all = brute_sorted(pts, q);
    all.resize(std::min(k, all.size()));
    return all;
}

std::vector<ks::Neighbor> brute_radius(const std::vector<ks::Vec3>& pts, const ks::Vec3& q, double r2) {
    auto all = brute_sorted(pts, q);
    std::vector<ks::Neighbor> out;
    for (const auto& n : all)
        if (n.squared_distance <= r2) out.push_back(n);
    return out;
}

void check_same(const std::vector<ks::Neighbor>& got, const std::vector<ks::Neighbor>& want) {
    REQUIRE(got.size() == want.size());
    for (std::size_t i = 0; i < got.size(); ++i) {
        CHECK(got[i].index == want[i].index);
        CHECK(got[i].squared_distance == want[i].squared_distance);
    }
}

std::vector<ks::Vec3> random_points(std::size_t n, unsigned seed) {
    std::mt19937 rng(seed);
    // Multiples of 1/1024 in [-1, 1]: exactly representable in float too.
    std::uniform_int_distribution<int> u(-1024, 1024);
    std::vector<ks::Vec3> p(n);
    for (auto& x : p) x = ks::Vec3(u(rng), u(rng), u(rng)) / 1024.0;
    return p;
}

// An integer grid: many exactly equidistant neighbours.
std::vector<ks::Vec3> grid_points(int m) {
    std::vector<ks::Vec3> p;
    for (int x = 0; x < m; ++x)
        for (int y = 0; y < m; ++y)
            for (int z = 0; z < m; ++z) p.emplace_back(x, y, z);
    // Shuffle so that index order differs from the tree's spatial order.
    std::mt19937 rng(7);
    std::shuffle(p.begin(), p.end(), rng);
    return p;
}

}  // namespace

static_assert(ks::SpatialIndex<ks::KdTree>);
static_assert(!std::is_copy_constructible_v<ks::KdTree> && std::is_nothrow_move_constructible_v<ks::KdTree>);

TEST_CASE("KdTree knn matches brute force on random points, k from 1 to beyond n") {
    const auto pts = random_points(3000, 1);
    const ks::KdTree tree(pts);
    REQUIRE(tree.size() == pts.size());
    const auto queries = random_points(150, 2);
    std::vector<ks::Neighbor> got;
    for (std::size_t k : {std::size_t{1}, std::size_t{2}, std::size_t{10}, std::size_t{64}, std::size_t{2999},
                          std::size_t{3000}, std::size_t{5000}}) {
        for (std::size_t qi = 0; qi < queries.size(); qi += (k > 100 ? 25 : 1)) {
            tree.knn(queries[qi], k, got);
            check_same(got, brute_knn(pts, queries[qi], k));
        }
    }
    // Query at a data point: itself first at distance zero.
    tree.knn(pts[42], 3, got);
    CHECK(got[0].squared_distance == 0.0);
    CHECK(pts[got[0].index] == pts[42]);
    // k = 0 gives nothing; the returning overload agrees with the out-parameter one.
    tree.knn(queries[0], 0, got);
    CHECK(got.empty());
    check_same(tree.knn(queries[1], 7), brute_knn(pts, queries[1], 7));
}

TEST_CASE("KdTree knn resolves equidistant ties by index, also beyond the k-th place") {
    const auto pts = grid_points(7);
    const ks::KdTree tree(pts);
    std::vector<ks::Neighbor> got;
    std::vector<ks::Vec3> queries;
    for (int i = 0; i < 60; ++i) queries.push_back(pts[static_cast<std::size_t>(i)]);  // at grid points: 6 at distance 1
    for (double c : {0.5, 1.5, 2.5, 3.5}) queries.emplace_back(c, c, c);                // cell centres: 8 corners tie
    queries.emplace_back(3, 3.5, 3.5);                                                 // face centres: 4 tie
    queries.emplace_back(-10, 3, 3);                                                    // outside the grid
    for (const auto& q : queries)
        for (std::size_t k = 1; k <= 40; ++k) {
            tree.knn(q, k, got);
            check_same(got, brute_knn(pts, q, k));
        }
}

TEST_CASE("KdTree knn_within: the k nearest cut at an inclusive radius, ties by index, any bound") {
    // brute force: the k nearest, then those at most r2 away
    auto want = [](const std::vector<ks::Vec3>& pts, const ks::Vec3& q, std::size_t k, double r2) {
        auto all = brute_knn(pts, q, k);
        while (!all.empty() && all.back().squared_distance > r2) all.pop_back();
        return all;
    };
    const auto pts = random_points(3000, 11);
    const ks::KdTree tree(pts);
    std::vector<ks::Neighbor> got;
    std::size_t cut = 0, whole = 0;
    auto queries = random_points(100, 12);
    for (std::size_t i = 0; i < 20; ++i) queries.push_back(queries[i] * 40.0);  // far from every point
    for (const auto& q : queries)
        for (const std::size_t k : {std::size_t{1}, std::size_t{7}, std::size_t{30}}) {
            const auto exact = brute_knn(pts, q, k);
            const double dk = exact.back().squared_distance;
            // Below, at (inclusive), and above the k-th distance; an upper bound from
            // other points (the k points nearest a shifted query), and none at all.
            const auto shifted = brute_knn(pts, q + ks::Vec3(0.01, -0.02, 0.015), k);
            double from_others = 0;
            for (const auto& n : shifted) from_others = std::max(from_others, sq_dist(q, pts[n.index]));
            for (const double r2 : {dk * 0.5, dk, dk * 1.5, from_others, std::numeric_limits<double>::max()}) {
                tree.knn_within(q, k, r2, got);
                const auto w = want(pts, q, k, r2);
                check_same(got, w);
                (w.size() < k ? cut : whole) += 1;
            }
        }
    CHECK(cut >= 100);    // the radius cut the list
    CHECK(whole >= 300);  // and it did not
    // Ties: grid cell centres (8 equidistant corners) and grid points, the bound exactly
    // at the tied distance keeps every tied point that the k allow, by index.
    const auto grid = grid_points(6);
    const ks::KdTree gtree(grid);
    for (const ks::Vec3 q : {ks::Vec3(1.5, 1.5, 1.5), ks::Vec3(2, 2, 2), ks::Vec3(2.5, 3, 3.5)})
        for (std::size_t k = 1; k <= 20; ++k)
            for (const double r2 : {0.75, 1.0, 2.0, 2.75}) {
                gtree.knn_within(q, k, r2, got);
                check_same(got, want(grid, q, k, r2));
            }
    // A negative radius finds nothing; NaN is refused; an empty tree finds nothing.
    tree.knn_within(queries[0], 5, -1.0, got);
    CHECK(got.empty());
    CHECK_THROWS_WITH_AS(tree.knn_within(queries[0], 5, std::nan(""), got), doctest::Contains("NaN"),
                         ks::invalid_input);
    CHECK_THROWS_WITH_AS(tree.knn_within(ks::Vec3(std::nan(""), 0, 0), 5, 1.0, got), doctest::Contains("NaN"),
                         ks::invalid_input);
    const ks::KdTree empty(std::vector<ks::Vec3>{});
    empty.knn_within(queries[0], 5, 1.0, got);
    CHECK(got.empty());
}

TEST_CASE("KdTree radius search is inclusive at the boundary and matches brute force") {
    const auto pts = grid_points(6);
    const ks::KdTree tree(pts);
    std::vector<ks::Neighbor> got;
    const ks::Vec3 centre(2, 2, 2);
    // Exact squared radii: 0 -> itself, 1 -> +6 face neighbours, 2 -> +12, 3 -> +8 corners.
    const std::array<std::size_t, 4> expected = {1, 7, 19, 27};
    for (int r2 = 0; r2 <= 3; ++r2) {
        tree.radius_search_squared(centre, r2, got);
        CHECK(got.size() == expected[static_cast<std::size_t>(r2)]);
        check_same(got, brute_radius(pts, centre, r2));
    }
    // Just below an exact boundary excludes it.
    tree.radius_search_squared(centre, std::nextafter(1.0, 0.0), got);
    CHECK(got.size() == 1);
    // Random points, radius = exact distance to some point: that point is found.
    const auto rp = random_points(2000, 3);
    const ks::KdTree rtree(rp);
    const auto queries = random_points(50, 4);
    for (std::size_t qi = 0; qi < queries.size(); ++qi) {
        const double r2 = sq_dist(queries[qi], rp[qi * 13]);
        rtree.radius_search_squared(queries[qi], r2, got);
        const auto want = brute_radius(rp, queries[qi], r2);
        check_same(got, want);
        CHECK(std::any_of(got.begin(), got.end(), [&](const ks::Neighbor& n) { return n.index == qi * 13; }));
    }
    // A negative radius finds nothing.
    tree.radius_search_squared(centre, -1.0, got);
    CHECK(got.empty());
    check_same(tree.radius_search_squared(centre, 1.0), brute_radius(pts, centre, 1.0));
}

TEST_CASE("KdTree nearest matches brute force, ties by lowest index") {
    const auto pts = grid_points(5);
    const ks::KdTree tree(pts);
    for (double c : {0.5, 1.5, 2.5}) {
        const ks::Vec3 q(c, c, c);
        const auto want = brute_knn(pts, q, 1)[0];
        const auto got = tree.nearest(q);
        CHECK(got.index == want.index);
        CHECK(got.squared_distance == want.squared_distance);
    }
    const auto rp = random_points(1000, 5);
    const ks::KdTree rtree(rp);
    for (const auto& q : random_points(100, 6)) CHECK(rtree.nearest(q).index == brute_knn(rp, q, 1)[0].index);
}

TEST_CASE("KdTree any_other_within_squared matches brute force (strict, one point excluded)") {
    const auto pts = grid_points(5);
    const ks::KdTree tree(pts);
    // Point 0 at the origin, its face neighbours at squared distance 1: strict, so not within 1.
    CHECK_FALSE(tree.any_other_within_squared(pts[0], 1.0, 0));
    CHECK(tree.any_other_within_squared(pts[0], std::nextafter(1.0, 2.0), 0));
    CHECK_FALSE(tree.any_other_within_squared(pts[0], 0.5, 0));
    CHECK(tree.any_other_within_squared(pts[0], 0.5, 1));  // point 0 itself counts when not excluded
    const auto rp = random_points(2000, 11);
    const ks::KdTree rtree(rp);
    const auto queries = random_points(200, 12);
    for (std::size_t qi = 0; qi < queries.size(); ++qi) {
        const std::size_t ex = qi * 7;
        const double r2 = sq_dist(queries[qi], rp[ex]);  // "is another point nearer than rp[ex]?"
        bool want = false;
        for (std::size_t j = 0; j < rp.size(); ++j)
            if (j != ex && sq_dist(queries[qi], rp[j]) < r2) want = true;
        CHECK(rtree.any_other_within_squared(queries[qi], r2, ex) == want);
        CHECK(rtree.any_other_within_squared(queries[qi], r2, ex) == (rtree.nearest(queries[qi]).index != ex));
    }
    CHECK_FALSE(ks::KdTree(std::vector<ks::Vec3>{}).any_other_within_squared(ks::Vec3(0, 0, 0), 1.0, 0));
}

TEST_CASE("empty KdTree: queries find nothing, nearest throws") {
    const ks::KdTree empty_built(std::vector<ks::Vec3>{});
    const ks::KdTree defaulted;
    for (const ks::KdTree* t : {&empty_built, &defaulted}) {
        CHECK(t->size() == 0);
        CHECK(t->points().empty());
        CHECK(t->knn(ks::Vec3(0, 0, 0), 5).empty());
        CHECK(t->radius_search_squared(ks::Vec3(0, 0, 0), 100.0).empty());
        CHECK_THROWS_WITH_AS((void)t->nearest(ks::Vec3(0, 0, 0)), doctest::Contains("empty"), ks::invalid_input);
    }
}

TEST_CASE("KdTree rejects NaN and infinite coordinates") {
    auto pts = random_points(20, 8);
    pts[3].y() = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH_AS(ks::KdTree{pts}, doctest::Contains("point 3"), ks::invalid_input);
    ks::PointCloud cloud;
    cloud.points = random_points(20, 9);
    cloud.points[11].z() = std::numeric_limits<double>::infinity();
    CHECK_THROWS_WITH_AS(ks::KdTree{cloud}, doctest::Contains("point 11"), ks::invalid_input);

    const ks::KdTree tree(random_points(20, 10));
    const ks::Vec3 bad(0, std::numeric_limits<double>::quiet_NaN(), 0);
    std::vector<ks::Neighbor> out;
    CHECK_THROWS_WITH_AS(tree.knn(bad, 3, out), doctest::Contains("NaN"), ks::invalid_input);
    CHECK_THROWS_AS(tree.radius_search_squared(bad, 1.0, out), ks::invalid_input);
    CHECK_THROWS_AS((void)tree.nearest(bad), ks::invalid_input);
    CHECK_THROWS_AS(tree.radius_search_squared(ks::Vec3::Zero(), std::nan(""), out), ks::invalid_input);
}

TEST_CASE("moving a KdTree keeps it working; the moved-from tree is empty") {
    const auto pts = random_points(500, 11);
    const auto queries = random_points(20, 12);
    ks::KdTree a(pts);
    ks::KdTree b(std::move(a));
    CHECK(a.size() == 0);  // NOLINT(bugprone-use-after-move): documented state
    CHECK(a.knn(queries[0], 4).empty());
    CHECK(b.size() == pts.size());
    ks::KdTree c;
    c = std::move(b);
    std::vector<ks::KdTree> trees;
    trees.push_back(std::move(c));
    for (int i = 0; i < 8; ++i) trees.emplace_back(random_points(10, 100 + i));  // reallocations move trees
    for (const auto& q : queries) check_same(trees[0].knn(q, 9), brute_knn(pts, q, 9));
    // The moved-from tree can be assigned a new tree and used again.
    a = ks::KdTree(pts);
    check_same(a.knn(queries[1], 5), brute_knn(pts, queries[1], 5));
}

TEST_CASE("KdTree queries are safe and identical from parallel loops") {
    const auto pts = random_points(4000, 13);
    const auto queries = random_points(2000, 14);
    const ks::KdTree tree(pts);
    std::vector<std::vector<ks::Neighbor>> par(queries.size());
    ks::parallel_for(0, queries.size(), [&](std::size_t i) { tree.knn(queries[i], 12, par[i]); }, 16);
    for (std::size_t i = 0; i < queries.size(); i += 7) check_same(par[i], brute_knn(pts, queries[i], 12));
}

namespace {
struct UserSample {
    float xyz[3];
    std::array<float, 3> n;
};

// Builds each adapter type over the same positions.
struct VecD {
    std::vector<Eigen::Vector3d> c;
    explicit VecD(const std::vector<ks::Vec3>& p) : c(p.begin(), p.end()) {}
    const auto& set() const { return c; }
};
struct VecF {
    std::vector<Eigen::Vector3f> c;
    explicit VecF(const std::vector<ks::Vec3>& p) {
        for (const auto& x : p) c.push_back(x.cast<float>());
    }
    const auto& set() const { return c; }
};
struct WithNormals {
    std::vector<Eigen::Vector3d> p, n;
    explicit WithNormals(const std::vector<ks::Vec3>& x) : p(x.begin(), x.end()), n(x.size(), Eigen::Vector3d::UnitZ()) {}
    auto set() const { return ks::with_normals(p, n); }
};
struct Cloud {
    ks::PointCloud c;
    explicit Cloud(const std::vector<ks::Vec3>& p) { c.points = p; }
    const auto& set() const { return c; }
};
struct CgalSet {
    PointSet3 c;
    explicit CgalSet(const std::vector<ks::Vec3>& p) {
        for (const auto& x : p) c.insert(K::Point_3(x.x(), x.y(), x.z()));
    }
    const auto& set() const { return c; }
};
struct EigenP {
    Eigen::MatrixXd P;
    explicit EigenP(const std::vector<ks::Vec3>& p) : P(static_cast<Eigen::Index>(p.size()), 3) {
        for (std::size_t i = 0; i < p.size(); ++i) P.row(static_cast<Eigen::Index>(i)) = p[i].transpose();
    }
    auto set() const { return ks::eigen_points(P); }
};
struct User {
    std::vector<UserSample> s;
    explicit User(const std::vector<ks::Vec3>& p) {
        for (const auto& x : p) s.push_back({{float(x.x()), float(x.y()), float(x.z())}, {0, 0, 1}});
    }
    auto set() const { return ks::project_points(s, &UserSample::xyz); }
};
}  // namespace

TEST_CASE_TEMPLATE("KdTree over every point-set adapter gives the brute-force answer", A, VecD, VecF, WithNormals,
                   Cloud, CgalSet, EigenP, User) {
    const auto pts = random_points(1500, 15);  // exactly representable in float
    const A holder(pts);
    const auto& set = holder.set();
    static_assert(ks::PointSet<std::remove_cvref_t<decltype(set)>>);
    const ks::KdTree tree(set);
    REQUIRE(tree.size() == pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) REQUIRE(tree.point(i) == pts[i]);
    for (const auto& q : random_points(40, 16)) {
        check_same(tree.knn(q, 10), brute_knn(pts, q, 10));
        check_same(tree.radius_search_squared(q, 0.05), brute_radius(pts, q, 0.05));
        CHECK(tree.nearest(q).index == brute_knn(pts, q, 1)[0].index);
    }
}

TEST_CASE("KdTree unsorted radius search: the same set as the sorted one, in a repeatable order") {
    const auto pts = random_points(4000, 11);
    const ks::KdTree tree(pts);
    const auto queries = random_points(80, 12);
    std::vector<ks::Neighbor> sorted, unsorted, again;
    std::size_t out_of_order = 0;
    for (std::size_t qi = 0; qi < queries.size(); ++qi) {
        // Exact boundary: the distance to some point (inclusive, as the sorted search).
        const double r2 = sq_dist(queries[qi], pts[qi * 31]);
        tree.radius_search_squared(queries[qi], r2, sorted);
        tree.radius_search_squared(queries[qi], r2, unsorted, false);
        CHECK(std::any_of(unsorted.begin(), unsorted.end(), [&](const ks::Neighbor& n) { return n.index == qi * 31; }));
        for (std::size_t i = 1; i < unsorted.size(); ++i)
            out_of_order += unsorted[i].squared_distance < unsorted[i - 1].squared_distance ? 1 : 0;
        // Same answer twice (the order depends only on the tree and the query).
        tree.radius_search_squared(queries[qi], r2, again, false);
        check_same(again, unsorted);
        auto resorted = unsorted;
        std::sort(resorted.begin(), resorted.end(), [](const ks::Neighbor& a, const ks::Neighbor& b) {
            return a.squared_distance < b.squared_distance ||
                   (a.squared_distance == b.squared_distance && a.index < b.index);
        });
        check_same(resorted, sorted);
        check_same(sorted, brute_radius(pts, queries[qi], r2));
    }
    // The unsorted order really is the tree's (otherwise the flag would be untested).
    CHECK(out_of_order > 0);
    // Negative radius and empty tree: nothing.
    tree.radius_search_squared(queries[0], -1.0, unsorted, false);
    CHECK(unsorted.empty());
    CHECK_THROWS_AS(tree.radius_search_squared(queries[0], std::nan(""), unsorted, false), ks::invalid_input);
}

TEST_CASE("KdTree leaf size changes the tree, never the answers") {
    const auto pts = grid_points(9);  // many exact ties
    const ks::KdTree ref(pts);
    CHECK(ref.leaf_size() == ks::KdTreeParams{}.leaf_size);
    std::vector<ks::Neighbor> a, b;
    for (std::size_t leaf : {std::size_t{1}, std::size_t{3}, std::size_t{8}, std::size_t{32}, std::size_t{1000}}) {
        const ks::KdTree t(pts, ks::KdTreeParams{.leaf_size = leaf});
        CHECK(t.leaf_size() == leaf);
        for (std::size_t qi = 0; qi < 40; ++qi) {
            const ks::Vec3 q = pts[qi * 17] + ks::Vec3(0.5, qi % 2 ? 0.5 : 0.0, 0.0);
            for (std::size_t k : {std::size_t{1}, std::size_t{6}, std::size_t{19}}) {
                t.knn(q, k, a);
                ref.knn(q, k, b);
                check_same(a, b);
                check_same(a, brute_knn(pts, q, k));
            }
            t.radius_search_squared(q, 2.25, a);
            check_same(a, brute_radius(pts, q, 2.25));
            CHECK(t.nearest(q).index == ref.nearest(q).index);
        }
    }
    // Through a point-set adapter too.
    const ks::KdTree viaadapter(ks::PointCloud{pts, {}, {}}, ks::KdTreeParams{.leaf_size = 4});
    CHECK(viaadapter.size() == pts.size());
    CHECK_THROWS_WITH_AS(ks::KdTree(pts, ks::KdTreeParams{.leaf_size = 0}), doctest::Contains("leaf_size"),
                         ks::invalid_input);
}

TEST_CASE("KdTree::adopt takes the positions over and answers as the copying constructor") {
    auto pts = random_points(800, 21);
    const ks::KdTree copied(pts);
    const ks::Vec3* data = pts.data();
    const auto adopted = ks::KdTree::adopt(std::move(pts));
    CHECK(adopted.points().data() == data);  // no copy
    const auto coarse = ks::KdTree::adopt(copied.points(), {.leaf_size = 40});
    CHECK(coarse.leaf_size() == 40);
    for (const auto& q : random_points(30, 22)) {
        check_same(adopted.knn(q, 7), copied.knn(q, 7));
        check_same(coarse.radius_search_squared(q, 0.04), copied.radius_search_squared(q, 0.04));
    }
    CHECK_THROWS_WITH_AS((void)ks::KdTree::adopt(copied.points(), {.leaf_size = 0}), doctest::Contains("leaf_size"),
                         ks::invalid_input);
    std::vector<ks::Vec3> bad = {ks::Vec3::Zero(), ks::Vec3(0, 0, std::numeric_limits<double>::quiet_NaN())};
    CHECK_THROWS_WITH_AS((void)ks::KdTree::adopt(bad), doctest::Contains("point 1"), ks::invalid_input);
}
