// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// RunControl/Progress, the deterministic parallel loops and the disjoint sets.
#include <doctest/doctest.h>

#include <kintsugi/core/control.hpp>
#include <kintsugi/core/disjoint_sets.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <random>
#include <utility>
#include <vector>

namespace ks = kintsugi;

TEST_CASE("Progress throttles callbacks and reports stages") {
    int calls = 0;
    double last = -1;
    ks::RunControl rc;
    rc.progress = [&](const ks::ProgressEvent& e) {
        ++calls;
        CHECK(e.fraction >= last);
        last = e.fraction;
        return true;
    };
    ks::detail::Progress p(rc);
    p.stage("a", 0.0, 0.5);
    for (int i = 0; i <= 100000; ++i) p.update(i / 100000.0);
    p.stage("b", 0.5, 1.0);
    for (int i = 0; i <= 100000; ++i) p.update(i / 100000.0);
    const auto t = p.finish();
    CHECK(calls <= 110);
    CHECK(calls >= 50);
    CHECK(last == 1.0);
    REQUIRE(t.size() == 2);
    CHECK(t[0].stage == "a");
    CHECK(t[1].stage == "b");
}

TEST_CASE("Progress cancels through the callback and the stop token") {
    ks::RunControl rc;
    rc.progress = [](const ks::ProgressEvent& e) { return e.fraction < 0.3; };
    ks::detail::Progress p(rc);
    p.stage("x", 0, 1);
    CHECK_THROWS_AS(
        for (int i = 0; i <= 100; ++i) p.update(i / 100.0), ks::detail::cancelled_exception);

    std::stop_source src;
    ks::RunControl rc2;
    rc2.stop = src.get_token();
    ks::detail::Progress p2(rc2);
    p2.stage("y", 0, 1);
    CHECK_NOTHROW(p2.check());
    src.request_stop();
    CHECK_THROWS_AS(p2.check(), ks::detail::cancelled_exception);
    CHECK(ks::to_string(ks::Status::cancelled) == "cancelled");
}

TEST_CASE("parallel_reduce is identical whatever the thread count") {
    std::vector<double> v(200000);
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = std::sin(double(i)) * 1e-3 + 1.0 / double(i + 1);
    auto sum = [&] {
        return ks::parallel_reduce(
            std::size_t{0}, v.size(), 0.0,
            [&](std::size_t b, std::size_t e, double acc) {
                for (std::size_t i = b; i < e; ++i) acc += v[i];
                return acc;
            },
            [](double a, double b) { return a + b; }, 1000);
    };
    double s1 = 0, s2 = 0;
    {
        ks::ThreadLimit one(1);
        s1 = sum();
    }
    {
        ks::ThreadLimit two(2);
        s2 = sum();
    }
    CHECK(s1 == s2);  // bitwise equal, not just close
    CHECK(s1 == doctest::Approx(std::accumulate(v.begin(), v.end(), 0.0)));

    std::vector<int> out(10000, 0);
    ks::parallel_for(0, out.size(), [&](std::size_t i) { out[i] = int(i) * 2; });
    for (std::size_t i = 0; i < out.size(); ++i) REQUIRE(out[i] == int(i) * 2);
}

TEST_CASE("exceptions carry the file name") {
    const ks::io_error e("/tmp/x.ply", "truncated body");
    CHECK(std::string(e.what()) == "/tmp/x.ply: truncated body");
    CHECK(e.path() == "/tmp/x.ply");
    CHECK_THROWS_AS(throw ks::invalid_input("bad"), std::invalid_argument);
}

TEST_CASE_TEMPLATE("DisjointSets: the components of a random graph, named by their smallest element", I, std::size_t,
                   std::uint32_t) {
    // 2,000 elements, 1,500 random unions (about 500 sets), against a breadth-first
    // labelling of the same graph; then the same unions in reverse order.
    constexpr std::size_t n = 2000;
    std::mt19937 rng(7);
    std::uniform_int_distribution<std::size_t> pick(0, n - 1);
    std::vector<std::pair<I, I>> edges(1500);
    for (auto& [a, b] : edges) a = static_cast<I>(pick(rng)), b = static_cast<I>(pick(rng));
    std::vector<std::vector<std::size_t>> adj(n);
    for (const auto& [a, b] : edges) adj[a].push_back(b), adj[b].push_back(a);
    std::vector<std::size_t> smallest(n, n);  // breadth-first: the smallest element of each component
    std::size_t components = 0;
    for (std::size_t s = 0; s < n; ++s) {
        if (smallest[s] != n) continue;
        ++components;
        std::vector<std::size_t> queue{s};
        smallest[s] = s;
        for (std::size_t q = 0; q < queue.size(); ++q)
            for (const std::size_t u : adj[queue[q]])
                if (smallest[u] == n) smallest[u] = s, queue.push_back(u);
    }
    REQUIRE(components > 300);
    REQUIRE(components < 900);

    ks::detail::DisjointSets<I> sets(n);
    CHECK(sets.size() == n);
    std::size_t merges = 0;
    for (const auto& [a, b] : edges) {
        const bool apart = !sets.same(a, b);
        CHECK(sets.unite(a, b) == apart);  // true exactly when two sets were merged
        merges += apart;
        CHECK(sets.same(a, b));
    }
    CHECK(merges == n - components);
    for (std::size_t v = 0; v < n; ++v) CHECK(sets.find(static_cast<I>(v)) == smallest[v]);

    ks::detail::DisjointSets<I> reversed(n);
    for (auto it = edges.rbegin(); it != edges.rend(); ++it) reversed.unite(it->second, it->first);
    for (std::size_t v = 0; v < n; ++v) CHECK(reversed.find(static_cast<I>(v)) == smallest[v]);
}

TEST_CASE("DisjointSets: a chain linked from its far end") {
    // unite(k + 1, k) for k = n-2 .. 0 hangs each root under a smaller one, a path of
    // depth n (the worst order for a union without ranks); every element still finds 0.
    constexpr std::size_t n = 100000;
    ks::detail::DisjointSets<std::size_t> sets(n);
    std::size_t merges = 0;
    for (std::size_t k = n - 1; k-- > 0;) merges += sets.unite(k + 1, k);
    CHECK(merges == n - 1);
    std::size_t found_zero = 0;
    for (std::size_t v = n; v-- > 0;) found_zero += sets.find(v) == 0;
    CHECK(found_zero == n);
    CHECK_FALSE(sets.unite(0, n - 1));
    sets.reset(3);  // singletons again, whatever was united before
    CHECK(sets.size() == 3);
    CHECK(sets.find(2) == 2);
    CHECK_FALSE(sets.same(0, 2));
    const ks::detail::DisjointSets<std::size_t> none;
    CHECK(none.size() == 0);
}
