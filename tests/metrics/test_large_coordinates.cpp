// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Coordinates of any finite magnitude through the metrics: squared lengths overflow
// above ~1e154 and underflow below ~1e-154, so the metrics rescale their copies by a
// power of two and map lengths back. A copy scaled by 2^e gives the same report times 2^e.
#include <doctest/doctest.h>

#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/metrics/denoise.hpp>
#include <kintsugi/metrics/distance.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include "metrics/mesh_fixtures.hpp"

#include <cmath>

namespace ks = kintsugi;
using ks::IndexedMesh;
using ks::Vec3;

namespace {
IndexedMesh scaled(IndexedMesh m, double s) {
    for (auto& v : m.vertices) v *= s;
    return m;
}
IndexedMesh bumpy(const IndexedMesh& m) {
    IndexedMesh out = m;
    for (std::size_t i = 0; i < out.vertices.size(); ++i) out.vertices[i] *= 1 + 0.03 * std::sin(double(i) * 1.7);
    return out;
}
const int kExponents[] = {512, 665, 997, -997};  // about 1e154, 1e200, 1e300, 1e-300
}  // namespace

TEST_CASE("topology_report: counts do not depend on the magnitude of the coordinates") {
    const IndexedMesh torus = fixtures::torus();
    const auto ref = ks::topology_report(torus);
    for (const double s : {1e154, 1e200, 1e300, 1e-300, std::ldexp(1.0, 1021)}) {
        CAPTURE(s);
        const auto r = ks::topology_report(scaled(torus, s));
        CHECK(r.degenerate_faces == 0);
        CHECK(r.genus == ref.genus);
        CHECK(r.edges == ref.edges);
        CHECK(r.closed);
        CHECK(r.manifold);
    }
}

TEST_CASE("compare / compare_points / distances_to_mesh: a copy scaled by 2^e gives the lengths times 2^e") {
    const IndexedMesh a = bumpy(fixtures::uv_sphere(12, 16)), b = fixtures::uv_sphere(10, 14);
    const ks::DistanceParams params{.samples = 3000};
    const auto ref = ks::compare(a, b, params);
    const auto ref_p = ks::compare_points(a.vertices, b, params);
    const auto ref_d = ks::distances_to_mesh(a.vertices, b);
    REQUIRE(ref.a_to_b.mean > 0);
    for (const int e : kExponents) {
        CAPTURE(e);
        const double s = std::ldexp(1.0, e);
        const IndexedMesh as = scaled(a, s), bs = scaled(b, s);
        const auto r = ks::compare(as, bs, params);
        CHECK(r.diagonal == ref.diagonal * s);
        CHECK(r.a_to_b.mean == ref.a_to_b.mean * s);
        CHECK(r.b_to_a.hausdorff == ref.b_to_a.hausdorff * s);
        CHECK(r.chamfer == ref.chamfer * s);
        CHECK(r.fscore == ref.fscore);
        // A sample on an edge may be matched to either face (the AABB tree's choice).
        CHECK(r.normal_consistency == doctest::Approx(ref.normal_consistency).epsilon(1e-4));
        const auto p = ks::compare_points(as.vertices, bs, params);
        CHECK(p.a_to_b.rms == ref_p.a_to_b.rms * s);
        CHECK(p.b_to_a.p99 == ref_p.b_to_a.p99 * s);
        const auto d = ks::distances_to_mesh(as.vertices, bs);
        std::size_t same = 0;
        for (std::size_t i = 0; i < d.size(); ++i) same += d[i] == ref_d[i] * s;
        CHECK(same == d.size());
    }
    // Not a power of two: the same relative figures up to rounding.
    for (const double s : {1e154, 1e200, 1e300, 1e-300}) {
        CAPTURE(s);
        const auto r = ks::compare(scaled(a, s), scaled(b, s), params);
        CHECK(r.relative(r.a_to_b).mean == doctest::Approx(ref.relative(ref.a_to_b).mean).epsilon(1e-9));
        CHECK(r.relative(r.b_to_a).hausdorff == doctest::Approx(ref.relative(ref.b_to_a).hausdorff).epsilon(1e-9));
    }
}

TEST_CASE("denoise_metrics: angles and RMS at any magnitude") {
    const IndexedMesh truth = fixtures::uv_sphere(12, 16), result = bumpy(truth);
    const auto ref = ks::denoise_metrics(result, truth);
    REQUIRE(ref.mean_normal_angle_deg > 0.1);
    for (const int e : kExponents) {
        CAPTURE(e);
        const double s = std::ldexp(1.0, e);
        const auto m = ks::denoise_metrics(scaled(result, s), scaled(truth, s));
        CHECK(m.mean_normal_angle_deg == ref.mean_normal_angle_deg);
        CHECK(m.max_normal_angle_deg == ref.max_normal_angle_deg);
        CHECK(m.vertex_rms == ref.vertex_rms * s);
    }
}
