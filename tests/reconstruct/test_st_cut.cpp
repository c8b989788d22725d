// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The generic s-t minimum cut (kintsugi/graph/st_cut.hpp).
#include <doctest/doctest.h>

#include <kintsugi/graph/st_cut.hpp>

#include <cmath>
#include <limits>
#include <random>
#include <stop_token>
#include <vector>

namespace ks = kintsugi;

namespace {

// Cost of a labelling (bit i set = node i on the sink side), straight from the definition.
double labelling_cost(const ks::StCutGraph& g, unsigned mask) {
    auto sink = [&](std::size_t i) { return ((mask >> i) & 1U) != 0; };
    double c = 0;
    for (std::size_t i = 0; i < g.num_nodes; ++i) {
        const double cs = g.source_capacities.empty() ? 0 : g.source_capacities[i];
        const double ct = g.sink_capacities.empty() ? 0 : g.sink_capacities[i];
        c += sink(i) ? cs : ct;
    }
    for (std::size_t e = 0; e < g.edges.size(); ++e) {
        const auto [a, b] = g.edges[e];
        const double r = g.reverse_capacities.empty() ? g.capacities[e] : g.reverse_capacities[e];
        if (!sink(a) && sink(b)) c += g.capacities[e];
        if (sink(a) && !sink(b)) c += r;
    }
    return c;
}

unsigned mask_of(const ks::StCutResult& r) {
    unsigned m = 0;
    for (std::size_t i = 0; i < r.labels.size(); ++i)
        if (r.labels[i] == ks::StSide::sink) m |= 1U << i;
    return m;
}

}  // namespace

TEST_CASE("st_min_cut: two nodes, hand-computed cut") {
    // Both source: 1 + 3 = 4; both sink: 3 + 1 = 4; {S, T}: 1 + 1 + 1 = 3; {T, S}: 3 + 3 + 1 = 7.
    ks::StCutGraph g{.num_nodes = 2,
                     .edges = {{0, 1}},
                     .capacities = {1.0},
                     .reverse_capacities = {},
                     .source_capacities = {3.0, 1.0},
                     .sink_capacities = {1.0, 3.0}};
    const auto r = ks::st_min_cut(g);
    REQUIRE(r.status == ks::Status::ok);
    REQUIRE(r.labels.size() == 2);
    CHECK(r.labels[0] == ks::StSide::source);
    CHECK(r.labels[1] == ks::StSide::sink);
    CHECK(r.cut_value == doctest::Approx(3.0));
}

TEST_CASE("st_min_cut: directed capacities decide the side") {
    // Chain s -> 0 -> 1 -> 2 -> t with a cheap arc 1 -> 2 (0.5) and an expensive way back.
    ks::StCutGraph g{.num_nodes = 3,
                     .edges = {{0, 1}, {1, 2}},
                     .capacities = {4.0, 0.5},
                     .reverse_capacities = {0.0, 100.0},
                     .source_capacities = {10.0, 0.0, 0.0},
                     .sink_capacities = {0.0, 0.0, 10.0}};
    const auto r = ks::st_min_cut(g);
    CHECK(r.labels[0] == ks::StSide::source);
    CHECK(r.labels[1] == ks::StSide::source);
    CHECK(r.labels[2] == ks::StSide::sink);
    CHECK(r.cut_value == doctest::Approx(0.5));
    // Reversing the roles of the directions moves the cut to the other arc.
    g.capacities = {0.25, 100.0};
    g.reverse_capacities = {100.0, 0.0};
    const auto r2 = ks::st_min_cut(g);
    CHECK(r2.labels[0] == ks::StSide::source);
    CHECK(r2.labels[1] == ks::StSide::sink);
    CHECK(r2.labels[2] == ks::StSide::sink);
    CHECK(r2.cut_value == doctest::Approx(0.25));
}

TEST_CASE("st_min_cut: random small graphs agree with exhaustive search") {
    std::mt19937 rng(12345);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int trial = 0; trial < 200; ++trial) {
        const std::size_t n = 1 + rng() % 9;
        ks::StCutGraph g;
        g.num_nodes = n;
        const bool symmetric = trial % 2 == 0;
        for (std::size_t a = 0; a < n; ++a)
            for (std::size_t b = a + 1; b < n; ++b)
                if (u(rng) < 0.5) {
                    g.edges.push_back({a, b});
                    g.capacities.push_back(std::floor(u(rng) * 5));
                    if (!symmetric) g.reverse_capacities.push_back(std::floor(u(rng) * 5));
                }
        for (std::size_t i = 0; i < n; ++i) {
            g.source_capacities.push_back(std::floor(u(rng) * 8));
            g.sink_capacities.push_back(std::floor(u(rng) * 8));
        }
        double best = std::numeric_limits<double>::infinity();
        for (unsigned m = 0; m < (1U << n); ++m) best = std::min(best, labelling_cost(g, m));
        const auto r = ks::st_min_cut(g);
        CAPTURE(trial);
        CHECK(r.cut_value == doctest::Approx(best));
        CHECK(labelling_cost(g, mask_of(r)) == doctest::Approx(best));
    }
}

TEST_CASE("st_min_cut: grid segmentation removes salt noise and keeps the square") {
    const int W = 24, H = 20;
    auto id = [&](int x, int y) { return static_cast<std::size_t>(y * W + x); };
    auto in_square = [](int x, int y) { return x >= 6 && x < 14 && y >= 5 && y < 13; };
    ks::StCutGraph g;
    g.num_nodes = static_cast<std::size_t>(W * H);
    std::mt19937 rng(7);
    int flipped = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            double v = in_square(x, y) ? 0.9 : 0.1;
            // isolated flipped pixels, away from the square's border
            if ((x % 5 == 2 && y % 7 == 3) && !in_square(x - 1, y) && !in_square(x + 1, y) && !in_square(x, y - 1) &&
                !in_square(x, y + 1)) {
                v = 1.0 - v;
                ++flipped;
            }
            g.source_capacities.push_back(v);        // bright wants the source (foreground)
            g.sink_capacities.push_back(1.0 - v);
            if (x + 1 < W) {
                g.edges.push_back({id(x, y), id(x + 1, y)});
                g.capacities.push_back(0.5);
            }
            if (y + 1 < H) {
                g.edges.push_back({id(x, y), id(x, y + 1)});
                g.capacities.push_back(0.5);
            }
        }
    REQUIRE(flipped > 5);
    const auto r = ks::st_min_cut(g);
    int wrong = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            if ((r.labels[id(x, y)] == ks::StSide::source) != in_square(x, y)) ++wrong;
    CHECK(wrong == 0);
    // 32 border edges of 0.5, plus the 64 square pixels paying 0.1 and 396 others paying 0.1,
    // except the flipped ones which pay 0.9 instead of 0.1.
    CHECK(r.cut_value == doctest::Approx(32 * 0.5 + (W * H - flipped) * 0.1 + flipped * 0.9));
    CHECK(r.network_nodes == static_cast<std::size_t>(W * H + 2));
}

TEST_CASE("st_min_cut: infinite terminal capacities are hard constraints") {
    const double inf = std::numeric_limits<double>::infinity();
    ks::StCutGraph g{.num_nodes = 3,
                     .edges = {{0, 1}, {1, 2}},
                     .capacities = {1.0, 1.0},
                     .reverse_capacities = {},
                     .source_capacities = {inf, 0.0, 5.0},
                     .sink_capacities = {0.0, 2.0, inf}};
    const auto r = ks::st_min_cut(g);
    CHECK(r.labels[0] == ks::StSide::source);
    CHECK(r.labels[2] == ks::StSide::sink);
    // node 2 forced to the sink pays its source capacity 5; node 1: source side costs 2 + 1, sink side 1.
    CHECK(r.labels[1] == ks::StSide::sink);
    CHECK(r.cut_value == doctest::Approx(5.0 + 1.0));
    // Empty graph and isolated nodes.
    ks::StCutGraph empty;
    CHECK(ks::st_min_cut(empty).labels.empty());
    ks::StCutGraph iso{.num_nodes = 2, .edges = {}, .capacities = {}, .reverse_capacities = {},
                       .source_capacities = {}, .sink_capacities = {0.0, 1.0}};
    const auto ri = ks::st_min_cut(iso);
    CHECK(ri.labels[0] == ks::StSide::sink);
    CHECK(ri.labels[1] == ks::StSide::sink);
    CHECK(ri.cut_value == 0.0);
}

TEST_CASE("st_min_cut: bad input throws invalid_input") {
    ks::StCutGraph g{.num_nodes = 2,
                     .edges = {{0, 1}},
                     .capacities = {1.0},
                     .reverse_capacities = {},
                     .source_capacities = {1.0, 0.0},
                     .sink_capacities = {0.0, 1.0}};
    REQUIRE_NOTHROW((void)ks::st_min_cut(g));
    auto bad = g;
    bad.capacities[0] = -1;
    CHECK_THROWS_WITH_AS((void)ks::st_min_cut(bad), doctest::Contains("capacities[0]"), ks::invalid_input);
    bad = g;
    bad.capacities[0] = std::nan("");
    CHECK_THROWS_AS((void)ks::st_min_cut(bad), ks::invalid_input);
    bad = g;
    bad.capacities[0] = std::numeric_limits<double>::infinity();
    CHECK_THROWS_AS((void)ks::st_min_cut(bad), ks::invalid_input);
    bad = g;
    bad.sink_capacities[1] = std::nan("");
    CHECK_THROWS_WITH_AS((void)ks::st_min_cut(bad), doctest::Contains("sink_capacities[1]"), ks::invalid_input);
    bad = g;
    bad.source_capacities[0] = -0.5;
    CHECK_THROWS_AS((void)ks::st_min_cut(bad), ks::invalid_input);
    bad = g;
    bad.edges[0] = {0, 2};
    CHECK_THROWS_WITH_AS((void)ks::st_min_cut(bad), doctest::Contains("edge 0"), ks::invalid_input);
    bad = g;
    bad.capacities.push_back(1.0);
    CHECK_THROWS_WITH_AS((void)ks::st_min_cut(bad), doctest::Contains("one capacity per edge"), ks::invalid_input);
    bad = g;
    bad.reverse_capacities = {1.0, 2.0};
    CHECK_THROWS_AS((void)ks::st_min_cut(bad), ks::invalid_input);
    bad = g;
    bad.source_capacities = {1.0};
    CHECK_THROWS_AS((void)ks::st_min_cut(bad), ks::invalid_input);
    bad = g;
    bad.source_capacities[0] = bad.sink_capacities[0] = std::numeric_limits<double>::infinity();
    CHECK_THROWS_WITH_AS((void)ks::st_min_cut(bad), doctest::Contains("both"), ks::invalid_input);
}

TEST_CASE("st_min_cut: cancellation") {
    ks::StCutGraph g{.num_nodes = 2,
                     .edges = {{0, 1}},
                     .capacities = {1.0},
                     .reverse_capacities = {},
                     .source_capacities = {1.0, 0.0},
                     .sink_capacities = {0.0, 1.0}};
    std::stop_source stop;
    stop.request_stop();
    ks::StCutParams p;
    p.control.stop = stop.get_token();
    const auto r = ks::st_min_cut(g, p);
    CHECK(r.status == ks::Status::cancelled);
    CHECK(r.labels.empty());
    ks::StCutParams p2;
    p2.control.progress = [](const ks::ProgressEvent&) { return false; };
    CHECK(ks::st_min_cut(g, p2).status == ks::Status::cancelled);
}
