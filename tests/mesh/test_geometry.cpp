// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// mesh/geometry.hpp: normals, areas, edge lengths, bounding box and volume against
// closed-form values.
#include <doctest/doctest.h>

#include <kintsugi/mesh/geometry.hpp>

#include "metrics/mesh_fixtures.hpp"

#include <cmath>
#include <numbers>
#include <numeric>

namespace ks = kintsugi;
using ks::IndexedMesh;
using ks::Vec3;

TEST_CASE("geometry: face normals and areas of the unit cube") {
    const IndexedMesh m = fixtures::cube();
    const auto n = ks::face_normals(m);
    const auto a = ks::face_areas(m);
    REQUIRE(n.size() == 12);
    REQUIRE(a.size() == 12);
    const Vec3 centre(0.5, 0.5, 0.5);
    for (std::size_t f = 0; f < 12; ++f) {
        CHECK(a[f] == doctest::Approx(0.5));
        CHECK(n[f].norm() == doctest::Approx(1.0));
        // outward: points away from the centre, and is axis-aligned
        const Vec3 c = (m.vertices[m.faces[f][0]] + m.vertices[m.faces[f][1]] + m.vertices[m.faces[f][2]]) / 3;
        CHECK(n[f].dot(c - centre) > 0);
        CHECK(n[f].cwiseAbs().maxCoeff() == doctest::Approx(1.0));
        CHECK((ks::face_normal(m, f) - n[f]).norm() == doctest::Approx(0.0));
    }
    CHECK(std::accumulate(a.begin(), a.end(), 0.0) == doctest::Approx(6.0));
}

TEST_CASE("geometry: vertex normals, volume, edge length") {
    SUBCASE("cube corners") {
        const IndexedMesh m = fixtures::cube();
        const auto vn = ks::vertex_normals(m);
        REQUIRE(vn.size() == 8);
        for (std::size_t v = 0; v < 8; ++v) {
            CHECK(vn[v].norm() == doctest::Approx(1.0));
            CHECK(vn[v].dot(m.vertices[v] - Vec3(0.5, 0.5, 0.5)) > 0);  // outward
        }
        CHECK(ks::signed_volume(m) == doctest::Approx(1.0));
        // 12 unit edges + 6 face diagonals of length sqrt 2
        CHECK(ks::mean_edge_length(m) == doctest::Approx((12 + 6 * std::sqrt(2.0)) / 18));
    }
    SUBCASE("flipping every face flips the volume sign") {
        IndexedMesh m = fixtures::cube(Vec3(3, -2, 7));  // away from the origin
        CHECK(ks::signed_volume(m) == doctest::Approx(1.0));
        for (auto& f : m.faces) std::swap(f[1], f[2]);
        CHECK(ks::signed_volume(m) == doctest::Approx(-1.0));
    }
    SUBCASE("sphere: normals approach the radial direction, volume approaches 4/3 pi") {
        const IndexedMesh s = fixtures::uv_sphere(64, 128, 2.0);
        const auto vn = ks::vertex_normals(s);
        double worst = 0;
        for (std::size_t v = 0; v < s.vertices.size(); ++v)
            worst = std::max(worst, std::acos(std::clamp(vn[v].dot(s.vertices[v].normalized()), -1.0, 1.0)));
        CHECK(worst < 0.02);  // radians
        const double exact = 4.0 / 3.0 * std::numbers::pi * 8.0;
        CHECK(ks::signed_volume(s) == doctest::Approx(exact).epsilon(0.01));
        CHECK(ks::signed_volume(s) < exact);  // inscribed polyhedron
    }
    SUBCASE("isolated and degenerate") {
        IndexedMesh m = fixtures::tetrahedron();
        m.vertices.push_back(Vec3(9, 9, 9));                                  // isolated
        m.vertices.push_back(Vec3(2, 0, 0));                                  // collinear with 0, 1
        m.faces.push_back({0, 1, 5});
        const auto vn = ks::vertex_normals(m);
        CHECK(vn[4] == Vec3::Zero());
        CHECK(ks::face_normal(m, 4) == Vec3::Zero());
        CHECK(ks::face_areas(m)[4] == 0.0);
    }
}

TEST_CASE("geometry: bounding box") {
    const IndexedMesh m = fixtures::cube(Vec3(1, 2, 3));
    const ks::BoundingBox b = ks::bounding_box(m.vertices);
    CHECK(b.min == Vec3(1, 2, 3));
    CHECK(b.max == Vec3(2, 3, 4));
    CHECK(b.diagonal() == doctest::Approx(std::sqrt(3.0)));
    CHECK(ks::bounding_box({}).empty());
}

TEST_CASE("geometry: bad input") {
    IndexedMesh m = fixtures::tetrahedron();
    m.faces.push_back({0, 1, 42});
    CHECK_THROWS_WITH_AS(ks::face_normals(m), doctest::Contains("face 4 uses vertex 42"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::vertex_normals(m), doctest::Contains("kintsugi::vertex_normals"), ks::invalid_input);
    CHECK_THROWS_AS((void)ks::face_areas(m), ks::invalid_input);
    CHECK_THROWS_AS((void)ks::signed_volume(m), ks::invalid_input);
    CHECK_THROWS_AS((void)ks::mean_edge_length(m), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::face_normal(m, 17), doctest::Contains("face 17 out of range"), ks::invalid_input);
}
