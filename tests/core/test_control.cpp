// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// RunControl/Progress and the deterministic parallel loops.
#include <doctest/doctest.h>

#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>

#include <cmath>
#include <numeric>
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
