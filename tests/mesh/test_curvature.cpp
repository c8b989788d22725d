// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Principal curvatures from jet fits (mesh/curvature.hpp, spatial/jet_fit.hpp)
// against the analytic sphere and torus, on point sets and meshes.
#include <doctest/doctest.h>

#include "analytic_shapes.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/mesh/curvature.hpp>
#include <kintsugi/spatial/jet_fit.hpp>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <stop_token>
#include <vector>

namespace ks = kintsugi;
using kintsugi_test::Sphere;
using kintsugi_test::Torus;
using ks::Scalar;
using ks::Vec3;
using SurfaceMesh = CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3>;

namespace {

/// Errors of a curvature estimate against the truth: each principal curvature's error
/// relative to the largest absolute principal curvature at that point (the local
/// curvature scale; k2 vanishes on the torus's top and bottom circles), and the angle
/// error (sine) of d1 where the truth has distinct curvatures.
struct Errors {
    Scalar mean = 0, p99 = 0, max = 0, dir_mean = 0, dir_max = 0;
    std::size_t invalid = 0;
};

template <class Shape>
Errors compare(const Shape& shape, const std::vector<Vec3>& pts, const std::vector<ks::PrincipalCurvature>& c,
               bool check_sign = true) {
    REQUIRE(c.size() == pts.size());
    std::vector<Scalar> err;
    std::vector<Scalar> dir;
    Errors e;
    for (std::size_t i = 0; i < pts.size(); ++i) {
        if (!c[i].valid) {
            ++e.invalid;
            continue;
        }
        const auto t = shape.curvature(pts[i]);
        Scalar k1 = c[i].k1, k2 = c[i].k2;
        Vec3 d1 = c[i].d1;
        if (!check_sign && c[i].normal.dot(t.normal) < 0) {  // unoriented input: compare along the true normal
            k1 = -c[i].k2;
            k2 = -c[i].k1;
            d1 = c[i].d2;
        }
        const Scalar scale = std::max(std::abs(t.k1), std::abs(t.k2));
        err.push_back(std::max(std::abs(k1 - t.k1), std::abs(k2 - t.k2)) / scale);
        if (t.d1.squaredNorm() > 0) dir.push_back(d1.cross(t.d1).norm());
    }
    std::sort(err.begin(), err.end());
    for (Scalar x : err) e.mean += x / Scalar(err.size());
    e.p99 = err[err.size() * 99 / 100];
    e.max = err.back();
    for (Scalar x : dir) {
        e.dir_mean += x / Scalar(dir.size());
        e.dir_max = std::max(e.dir_max, x);
    }
    return e;
}

}  // namespace

TEST_CASE("fit_jet: exact quadric, degree 2 to 4, and orientation") {
    // z = (a x^2 + b y^2) / 2 around the origin: with the normal +z the surface bends
    // towards the normal, so the curvatures are (-b, -a) for a > b; seen from -z, (a, b).
    const Scalar a = 2.0, b = 0.5;
    std::vector<Vec3> pts{Vec3::Zero()};
    for (int i = -3; i <= 3; ++i)
        for (int j = -3; j <= 3; ++j)
            if (i || j) {
                const Scalar x = 0.01 * i + 0.001 * j, y = 0.012 * j;
                pts.emplace_back(x, y, (a * x * x + b * y * y) / 2);
            }
    for (int degree : {2, 3, 4}) {
        CAPTURE(degree);
        ks::JetFit j = ks::fit_jet(pts, {.degree = degree});
        REQUIRE(j.valid);
        ks::orient_jet(j, Vec3(0, 0, 1));
        CHECK(j.normal.z() == doctest::Approx(1).epsilon(1e-9));
        CHECK(j.k1 == doctest::Approx(-b).epsilon(1e-6));
        CHECK(j.k2 == doctest::Approx(-a).epsilon(1e-6));
        CHECK(std::abs(j.d2.x()) == doctest::Approx(1).epsilon(1e-6));  // the stronger bend is along x
        CHECK(std::abs(j.d1.y()) == doctest::Approx(1).epsilon(1e-6));
        ks::orient_jet(j, Vec3(0, 0, -1));  // seen from below: the bowl is convex
        CHECK(j.k1 == doctest::Approx(a).epsilon(1e-6));
        CHECK(j.k2 == doctest::Approx(b).epsilon(1e-6));
        CHECK(j.mean_curvature() == doctest::Approx((a + b) / 2).epsilon(1e-6));
        CHECK(j.gaussian_curvature() == doctest::Approx(a * b).epsilon(1e-6));
    }
    // Too few points, bad degree, coincident points: not valid.
    CHECK_FALSE(ks::fit_jet(std::span<const Vec3>(pts.data(), 5)).valid);
    CHECK_FALSE(ks::fit_jet(std::span<const Vec3>(pts.data(), 12), {.degree = 4}).valid);
    CHECK_FALSE(ks::fit_jet(pts, {.degree = 5}).valid);
    const std::vector<Vec3> same(10, Vec3(1, 2, 3));
    CHECK_FALSE(ks::fit_jet(same).valid);
}

TEST_CASE_TEMPLATE("point-set curvature on a sphere and a torus is within 2 % of the analytic values", Kind,
                   ks::PointCloud, std::vector<Eigen::Vector3d>) {
    const Sphere sphere{1.0};
    const Torus torus{1.0, 0.4};
    auto run = [&](const auto& shape, const ks::PointCloud& cloud, const std::string& name) {
        ks::CurvatureResult r;
        bool oriented = true;
        if constexpr (std::is_same_v<Kind, ks::PointCloud>) {
            r = ks::estimate_curvatures(cloud);
        } else {
            std::vector<Eigen::Vector3d> v(cloud.points.begin(), cloud.points.end());  // no normals
            r = ks::estimate_curvatures(v);
            oriented = false;
        }
        REQUIRE(r.status == ks::Status::ok);
        const Errors e = compare(shape, cloud.points, r.curvatures, oriented);
        MESSAGE(name << " (" << cloud.points.size() << " points, k 30, degree 4): curvature error mean "
                     << 100 * e.mean << " %, p99 " << 100 * e.p99 << " %, max " << 100 * e.max
                     << " %; d1 angle mean " << e.dir_mean << ", max " << e.dir_max << " rad; invalid " << e.invalid);
        CHECK(e.invalid == 0);
        CHECK(e.max < 0.02);     // the acceptance bound
        CHECK(e.mean < 0.002);   // measured 0.001-0.035 %
        if (e.dir_max > 0) CHECK(e.dir_max < 0.02);
    };
    run(sphere, sphere.sample(20000, 1), "sphere");
    run(torus, torus.sample(20000, 2), "torus");
}

TEST_CASE_TEMPLATE("mesh curvature on a sphere and a torus is within 2 % of the analytic values", Kind, ks::IndexedMesh,
                   ks::EigenMeshView<const Eigen::MatrixXd, Eigen::MatrixXi>, SurfaceMesh) {
    const Sphere sphere{2.0};
    const Torus torus{1.0, 0.4};
    auto run = [&](const auto& shape, const ks::IndexedMesh& m, const std::string& name) {
        ks::CurvatureResult r;
        if constexpr (std::is_same_v<Kind, ks::IndexedMesh>) {
            r = ks::estimate_curvatures(m);
        } else if constexpr (std::is_same_v<Kind, SurfaceMesh>) {
            SurfaceMesh sm;
            for (const Vec3& p : m.vertices) ks::mesh_traits<SurfaceMesh>::add_vertex(sm, p);
            for (const ks::Face& f : m.faces) ks::mesh_traits<SurfaceMesh>::add_face(sm, f);
            REQUIRE(sm.number_of_vertices() == m.vertices.size());
            REQUIRE(sm.number_of_faces() == m.faces.size());
            r = ks::estimate_curvatures(sm);
        } else {
            Eigen::MatrixXd V(m.vertices.size(), 3);
            Eigen::MatrixXi F(m.faces.size(), 3);
            for (std::size_t i = 0; i < m.vertices.size(); ++i) V.row(Eigen::Index(i)) = m.vertices[i].transpose();
            for (std::size_t f = 0; f < m.faces.size(); ++f)
                for (int c = 0; c < 3; ++c) F(Eigen::Index(f), c) = int(m.faces[f][c]);
            const Eigen::MatrixXd& cV = V;
            r = ks::estimate_curvatures(ks::eigen_mesh(cV, F));
        }
        REQUIRE(r.status == ks::Status::ok);
        const Errors e = compare(shape, m.vertices, r.curvatures);
        MESSAGE(name << " mesh (" << m.vertices.size() << " vertices, k 30, degree 4): curvature error mean "
                     << 100 * e.mean << " %, p99 " << 100 * e.p99 << " %, max " << 100 * e.max
                     << " %; d1 angle mean " << e.dir_mean << ", max " << e.dir_max << " rad");
        CHECK(e.invalid == 0);
        CHECK(e.max < 0.02);     // the acceptance bound
        CHECK(e.mean < 0.002);   // measured 0.001-0.035 %
        if (e.dir_max > 0) CHECK(e.dir_max < 0.02);
        // Normals follow the outward vertex normals.
        for (std::size_t i = 0; i < m.vertices.size(); i += 97)
            CHECK(r.curvatures[i].normal.dot(shape.curvature(m.vertices[i]).normal) > 0.999);
    };
    run(sphere, sphere.mesh(5), "sphere");
    run(torus, torus.mesh(240, 96), "torus");
}

TEST_CASE_TEMPLATE("curvature at points off the samples (fit_jet_at) is within 2 % on the torus", Kind, ks::PointCloud,
                   std::vector<Eigen::Vector3d>) {
    const Torus torus{1.0, 0.4};
    const ks::PointCloud cloud = torus.sample(20000, 6);
    // Queries: 2,000 other surface points, pushed off the surface by up to 0.5 % of r.
    ks::PointCloud other = torus.sample(2000, 7);
    std::vector<Vec3> queries;
    for (std::size_t i = 0; i < other.points.size(); ++i)
        queries.push_back(other.points[i] + other.normals[i] * (0.002 * ((i % 5) - 2.0) / 2));
    ks::CurvatureResult r;
    bool oriented = true;
    if constexpr (std::is_same_v<Kind, ks::PointCloud>) {
        r = ks::estimate_curvatures_at(cloud, queries);
    } else {
        std::vector<Eigen::Vector3d> v(cloud.points.begin(), cloud.points.end());
        r = ks::estimate_curvatures_at(v, queries);
        oriented = false;
    }
    REQUIRE(r.status == ks::Status::ok);
    const Errors e = compare(torus, other.points, r.curvatures, oriented);
    MESSAGE("torus, 2,000 off-sample queries (k 30, degree 4): curvature error mean " << 100 * e.mean << " %, max "
                                                                                     << 100 * e.max << " %; d1 angle max "
                                                                                     << e.dir_max << " rad");
    CHECK(e.invalid == 0);
    CHECK(e.max < 0.02);
    CHECK(e.dir_max < 0.02);
    // fit_jet_at on one neighbourhood gives the surface point above the query.
    std::vector<Vec3> nb;
    for (const auto& n : ks::KdTree(cloud.points).knn(queries[0], 30)) nb.push_back(cloud.points[n.index]);
    const ks::JetFit j = ks::fit_jet_at(queries[0], nb, {.degree = 4});
    REQUIRE(j.valid);
    CHECK(torus.distance(j.point) < 1e-5);
    CHECK_THROWS_WITH_AS((void)ks::estimate_curvatures_at(cloud, std::vector<Vec3>{Vec3(0, 0, NAN)}),
                         doctest::Contains("estimate_curvatures_at: query point 0 has a NaN"), ks::invalid_input);
}

TEST_CASE("curvature: bad input throws and names the fix") {
    const ks::PointCloud cloud = Sphere{}.sample(100, 3);
    CHECK_THROWS_WITH_AS((void)ks::estimate_curvatures(ks::PointCloud{}), doctest::Contains("is empty"),
                         ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)ks::estimate_curvatures(cloud, {.k = 9}), doctest::Contains("params.k = 9"),
                         ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)ks::estimate_curvatures(cloud, {.k = 101}), doctest::Contains("[15, 100]"),
                         ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)ks::estimate_curvatures(cloud, {.degree = 5}), doctest::Contains("pass 2, 3 or 4"),
                         ks::invalid_input);
    ks::PointCloud bad = cloud;
    bad.points[7].y() = std::numeric_limits<Scalar>::quiet_NaN();
    CHECK_THROWS_WITH_AS((void)ks::estimate_curvatures(bad), doctest::Contains("point 7 has a NaN"), ks::invalid_input);
    ks::IndexedMesh m = Sphere{}.mesh(2);
    CHECK_THROWS_WITH_AS((void)ks::estimate_curvatures(m, {.rings = 0}), doctest::Contains("rings is 0"),
                         ks::invalid_input);
    m.faces[3][1] = 100000;
    CHECK_THROWS_AS((void)ks::estimate_curvatures(m), ks::invalid_input);
    ks::IndexedMesh nan_mesh = Sphere{}.mesh(2);
    nan_mesh.vertices[5].x() = std::numeric_limits<Scalar>::infinity();
    CHECK_THROWS_WITH_AS((void)ks::estimate_curvatures(nan_mesh), doctest::Contains("vertex 5 has a NaN"),
                         ks::invalid_input);
}

TEST_CASE("curvature: cancellation returns cancelled and no curvatures") {
    const ks::PointCloud cloud = Torus{}.sample(20000, 4);
    std::stop_source stop;
    int calls = 0;
    ks::CurvatureParams p;
    p.control.progress = [&](const ks::ProgressEvent& e) {
        if (e.stage == "fit" && ++calls == 3) stop.request_stop();
        return true;
    };
    p.control.stop = stop.get_token();
    const auto r = ks::estimate_curvatures(cloud, p);
    CHECK(r.status == ks::Status::cancelled);
    CHECK(r.curvatures.empty());
    ks::CurvatureParams q;
    q.control.progress = [](const ks::ProgressEvent&) { return false; };
    const auto rm = ks::estimate_curvatures(Torus{}.mesh(60, 30), q);
    CHECK(rm.status == ks::Status::cancelled);
    CHECK(rm.curvatures.empty());
}

TEST_CASE("curvature is identical whatever the thread count") {
    const ks::PointCloud cloud = Torus{}.sample(5000, 5);
    const auto a = ks::estimate_curvatures(cloud);
    ks::CurvatureResult b;
    {
        ks::ThreadLimit one(1);
        b = ks::estimate_curvatures(cloud);
    }
    REQUIRE(a.curvatures.size() == b.curvatures.size());
    for (std::size_t i = 0; i < a.curvatures.size(); ++i) {
        CHECK(a.curvatures[i].k1 == b.curvatures[i].k1);
        CHECK(a.curvatures[i].d2 == b.curvatures[i].d2);
    }
}
