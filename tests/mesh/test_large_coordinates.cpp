// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Coordinates of any finite magnitude through the mesh helpers and Taubin smoothing:
// squared lengths overflow above ~1e154 (1e300 normals used to come out NaN or zero) and
// underflow below ~1e-154. Results equal the unit-scale ones up to the scale; a true
// value beyond double's range (an area of 1e600) is +inf, never NaN.
#include <doctest/doctest.h>

#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/mesh/taubin.hpp>

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
}  // namespace

TEST_CASE("mesh geometry helpers at 1e154, 1e200, 1e300, 1e-300 and near DBL_MAX") {
    IndexedMesh base = fixtures::uv_sphere(8, 12);
    for (std::size_t i = 0; i < base.vertices.size(); ++i) base.vertices[i] *= 1 + 0.05 * std::sin(double(i));
    const auto fn0 = ks::face_normals(base);
    const auto vn0 = ks::vertex_normals(base);
    const auto area0 = ks::face_areas(base);
    const double edge0 = ks::mean_edge_length(base), vol0 = ks::signed_volume(base);
    for (const int e : {512, 665, 997, -997, 1020}) {
        CAPTURE(e);
        const double s = std::ldexp(1.0, e);
        const IndexedMesh m = scaled(base, s);
        const auto fn = ks::face_normals(m);
        const auto vn = ks::vertex_normals(m);
        const auto area = ks::face_areas(m);
        std::size_t same_fn = 0, same_vn = 0, area_ok = 0;
        for (std::size_t f = 0; f < fn.size(); ++f) {
            same_fn += fn[f] == fn0[f] && ks::face_normal(m, f) == ks::face_normal(base, f);
            const double want = std::ldexp(area0[f], 2 * e);  // +inf beyond double's range
            area_ok += std::isinf(want) ? std::isinf(area[f]) : area[f] == doctest::Approx(want).epsilon(1e-14);
        }
        for (std::size_t v = 0; v < vn.size(); ++v) same_vn += vn[v] == vn0[v];
        CHECK(same_fn == fn.size());
        CHECK(same_vn == vn.size());
        CHECK(area_ok == area.size());
        CHECK(ks::mean_edge_length(m) == edge0 * s);
        const double vol = ks::signed_volume(m), want_vol = std::ldexp(vol0, 3 * e);
        CHECK(!std::isnan(vol));
        if (std::isinf(want_vol) || want_vol == 0)
            CHECK(vol == want_vol);
        else
            CHECK(vol == doctest::Approx(want_vol).epsilon(1e-14));
    }
    // A face spanning -DBL_MAX/2 .. DBL_MAX/2: edge vectors overflow, the normal does not.
    IndexedMesh huge;
    const double big = 8e307;
    huge.vertices = {Vec3(-big, -big, 0), Vec3(big, -big, 0), Vec3(0, big, 0)};
    huge.faces = {{0, 1, 2}};
    CHECK(ks::face_normal(huge, 0) == Vec3(0, 0, 1));
    CHECK(std::isinf(ks::face_areas(huge)[0]));
    CHECK(ks::vertex_normals(huge)[2] == Vec3(0, 0, 1));
}

TEST_CASE("smooth_taubin: a copy scaled by 2^e is smoothed bit for bit alike; 1e300 stays finite") {
    IndexedMesh base = fixtures::uv_sphere(10, 14);
    for (std::size_t i = 0; i < base.vertices.size(); ++i) base.vertices[i] *= 1 + 0.05 * std::sin(3.0 * double(i));
    IndexedMesh ref = base;
    REQUIRE(ks::smooth_taubin(ref).status == ks::Status::ok);
    for (const int e : {512, 665, 997, -997, 1022}) {
        CAPTURE(e);
        const double s = std::ldexp(1.0, e);
        IndexedMesh m = scaled(base, s);
        REQUIRE(ks::smooth_taubin(m).status == ks::Status::ok);
        std::size_t same = 0;
        for (std::size_t v = 0; v < m.vertices.size(); ++v) same += m.vertices[v] == ref.vertices[v] * s;
        CHECK(same == m.vertices.size());
    }
    IndexedMesh m = scaled(base, 1.7e308);
    REQUIRE(ks::smooth_taubin(m).status == ks::Status::ok);
    for (std::size_t v = 0; v < m.vertices.size(); ++v) {
        REQUIRE(m.vertices[v].allFinite());
        CHECK((m.vertices[v] / 1.7e308 - ref.vertices[v]).norm() < 1e-12);
    }
}
