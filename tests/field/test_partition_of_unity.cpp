// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// PartitionOfUnity (the b2 blend over a ball grid) against brute force; find_edge_root.
#include <doctest/doctest.h>

#include <kintsugi/field/edge_root.hpp>
#include <kintsugi/field/partition_of_unity.hpp>

#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <vector>

namespace ks = kintsugi;

namespace {

struct Setup {
    std::vector<ks::PUBall> balls;
    std::vector<ks::Vec3> normal, origin;
};

Setup random_balls(std::size_t n, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1), r(0.05, 0.4);
    std::normal_distribution<double> g;
    Setup s;
    for (std::size_t i = 0; i < n; ++i) {
        s.balls.push_back({ks::Vec3(u(rng), u(rng), u(rng)) * 2 - ks::Vec3::Constant(0.5), r(rng)});
        s.normal.push_back(ks::Vec3(g(rng), g(rng), g(rng)).normalized());
        s.origin.push_back(ks::Vec3(u(rng), u(rng), u(rng)));
    }
    return s;
}

}  // namespace

TEST_CASE("b2_weight: values, continuity and derivative") {
    CHECK(ks::b2_weight(0) == 0.75);
    CHECK(ks::b2_weight(0.5) == 0.5);
    CHECK(ks::b2_weight(1.0) == 0.125);
    CHECK(ks::b2_weight(1.5) == 0);
    CHECK(ks::b2_weight(7) == 0);
    CHECK(ks::b2_weight(0.5 - 1e-12) == doctest::Approx(0.5));
    for (double t = 0.01; t < 1.6; t += 0.0731) {
        const double h = 1e-6;
        const double fd = (ks::b2_weight(t + h) - ks::b2_weight(t - h)) / (2 * h);
        CHECK(ks::b2_weight_derivative(t) == doctest::Approx(fd).epsilon(1e-5));
    }
}

TEST_CASE("PartitionOfUnity: the blend equals brute force over all balls; value and gradient") {
    const Setup s = random_balls(400, 1);
    const ks::PartitionOfUnity pu(s.balls, ks::Vec3::Constant(-0.5), 2.0);
    CHECK(pu.size() == 400);
    CHECK(pu.grid_resolution() >= 4);
    auto local = [&](std::size_t i, const ks::Vec3& x, ks::Vec3* g) {
        if (g) *g = s.normal[i];
        return s.normal[i].dot(x - s.origin[i]);
    };
    std::vector<double> factors(400, 1.0);
    for (std::size_t i = 0; i < 400; i += 3) factors[i] = 0.25;
    factors[7] = 0;
    std::mt19937_64 rng(2);
    std::uniform_real_distribution<double> u(-0.5, 1.5);
    int covered = 0;
    for (int q = 0; q < 2000; ++q) {
        const ks::Vec3 x(u(rng), u(rng), u(rng));
        double W = 0, F = 0;
        std::set<std::size_t> brute;
        for (std::size_t i = 0; i < 400; ++i) {
            const double d = (x - s.balls[i].center).norm();
            if (d >= s.balls[i].radius) continue;
            brute.insert(i);
            const double w = factors[i] * ks::b2_weight(1.5 * d / s.balls[i].radius);
            W += w;
            F += w * local(i, x, nullptr);
        }
        std::set<std::size_t> visited;
        pu.for_each_ball(x, [&](std::size_t i) { visited.insert(i); });
        CHECK(visited == brute);
        ks::Vec3 g;
        const double v = pu.blend(x, local, factors.data(), &g);
        if (!(W > 0)) {
            CHECK(std::isnan(v));
            CHECK(std::isnan(g[0]));
            continue;
        }
        ++covered;
        CHECK(v == doctest::Approx(F / W).epsilon(1e-12));
        CHECK(pu.blend(x, local, factors.data()) == v);
        const double h = 1e-7;
        for (int k = 0; k < 3; ++k) {
            ks::Vec3 e = ks::Vec3::Zero();
            e[k] = h;
            const double a = pu.blend(x + e, local, factors.data()), b = pu.blend(x - e, local, factors.data());
            if (std::isnan(a) || std::isnan(b)) continue;
            CHECK(g[k] == doctest::Approx((a - b) / (2 * h)).epsilon(1e-4).scale(1));
        }
    }
    CHECK(covered > 500);
    // Outside the cube: NaN even where a ball reaches.
    CHECK(std::isnan(pu.blend(ks::Vec3(-0.6, 0.5, 0.5), local)));
    CHECK(std::isnan(pu.blend(ks::Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0), local)));
    // weight() is the single-ball weight.
    CHECK(pu.weight(3, s.balls[3].center) == 0.75);
    CHECK(pu.weight(3, s.balls[3].center + ks::Vec3(s.balls[3].radius, 0, 0)) == 0);
}

TEST_CASE("PartitionOfUnity: a partition of unity — constants and a shared plane are reproduced exactly") {
    const Setup s = random_balls(200, 3);
    const ks::PartitionOfUnity pu(s.balls, ks::Vec3::Constant(-0.5), 2.0);
    const ks::Vec3 n = ks::Vec3(1, 2, -2).normalized();
    std::mt19937_64 rng(4);
    std::uniform_real_distribution<double> u(-0.5, 1.5);
    for (int q = 0; q < 500; ++q) {
        const ks::Vec3 x(u(rng), u(rng), u(rng));
        const double c = pu.blend(x, [](std::size_t, const ks::Vec3&, ks::Vec3* g) {
            if (g) *g = ks::Vec3::Zero();
            return 2.5;
        });
        if (std::isnan(c)) continue;
        CHECK(c == doctest::Approx(2.5).epsilon(1e-14));
        ks::Vec3 g;
        const double p = pu.blend(x, [&](std::size_t, const ks::Vec3& y, ks::Vec3* gl) {
            if (gl) *gl = n;
            return n.dot(y) - 0.1;
        }, nullptr, &g);
        CHECK(p == doctest::Approx(n.dot(x) - 0.1).epsilon(1e-12));
        CHECK((g - n).norm() < 1e-9);
    }
}

TEST_CASE("ball_weight and box_weight: values, support, C¹ gradients; PartitionOfUnity blends with ball_weight") {
    const ks::Vec3 c(0.3, -0.2, 0.5);
    // Ball: b2(1.5 d / r), r = 0.4.
    CHECK(ks::ball_weight(c, c, 0.4) == 0.75);
    CHECK(ks::ball_weight(c + ks::Vec3(0.4 / 3, 0, 0), c, 0.4) == doctest::Approx(0.5).epsilon(1e-15));
    CHECK(ks::ball_weight(c + ks::Vec3(0, 0.4, 0), c, 0.4) == 0);
    CHECK(ks::ball_weight(c + ks::Vec3(0, 0.5, 0), c, 0.4) == 0);
    // Box: Π (1 - t²)², half side 0.4.
    CHECK(ks::box_weight(c, c, 0.4) == 1);
    CHECK(ks::box_weight(c + ks::Vec3(0.2, 0, 0), c, 0.4) == doctest::Approx(0.5625).epsilon(1e-15));
    CHECK(ks::box_weight(c + ks::Vec3(0.2, -0.2, 0.2), c, 0.4) == doctest::Approx(0.5625 * 0.5625 * 0.5625).epsilon(1e-14));
    ks::Vec3 g;
    CHECK(ks::box_weight(c + ks::Vec3(0, 0.4, 0), c, 0.4, &g) == 0);  // on a face
    CHECK(g == ks::Vec3::Zero());
    CHECK(ks::box_weight(c + ks::Vec3(0.39, 0.39, 0.39), c, 0.4) > 0);  // a corner of the box: inside
    CHECK(ks::ball_weight(c + ks::Vec3(0.39, 0.39, 0.39), c, 0.4) == 0);  // outside the ball
    // Gradients against central differences, and C¹ at the border (the gradient tends to 0).
    std::mt19937_64 rng(9);
    std::uniform_real_distribution<double> u(-0.45, 0.45);
    const double h = 1e-7;
    for (int q = 0; q < 300; ++q) {
        const ks::Vec3 x = c + ks::Vec3(u(rng), u(rng), u(rng));
        for (int kind = 0; kind < 2; ++kind) {
            auto w = [&](const ks::Vec3& y, ks::Vec3* gr) {
                return kind == 0 ? ks::ball_weight(y, c, 0.4, gr) : ks::box_weight(y, c, 0.4, gr);
            };
            ks::Vec3 gr;
            const double v = w(x, &gr);
            CHECK(v == w(x, nullptr));
            for (int k = 0; k < 3; ++k) {
                ks::Vec3 e = ks::Vec3::Zero();
                e[k] = h;
                CHECK(gr[k] == doctest::Approx((w(x + e, nullptr) - w(x - e, nullptr)) / (2 * h)).epsilon(1e-5).scale(1));
            }
        }
    }
    ks::Vec3 g_in;
    (void)ks::box_weight(c + ks::Vec3(0.4 * (1 - 1e-6), 0.1, 0), c, 0.4, &g_in);
    CHECK(g_in.norm() < 1e-4);
    (void)ks::ball_weight(c + ks::Vec3(0.4 * (1 - 1e-6), 0, 0), c, 0.4, &g_in);
    CHECK(g_in.norm() < 1e-4);
    // PartitionOfUnity's blend is PUAccumulator over ball_weight in ball order, to the bit.
    const Setup s = random_balls(300, 5);
    const ks::PartitionOfUnity pu(s.balls, ks::Vec3::Constant(-0.5), 2.0);
    auto local = [&](std::size_t i, const ks::Vec3& x, ks::Vec3* gl) {
        if (gl) *gl = s.normal[i];
        return s.normal[i].dot(x - s.origin[i]);
    };
    std::uniform_real_distribution<double> v(-0.5, 1.5);
    int covered = 0;
    for (int q = 0; q < 1000; ++q) {
        const ks::Vec3 x(v(rng), v(rng), v(rng));
        ks::PUAccumulator acc(true);
        for (std::size_t i = 0; i < s.balls.size(); ++i) {
            ks::Vec3 dw, dg;
            const double w = ks::ball_weight(x, s.balls[i].center, s.balls[i].radius, &dw);
            if (w == 0) continue;
            const double gi = local(i, x, &dg);
            acc.add(w, dw, gi, dg);
            CHECK(pu.weight(i, x) == w);
        }
        ks::Vec3 gp;
        const double f = pu.blend(x, local, nullptr, &gp);
        CHECK(acc.covered() == !std::isnan(f));
        if (!acc.covered()) continue;
        ++covered;
        CHECK(f == acc.value());
        CHECK(gp == acc.gradient());
    }
    CHECK(covered > 300);
}

TEST_CASE("PUAccumulator over box_weight: overlapping cubes of a tiling reproduce constants and planes; C¹ blend") {
    // Cubes of side 0.25 tiling [0, 1]³, each support its cube enlarged by α = 1.35 (the
    // octree RBF's default overlap); brute force over all 64.
    const double side = 0.25, half = 1.35 * side / 2;
    std::vector<ks::Vec3> centre;
    for (int k = 0; k < 4; ++k)
        for (int j = 0; j < 4; ++j)
            for (int i = 0; i < 4; ++i) centre.emplace_back((i + 0.5) * side, (j + 0.5) * side, (k + 0.5) * side);
    const ks::Vec3 n = ks::Vec3(2, -1, 2).normalized();
    // Distinct linear local functions: the blend is C¹, its gradient the derivative of its value.
    auto blend = [&](const ks::Vec3& x, ks::Vec3* grad, int kind) {
        ks::PUAccumulator acc(grad != nullptr);
        for (std::size_t c = 0; c < centre.size(); ++c) {
            ks::Vec3 dw;
            const double w = ks::box_weight(x, centre[c], half, grad ? &dw : nullptr);
            if (w == 0) continue;
            const ks::Vec3 a = kind == 2 ? ks::Vec3(std::sin(double(c)), std::cos(3.0 * c), 0.5) : n;
            const double g = kind == 0 ? 2.5 : a.dot(x) - 0.1 * (kind == 2 ? double(c % 5) : 1.0);
            if (grad) acc.add(w, dw, g, kind == 0 ? ks::Vec3::Zero() : a);
            else acc.add(w, g);
        }
        if (!acc.covered()) return std::numeric_limits<double>::quiet_NaN();
        if (grad) *grad = acc.gradient();
        return acc.value();
    };
    std::mt19937_64 rng(6);
    std::uniform_real_distribution<double> u(0, 1);
    const double h = 1e-7;
    for (int q = 0; q < 500; ++q) {
        const ks::Vec3 x(u(rng), u(rng), u(rng));  // every point of the tiling is covered
        ks::Vec3 g;
        CHECK(blend(x, &g, 0) == doctest::Approx(2.5).epsilon(1e-14));
        CHECK(g.norm() < 1e-12);
        CHECK(blend(x, &g, 1) == doctest::Approx(n.dot(x) - 0.1).epsilon(1e-12).scale(1));
        CHECK((g - n).norm() < 1e-9);
        const double f = blend(x, &g, 2);
        CHECK(f == blend(x, nullptr, 2));
        for (int k = 0; k < 3; ++k) {
            ks::Vec3 e = ks::Vec3::Zero();
            e[k] = h;
            CHECK(g[k] == doctest::Approx((blend(x + e, nullptr, 2) - blend(x - e, nullptr, 2)) / (2 * h)).epsilon(1e-5).scale(1));
        }
    }
    // Far from every cube: nothing covers.
    CHECK(std::isnan(blend(ks::Vec3(2, 2, 2), nullptr, 1)));
}

TEST_CASE("PartitionOfUnity: bad input throws invalid_input") {
    const ks::Vec3 lo = ks::Vec3::Zero();
    CHECK_THROWS_WITH_AS(ks::PartitionOfUnity({}, lo, 1.0), doctest::Contains("no ball"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::PartitionOfUnity({{lo, 0.0}}, lo, 1.0), doctest::Contains("ball 0"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::PartitionOfUnity({{lo, 0.1}, {ks::Vec3(NAN, 0, 0), 0.1}}, lo, 1.0),
                         doctest::Contains("ball 1"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::PartitionOfUnity({{lo, 0.1}}, lo, -1.0), doctest::Contains("positive finite side"),
                         ks::invalid_input);
    const ks::PartitionOfUnity empty;
    CHECK(empty.empty());
    CHECK(std::isnan(empty.blend(lo, [](std::size_t, const ks::Vec3&, ks::Vec3*) { return 1.0; })));
}

TEST_CASE("find_edge_root: the first crossing from inside to outside, Illinois-refined") {
    int calls = 0;
    // one crossing at t = 0.3 on a curved function
    auto f = [&](double t) {
        ++calls;
        return std::exp(t) - std::exp(0.3);
    };
    const auto r = ks::find_edge_root(f, {.samples = 1});
    REQUIRE(r);
    CHECK(*r == doctest::Approx(0.3).epsilon(1e-9));
    CHECK(calls < 15);
    // linear interpolation of the ends when no iteration is allowed
    const auto lin = ks::find_edge_root([](double t) { return t * t - 0.25; }, {.samples = 1, .max_iterations = 0});
    REQUIRE(lin);
    CHECK(*lin == doctest::Approx(0.25));
    // three crossings: - + - +; the samples find the first one (t = 0.2)
    auto two = [](double t) { return (t - 0.2) * (t - 0.5) * (t - 0.8); };
    CHECK(*ks::find_edge_root(two, {.samples = 8}) == doctest::Approx(0.2).epsilon(1e-9));
    CHECK(*ks::find_edge_root(two, {.samples = 1}) == doctest::Approx(0.8).epsilon(1e-9));  // the ends alone: the last
    // no change from < 0 to >= 0: nothing
    CHECK_FALSE(ks::find_edge_root([](double t) { return 1 + t; }));
    CHECK_FALSE(ks::find_edge_root([](double t) { return -1 - t; }));
    // f == 0 counts as outside
    CHECK(*ks::find_edge_root([](double t) { return t < 0.5 ? -1.0 : 0.0; }, {.samples = 4}) >= 0.25);
}
