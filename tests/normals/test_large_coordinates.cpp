// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Coordinates of any finite magnitude: squared distances of points at 1e154 and above
// overflow double (the normal estimation used to crash there with SIGSEGV), those of
// points at 1e-154 and below underflow. The algorithms rescale their own copy by a power
// of two, so a scaled copy of a shape gives the same normals as the shape itself.
#include <doctest/doctest.h>

#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/normals/estimate_normals.hpp>
#include <kintsugi/spatial/kd_tree.hpp>

#include <cmath>
#include <numbers>
#include <vector>

namespace ks = kintsugi;

namespace {

// A bumpy closed surface (an ellipsoid with ripples): normals depend on the neighbours.
std::vector<ks::Vec3> bumpy_shape(std::size_t n) {
    std::vector<ks::Vec3> p(n);
    const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
    for (std::size_t i = 0; i < n; ++i) {
        const double z = 1.0 - 2.0 * (static_cast<double>(i) + 0.5) / static_cast<double>(n);
        const double r = std::sqrt(1.0 - z * z), phi = golden * static_cast<double>(i);
        const double bump = 1.0 + 0.05 * std::sin(5 * phi) * std::cos(3 * z);
        p[i] = ks::Vec3(1.5 * r * std::cos(phi), r * std::sin(phi), 0.8 * z) * bump + ks::Vec3(0.3, -0.2, 0.1);
    }
    return p;
}

std::vector<ks::Vec3> scaled(std::vector<ks::Vec3> p, double s) {
    for (auto& x : p) x *= s;
    return p;
}

std::vector<ks::Vec3> normals_of(const std::vector<ks::Vec3>& pts, ks::NormalMethod method) {
    std::vector<ks::Vec3> p = pts, n;
    auto view = ks::with_normals(p, n);
    const auto r = ks::estimate_normals(view, {.k = 12, .method = method});
    REQUIRE(r.status == ks::Status::ok);
    return n;
}

}  // namespace

TEST_CASE("estimate_normals: a copy scaled by 2^512, 2^665, 2^997 or 2^-997 gives the same normals, bit for bit") {
    const auto base = bumpy_shape(1500);
    for (const auto method : {ks::NormalMethod::pca, ks::NormalMethod::jet}) {
        const auto ref = normals_of(base, method);
        for (const int e : {512, 665, 997, -997}) {  // about 1e154, 1e200, 1e300, 1e-300
            CAPTURE(e);
            const auto n = normals_of(scaled(base, std::ldexp(1.0, e)), method);
            REQUIRE(n.size() == ref.size());
            std::size_t same = 0;
            for (std::size_t i = 0; i < n.size(); ++i) same += n[i] == ref[i];
            CHECK(same == n.size());
        }
    }
}

TEST_CASE("estimate_normals: coordinates at 1e154, 1e200, 1e300 and 1e-300 give the unit-scale normals") {
    const auto base = bumpy_shape(1500);
    const auto ref = normals_of(base, ks::NormalMethod::jet);
    for (const double s : {1e154, 1e200, 1e300, 1e-300}) {
        CAPTURE(s);
        const auto n = normals_of(scaled(base, s), ks::NormalMethod::jet);
        double worst = 1;
        for (std::size_t i = 0; i < n.size(); ++i) {
            REQUIRE(n[i].allFinite());
            worst = std::min(worst, n[i].dot(ref[i]));  // same orientation, same direction
        }
        CHECK(worst > 1 - 1e-9);
    }
}

TEST_CASE("orient_normals: coordinates at 1e300 and 1e-300 give the unit-scale signs") {
    const auto base = bumpy_shape(1200);
    const auto ref = normals_of(base, ks::NormalMethod::pca);
    for (const double s : {1e300, 1e-300, std::ldexp(1.0, 1020)}) {
        CAPTURE(s);
        std::vector<ks::Vec3> p = scaled(base, s), n = ref;
        for (std::size_t i = 0; i < n.size(); i += 3) n[i] = -n[i];  // scramble a third of the signs
        auto view = ks::with_normals(p, n);
        REQUIRE(ks::orient_normals(view, {.k = 12}).status == ks::Status::ok);
        std::size_t same = 0;
        for (std::size_t i = 0; i < n.size(); ++i) same += n[i] == ref[i];
        CHECK(same == n.size());
    }
}

TEST_CASE("KdTree refuses points whose squared distances leave double's range, and far queries") {
    const auto base = bumpy_shape(200);
    for (const double s : {1e154, 1e200, 1e300}) {
        CAPTURE(s);
        CHECK_THROWS_WITH_AS(ks::KdTree(scaled(base, s)), doctest::Contains("squared distances would overflow"),
                             ks::invalid_input);
    }
    CHECK_THROWS_WITH_AS(ks::KdTree(scaled(base, 1e-300)), doctest::Contains("squared distances would underflow"),
                         ks::invalid_input);
    // Inside the range, results scale exactly: 2^400 (about 2.6e120).
    const double s = std::ldexp(1.0, 400);
    const ks::KdTree unit(base), big(scaled(base, s));
    const auto a = unit.knn(base[7], 9), b = big.knn(base[7] * s, 9);
    REQUIRE(a.size() == 9);
    REQUIRE(b.size() == 9);
    for (std::size_t i = 0; i < 9; ++i) {
        CHECK(a[i].index == b[i].index);
        CHECK(b[i].squared_distance == a[i].squared_distance * s * s);
    }
    // A query whose squared distance to every point overflows is refused, not answered with garbage.
    CHECK_THROWS_WITH_AS((void)big.nearest(ks::Vec3(1e300, 0, 0)), doctest::Contains("overflow"), ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)unit.knn(ks::Vec3(0, -1e200, 0), 3), doctest::Contains("overflow"), ks::invalid_input);
}
