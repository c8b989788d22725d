// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Coordinates of any finite magnitude: the smoothing rescales its copy by a power of
// two, so a scaled copy of a mesh is smoothed exactly as the mesh itself, and 1e300
// coordinates are not reported as "zero length edges" (their squared lengths overflow).
#include <doctest/doctest.h>

#include "smooth/smooth_support.hpp"

#include <kintsugi/metrics/denoise.hpp>
#include <kintsugi/smooth/feature_bilateral.hpp>

#include <cmath>

namespace ks = kintsugi;
namespace ss = smooth_support;

namespace {
ks::IndexedMesh scaled(ks::IndexedMesh m, double s) {
    for (auto& v : m.vertices) v *= s;
    return m;
}
}  // namespace

TEST_CASE("smooth_feature_bilateral: a copy scaled by 2^512, 2^665, 2^997 or 2^-997 is smoothed bit for bit alike") {
    const auto clean = ss::box_mesh(8);
    const auto noisy = ss::add_normal_noise(clean, 0.3 * ks::mean_edge_length(clean), 3);
    ks::IndexedMesh ref = noisy;
    const auto rr = ks::smooth_feature_bilateral(ref);
    REQUIRE(rr.features.sharp_edges.size() > 0);
    for (const int e : {512, 665, 997, -997}) {  // about 1e154, 1e200, 1e300, 1e-300
        CAPTURE(e);
        const double s = std::ldexp(1.0, e);
        ks::IndexedMesh m = scaled(noisy, s);
        const auto r = ks::smooth_feature_bilateral(m);
        REQUIRE(r.status == ks::Status::ok);
        CHECK(r.features.sharp_edges == rr.features.sharp_edges);
        CHECK(r.features.mean_edge_length == rr.features.mean_edge_length * s);
        std::size_t same = 0;
        for (std::size_t v = 0; v < m.vertices.size(); ++v) same += m.vertices[v] == ref.vertices[v] * s;
        CHECK(same == m.vertices.size());
        const auto f = ks::detect_sharp_features(scaled(noisy, s));
        CHECK(f.features.sharp_edges == rr.features.sharp_edges);
    }
}

TEST_CASE("smooth_feature_bilateral: coordinates at 1e154, 1e200, 1e300 and 1e-300 smooth like the unit-scale mesh") {
    const auto clean = ss::box_mesh(8);
    const auto noisy = ss::add_normal_noise(clean, 0.3 * ks::mean_edge_length(clean), 5);
    ks::IndexedMesh ref = noisy;
    (void)ks::smooth_feature_bilateral(ref);
    const double err_ref = ks::denoise_metrics(ref, clean).mean_normal_angle_deg;
    for (const double s : {1e154, 1e200, 1e300, 1e-300}) {
        CAPTURE(s);
        ks::IndexedMesh m = scaled(noisy, s);
        REQUIRE(ks::smooth_feature_bilateral(m).status == ks::Status::ok);
        for (const auto& v : m.vertices) REQUIRE(v.allFinite());
        // Same normal error against the clean box (angles do not depend on the scale).
        CHECK(ks::denoise_metrics(m, scaled(clean, s)).mean_normal_angle_deg ==
              doctest::Approx(err_ref).epsilon(1e-3));
    }
}

TEST_CASE("smooth_feature_bilateral: a mesh whose edges really have zero length is named so, whatever its position") {
    ks::IndexedMesh m;
    m.vertices = {ks::Vec3(1e300, 1e300, 1e300), ks::Vec3(1e300, 1e300, 1e300), ks::Vec3(1e300, 1e300, 1e300)};
    m.faces = {{0, 1, 2}};
    CHECK_THROWS_WITH_AS(ks::smooth_feature_bilateral(m), doctest::Contains("every edge has zero length"),
                         ks::invalid_input);
}
