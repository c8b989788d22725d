// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// denoise_metrics: closed-form normal angles and vertex RMS, connectivity checks,
// and the noise levels stated for the Guided Mesh Normal Filtering data.
#include "test_data.hpp"
#include <doctest/doctest.h>

#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/metrics/denoise.hpp>

#include "metrics/mesh_fixtures.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <limits>
#include <numbers>

namespace ks = kintsugi;
using fixtures::EigenHolder;
using fixtures::IndexedHolder;
using fixtures::SurfaceMeshHolder;
using ks::IndexedMesh;
using ks::Vec3;

TEST_CASE_TEMPLATE("denoise_metrics: rigid rotation of a grid", H, IndexedHolder, EigenHolder, SurfaceMeshHolder) {
    const IndexedMesh truth = fixtures::grid(8, 5);
    SUBCASE("identical meshes") {
        H a(truth), b(truth);
        const auto m = ks::denoise_metrics(a.mesh(), b.mesh());
        CHECK(m.mean_normal_angle_deg == 0.0);
        CHECK(m.max_normal_angle_deg == 0.0);
        CHECK(m.vertex_rms == 0.0);
    }
    SUBCASE("rotated by 7 degrees about the x axis") {
        const double alpha = 7.0 * std::numbers::pi / 180;
        const Eigen::Matrix3d R = Eigen::AngleAxisd(alpha, Vec3::UnitX()).toRotationMatrix();
        IndexedMesh rotated = truth;
        double sum2 = 0;
        for (auto& v : rotated.vertices) {
            // |Rp - p| = 2 sin(alpha/2) * distance to the axis (= y here)
            sum2 += std::pow(2 * std::sin(alpha / 2) * v.y(), 2);
            v = R * v;
        }
        H a(rotated), b(truth);
        const auto m = ks::denoise_metrics(a.mesh(), b.mesh());
        CHECK(m.mean_normal_angle_deg == doctest::Approx(7.0).epsilon(1e-9));
        CHECK(m.max_normal_angle_deg == doctest::Approx(7.0).epsilon(1e-9));
        CHECK(m.vertex_rms == doctest::Approx(std::sqrt(sum2 / static_cast<double>(truth.vertices.size()))));
    }
}

TEST_CASE("denoise_metrics: one vertex moved") {
    const IndexedMesh truth = fixtures::grid(4, 4);
    IndexedMesh moved = truth;
    const std::size_t v = 12;  // interior vertex (2, 2): 6 incident faces
    moved.vertices[v].z() = 0.5;
    const auto m = ks::denoise_metrics(moved, truth);
    CHECK(m.vertex_rms == doctest::Approx(0.5 / std::sqrt(25.0)));
    // the 6 faces around vertex 12 tilt; the other 26 faces are unchanged
    double sum = 0, mx = 0;
    const auto nm = ks::face_normals(moved), nt = ks::face_normals(truth);
    for (std::size_t f = 0; f < nm.size(); ++f) {
        const double a = std::acos(std::clamp(nm[f].dot(nt[f]), -1.0, 1.0)) * 180 / std::numbers::pi;
        sum += a;
        mx = std::max(mx, a);
    }
    CHECK(mx > 20.0);  // atan(0.5 / 1) at the steepest face ~ 26.6 degrees
    CHECK(m.max_normal_angle_deg == doctest::Approx(mx).epsilon(1e-9));
    CHECK(m.mean_normal_angle_deg == doctest::Approx(sum / 32).epsilon(1e-9));
}

TEST_CASE("denoise_metrics: flipped orientation is 180 degrees, faces collapsed in the result 90") {
    IndexedMesh truth = fixtures::grid(2, 1);
    IndexedMesh flipped = truth;
    for (auto& v : flipped.vertices) v.z() = -v.z();
    for (auto& v : flipped.vertices) v.x() = 2 - v.x();  // mirror: every normal flips
    const auto m = ks::denoise_metrics(flipped, truth);
    CHECK(m.mean_normal_angle_deg == doctest::Approx(180.0));
    // a face degenerate in the result counts as 90 degrees (vertex 4 moved onto vertex 1:
    // faces (0,1,4) and (1,5,4) collapse, the other two keep their +z normal)
    IndexedMesh collapsed = truth;
    collapsed.vertices[4] = collapsed.vertices[1];
    const auto c = ks::denoise_metrics(collapsed, truth);
    CHECK(c.degenerate_result_faces == 2);
    CHECK(c.mean_normal_angle_deg == doctest::Approx(45.0));
    CHECK(c.max_normal_angle_deg == 90.0);
    CHECK(c.vertex_rms == doctest::Approx(1.0 / std::sqrt(6.0)));
    // a result collapsed to one point cannot score well; faces degenerate in the truth are
    // left out (both meshes collapsed: nothing compared)
    IndexedMesh point = truth;
    for (auto& v : point.vertices) v = ks::Vec3(0.5, 0.5, 0);
    const auto p = ks::denoise_metrics(point, truth);
    CHECK(p.degenerate_result_faces == truth.faces.size());
    CHECK(p.mean_normal_angle_deg == 90.0);
    const auto both = ks::denoise_metrics(point, point);
    CHECK(both.degenerate_result_faces == 0);
    CHECK(both.mean_normal_angle_deg == 0.0);
}

TEST_CASE("denoise_metrics: bad input") {
    const IndexedMesh truth = fixtures::grid(3, 3);
    SUBCASE("different sizes") {
        CHECK_THROWS_WITH_AS((void)ks::denoise_metrics(fixtures::grid(3, 2), truth),
                             doctest::Contains("same connectivity"), ks::invalid_input);
    }
    SUBCASE("different faces") {
        IndexedMesh other = truth;
        std::swap(other.faces[4][1], other.faces[4][2]);
        CHECK_THROWS_WITH_AS((void)ks::denoise_metrics(other, truth), doctest::Contains("face 4 differs"),
                             ks::invalid_input);
    }
    SUBCASE("empty") {
        CHECK_THROWS_WITH_AS((void)ks::denoise_metrics(IndexedMesh{}, IndexedMesh{}), doctest::Contains("empty"),
                             ks::invalid_input);
    }
    SUBCASE("NaN") {
        IndexedMesh bad = truth;
        bad.vertices[5].x() = std::numeric_limits<double>::quiet_NaN();
        CHECK_THROWS_WITH_AS((void)ks::denoise_metrics(bad, truth), doctest::Contains("vertex 5"), ks::invalid_input);
    }
    SUBCASE("index out of range") {
        IndexedMesh bad = truth;
        bad.faces[0][0] = 99;
        IndexedMesh bad2 = bad;
        CHECK_THROWS_WITH_AS((void)ks::denoise_metrics(bad, bad2), doctest::Contains("uses vertex 99"),
                             ks::invalid_input);
    }
}

TEST_CASE("denoise_metrics: Guided Mesh Normal Filtering noisy/original pairs (real data)") {
    // ../shared/data/README.md: "RMS vertex displacement about <noise level> x the mean
    // edge length" for Block0.4 (0.40) and SharpSphere0.3 (0.30).
    // Every input is checked before any CHECK runs, so a missing file can never turn a
    // failure into a skip.
    for (const char* dir : {"Block0.4", "SharpSphere0.3"})
        for (const char* file : {"/Original.obj", "/Noisy.obj"})
            KINTSUGI_REQUIRE_DATA(fixtures::shared_data(std::string("guided_denoising/") + dir + file));
    for (const auto& [dir, level] : {std::pair{"Block0.4", 0.40}, std::pair{"SharpSphere0.3", 0.30}}) {
        const auto orig = fixtures::shared_data(std::string("guided_denoising/") + dir + "/Original.obj");
        const auto noisy = fixtures::shared_data(std::string("guided_denoising/") + dir + "/Noisy.obj");
        IndexedMesh t = fixtures::load(orig), n = fixtures::load(noisy);
        t.normals.clear();
        n.normals.clear();
        const auto m = ks::denoise_metrics(n, t);
        const double edge = ks::mean_edge_length(t);
        MESSAGE(std::string(dir) << ": vertex RMS " << m.vertex_rms << " = " << m.vertex_rms / edge << " x mean edge; mean normal angle "
                    << m.mean_normal_angle_deg << " deg, max " << m.max_normal_angle_deg);
        CHECK(m.vertex_rms / edge == doctest::Approx(level).epsilon(0.1).scale(0));
        CHECK(m.mean_normal_angle_deg > 5.0);  // that much noise tilts faces by many degrees
        CHECK(m.max_normal_angle_deg <= 180.0);
    }
}
