// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Octree RBF (Miura, Sone, Masuda; Carr et al. 2001), the meshes: closed surfaces near
// analytic and real shapes, sharp edges, containers, cancellation (the field:
// test_rbf_field.cpp).
#include "test_data.hpp"
#include <doctest/doctest.h>

#include "rbf/rbf_test_support.hpp"
#include "reconstruct/pu_test_data.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/projection.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/metrics/distance.hpp>
#include <kintsugi/metrics/topology_report.hpp>
#include <kintsugi/rbf/rbf_octree.hpp>
#include <kintsugi/spatial/triangle_index.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <random>
#include <stop_token>
#include <string>
#include <vector>

namespace ks = kintsugi;
using ks::rbf_test::V;
using ks::rbf_test::diagonal;
using ks::rbf_test::sphere_points;

namespace {

using Epick = CGAL::Exact_predicates_inexact_constructions_kernel;
/// A user struct with float coordinates, read through projections.
struct Sample {
    float xyz[3];
    float normal[3];
};

/// One closed, manifold, connected surface.
void check_closed_surface(const ks::IndexedMesh& m) {
    const auto t = ks::topology_report(m);
    CHECK(t.closed);
    CHECK(t.manifold);
    CHECK(t.components == 1);
}

/// A closed star prism: `spikes` spikes of outer radius 1 and inner radius `inner` in the
/// xy-plane, extruded over z in [-h, h]: acute convex edges at the tips, concave creases
/// between them, right-angled edges at top and bottom. Outward faces.
ks::IndexedMesh star_prism(int spikes, double inner, double h) {
    ks::IndexedMesh m;
    const int n = 2 * spikes;
    for (const double z : {-h, h}) {
        for (int i = 0; i < n; ++i) {
            const double a = M_PI * i / spikes, r = i % 2 == 0 ? 1.0 : inner;
            m.vertices.emplace_back(r * std::cos(a), r * std::sin(a), z);
        }
        m.vertices.emplace_back(0, 0, z);
    }
    const auto N = static_cast<ks::Index>(n);
    const ks::Index bc = N, top = N + 1, tc = 2 * N + 1;
    for (ks::Index a = 0; a < N; ++a) {
        const ks::Index b = (a + 1) % N;
        m.faces.push_back({bc, b, a});
        m.faces.push_back({tc, top + a, top + b});
        m.faces.push_back({a, b, top + b});
        m.faces.push_back({a, top + b, top + a});
    }
    return m;
}

/// Whether x lies inside star_prism(spikes, inner, h) (crossings of the star polygon).
bool inside_star_prism(const ks::Vec3& x, int spikes, double inner, double h) {
    if (std::abs(x.z()) > h) return false;
    bool in = false;
    const int n = 2 * spikes;
    for (int i = 0; i < n; ++i) {
        const double a0 = M_PI * i / spikes, a1 = M_PI * (i + 1) / spikes;
        const double r0 = i % 2 == 0 ? 1.0 : inner, r1 = (i + 1) % 2 == 0 ? 1.0 : inner;
        const double x0 = r0 * std::cos(a0), y0 = r0 * std::sin(a0), x1 = r1 * std::cos(a1), y1 = r1 * std::sin(a1);
        if ((y0 > x.y()) != (y1 > x.y()) && x.x() < x0 + (x.y() - y0) / (y1 - y0) * (x1 - x0)) in = !in;
    }
    return in;
}

}  // namespace

TEST_CASE("reconstruct_rbf_octree: sphere and torus -> closed meshes near the exact surface") {
    {
        V pts, nrm;
        sphere_points(20000, 4, pts, nrm, ks::Vec3::Zero(), 1.0);
        const auto r = ks::reconstruct_rbf_octree(ks::with_normals(pts, nrm), {.resolution = 96});
        REQUIRE(r.status == ks::Status::ok);
        const auto t = ks::topology_report(r.mesh);
        CHECK(t.closed);
        CHECK(t.manifold);
        CHECK(t.components == 1);
        CHECK(t.genus == 0);
        CHECK(ks::signed_volume(r.mesh) > 0);
        double worst = 0;
        for (const auto& v : r.mesh.vertices) worst = std::max(worst, std::abs(v.norm() - 1));
        CHECK(worst <= 1e-3);
        CHECK(r.timings.size() == 4);
        CHECK(r.isosurface.faces == r.mesh.faces.size());
    }
    {
        // Torus R = 1, r = 0.4 (axis z), area-uniform samples.
        V pts, nrm;
        std::mt19937_64 rng(5);
        std::uniform_real_distribution<double> u(0, 1);
        while (pts.size() < 30000) {
            const double th = 2 * M_PI * u(rng), ph = 2 * M_PI * u(rng);
            if (u(rng) * 1.4 > 1.0 + 0.4 * std::cos(ph)) continue;
            const ks::Vec3 c(std::cos(th), std::sin(th), 0);
            const ks::Vec3 n = std::cos(ph) * c + std::sin(ph) * ks::Vec3(0, 0, 1);
            pts.push_back(c + 0.4 * n);
            nrm.push_back(n);
        }
        const auto r = ks::reconstruct_rbf_octree(ks::with_normals(pts, nrm), {.resolution = 128});
        REQUIRE(r.status == ks::Status::ok);
        const auto t = ks::topology_report(r.mesh);
        CHECK(t.closed);
        CHECK(t.components == 1);
        CHECK(t.genus == 1);
        double worst = 0;
        for (const auto& v : r.mesh.vertices)
            worst = std::max(worst, std::abs(std::hypot(std::hypot(v.x(), v.y()) - 1.0, v.z()) - 0.4));
        CHECK(worst <= 1e-3);
    }
}

TEST_CASE("reconstruct_rbf_octree: sharp edges — a star prism with exact normals -> one closed surface near it") {
    // Acute tips, concave creases, right-angled rims; 20,000 points sampled with the face
    // normals. Before the side_of sign and the crease offsets: 2 dead cells signed by a
    // tip point's normal lay inside out, and the mesh was open (a sheet off a tip to the
    // grid's border, a vertex 0.155 from the prism, mean 9.5e-4).
    const int spikes = 5;
    const double inner = 0.5, h = 0.3;
    const ks::IndexedMesh truth = star_prism(spikes, inner, h);
    REQUIRE(ks::signed_volume(truth) > 0);
    V nrm;
    const V pts = kintsugi_test::sample_mesh(truth, 20000, 7, &nrm);
    const auto fit = ks::RBFOctreeField::build(ks::with_normals(pts, nrm));
    REQUIRE(fit.status == ks::Status::ok);
    CHECK(fit.stats.crease_offsets > 0);
    CHECK(fit.stats.crease_offsets <= 2 * fit.stats.points);
    std::size_t dead = 0, wrong = 0;
    for (const auto& c : fit.field.cells()) {
        if (c.live) continue;
        ++dead;
        const ks::Vec3 x = c.min + ks::Vec3::Constant(c.side / 2);
        if ((fit.field(x) < 0) != inside_star_prism(x, spikes, inner, h)) ++wrong;
    }
    CHECK(dead > 100);
    CHECK(wrong == 0);

    const auto r = ks::reconstruct_rbf_octree(ks::with_normals(pts, nrm), {.resolution = 128});
    REQUIRE(r.status == ks::Status::ok);
    check_closed_surface(r.mesh);
    CHECK(ks::topology_report(r.mesh).genus == 0);
    const ks::TriangleIndex index(truth);
    double mean = 0, worst = 0;
    for (const auto& c : index.closest_points(r.mesh.vertices, [](double) {})) {
        mean += c.distance;
        worst = std::max(worst, c.distance);
    }
    mean /= static_cast<double>(r.mesh.vertices.size());
    MESSAGE("star prism: mesh to truth mean " << mean << ", max " << worst << " (diagonal 2.7)");
    CHECK(mean <= 7e-4);
    CHECK(worst <= 0.04);
}

TEST_CASE("reconstruct_rbf_octree: real mesh shipped — tests/data/bunny.off sampled with normals") {
    ks::IndexedMesh ref;
    ks::read_mesh(ks::test::test_data("bunny.off").string(), ref);
    V nrm;
    const V pts = kintsugi_test::sample_mesh(ref, 40000, 7, &nrm);
    const auto r = ks::reconstruct_rbf_octree(ks::with_normals(pts, nrm), {.resolution = 128});
    REQUIRE(r.status == ks::Status::ok);
    check_closed_surface(r.mesh);
    const auto d = ks::compare(r.mesh, ref, {.samples = 100000});
    const auto ab = d.relative(d.a_to_b), ba = d.relative(d.b_to_a);
    MESSAGE("bunny.off 40K samples: live " << r.stats.live_cells << "/" << r.stats.cells << ", mean "
                                           << ab.mean * 100 << " % / " << ba.mean * 100 << " % diag, Hausdorff "
                                           << ab.hausdorff * 100 << " %");
    CHECK(ba.mean <= 0.0005);
    CHECK(ab.mean <= 0.0005);
    CHECK(ab.hausdorff <= 0.01);
}

TEST_CASE("reconstruct_rbf_octree: real data — the Stanford bunny points -> one closed mesh within 0.05 % diag") {
    const auto file = ks::test::shared_data("stanford_bunny/reconstruction/bun_zipper_points_normals.xyz");
    const auto ref_file = ks::test::shared_data("stanford_bunny/reconstruction/bun_zipper.ply");
    KINTSUGI_REQUIRE_DATA(file);
    KINTSUGI_REQUIRE_DATA(ref_file);
    const ks::PointCloud cloud = ks::read_point_cloud(file);
    REQUIRE(cloud.points.size() == 34834);
    REQUIRE(cloud.normals.size() == 34834);
    const ks::IndexedMesh ref = ks::read_mesh(ref_file);
    const auto r = ks::reconstruct_rbf_octree(cloud, {.resolution = 160});
    REQUIRE(r.status == ks::Status::ok);
    check_closed_surface(r.mesh);
    const auto d = ks::compare(r.mesh, ref, {.samples = 200000});
    const auto ba = d.relative(d.b_to_a);
    MESSAGE("bunny 34.8K: " << r.stats.cells << " cells, " << r.stats.live_cells << " live, max "
                            << r.stats.max_points_per_cell << " mean " << r.stats.mean_points_per_cell
                            << " per cell, ill " << r.stats.ill_conditioned_cells << "; reference to mesh mean "
                            << ba.mean * 100 << " % diag, Hausdorff " << ba.hausdorff * 100 << " %; "
                            << r.isosurface.lattice_evaluations << " lattice + " << r.isosurface.root_evaluations << " root evaluations, " << r.mesh.faces.size() << " faces");
    for (const auto& s : r.timings) MESSAGE(s.stage << " " << s.seconds << " s");
    CHECK(ba.mean <= 0.0005);
}

TEST_CASE_TEMPLATE("reconstruct_rbf_octree: any container gives the same mesh", Container, V,
                   CGAL::Point_set_3<Epick::Point_3, Epick::Vector_3>, std::vector<Sample>) {
    V pts, nrm;
    sphere_points(3000, 6, pts, nrm);
    const ks::RBFOctreeParams prm{.n_max = 80, .resolution = 48};
    const auto ref = ks::reconstruct_rbf_octree(ks::with_normals(pts, nrm), prm);
    REQUIRE(ref.status == ks::Status::ok);
    Container c;
    ks::IndexedMesh out;
    ks::RBFReconstructResult r;
    if constexpr (std::is_same_v<Container, V>) {
        // Eigen vectors in, CGAL::Surface_mesh out.
        c = pts;
        CGAL::Surface_mesh<Epick::Point_3> sm;
        r = ks::reconstruct_rbf_octree(ks::with_normals(c, nrm), sm, prm);
        REQUIRE(r.status == ks::Status::ok);
        CHECK(sm.number_of_faces() == ref.mesh.faces.size());
        CHECK(sm.number_of_vertices() == ref.mesh.vertices.size());
    } else if constexpr (std::is_same_v<Container, std::vector<Sample>>) {
        for (std::size_t i = 0; i < pts.size(); ++i)
            c.push_back(Sample{{float(pts[i].x()), float(pts[i].y()), float(pts[i].z())},
                               {float(nrm[i].x()), float(nrm[i].y()), float(nrm[i].z())}});
        r = ks::reconstruct_rbf_octree(ks::project_points(c, &Sample::xyz, &Sample::normal), out, prm);
        REQUIRE(r.status == ks::Status::ok);
        // float input: the same sphere within float rounding, the same topology.
        const auto t = ks::topology_report(out);
        CHECK(t.closed);
        CHECK(t.genus == 0);
        for (const auto& v : out.vertices) CHECK(std::abs((v - ks::Vec3(0.2, -0.1, 0.3)).norm() - 1) < 1e-2);
    } else {
        c.add_normal_map();
        for (std::size_t i = 0; i < pts.size(); ++i)
            c.insert(Epick::Point_3(pts[i].x(), pts[i].y(), pts[i].z()),
                     Epick::Vector_3(nrm[i].x(), nrm[i].y(), nrm[i].z()));
        r = ks::reconstruct_rbf_octree(c, out, prm);
        REQUIRE(r.status == ks::Status::ok);
        CHECK(out.faces == ref.mesh.faces);
        CHECK(out.vertices == ref.mesh.vertices);
    }
}

TEST_CASE("reconstruct_rbf_octree: cancellation at every stage leaves the output untouched") {
    V pts, nrm;
    sphere_points(4000, 12, pts, nrm);
    for (const char* stage : {"rbf_offsets", "rbf_octree", "rbf_solve", "rbf_polygonise"}) {
        CAPTURE(stage);
        ks::RBFOctreeParams prm{.n_max = 50, .resolution = 40};
        bool seen = false;
        prm.control.progress = [&](const ks::ProgressEvent& e) {
            seen = seen || e.stage == stage;
            return !seen;
        };
        ks::IndexedMesh out;
        out.vertices.push_back(ks::Vec3(1, 2, 3));
        const auto r = ks::reconstruct_rbf_octree(ks::with_normals(pts, nrm), out, prm);
        CHECK(seen);
        CHECK(r.status == ks::Status::cancelled);
        CHECK(out.vertices.size() == 1);
        CHECK(out.faces.empty());
    }
    // A stop requested on the token in the middle of the solves.
    std::stop_source stopper;
    ks::RBFOctreeParams mid{.n_max = 50};
    mid.control = {.progress = [&stopper](const ks::ProgressEvent& e) {
                       if (e.stage == std::string_view("rbf_solve") && e.fraction > 0.5) stopper.request_stop();
                       return true;
                   },
                   .stop = stopper.get_token()};
    const auto stopped = ks::RBFOctreeField::build(ks::with_normals(pts, nrm), mid);
    CHECK(stopper.stop_requested());
    CHECK(stopped.status == ks::Status::cancelled);
    CHECK(stopped.field.empty());
    CHECK(std::isnan(stopped.field(pts[0])));
    // Progress never goes back, ends at 1, and is reported a bounded number of times.
    std::vector<double> seen_fractions;
    ks::RBFOctreeParams ok{.n_max = 50, .resolution = 40};
    ok.control.progress = [&seen_fractions](const ks::ProgressEvent& e) {
        seen_fractions.push_back(e.fraction);
        return true;
    };
    CHECK(ks::reconstruct_rbf_octree(ks::with_normals(pts, nrm), ok).status == ks::Status::ok);
    CHECK(std::is_sorted(seen_fractions.begin(), seen_fractions.end()));
    CHECK(seen_fractions.back() == 1.0);
    CHECK(seen_fractions.size() <= 220);
}
