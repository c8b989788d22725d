// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Marching tetrahedra over a labelling: closed, outward, manifold, no degenerate
// triangles, for every configuration (including the ones that make other
// implementations non-manifold).
#include <doctest/doctest.h>

#include "closed_mesh.hpp"
#include "mesh/mt_test_util.hpp"

#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/mesh/marching_tetrahedra.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include <cmath>
#include <numbers>
#include <random>
#include <set>
#include <stop_token>

namespace ks = kintsugi;
using kintsugi_test::make_tet_grid;

namespace {

// Everything the output guarantee promises, checked with the metrics module's report
// plus two geometric checks it does not make (no zero-area face, no coincident vertices).
void check_guarantee(const ks::IndexedMesh& m, std::size_t components, long genus) {
    const auto r = kintsugi_test::check_closed_manifold(m);
    CHECK(r.non_manifold_edges == 0);
    CHECK(r.non_manifold_vertices == 0);
    CHECK(r.boundary_edges == 0);
    CHECK(r.isolated_vertices == 0);
    CHECK(r.components == components);
    if (genus >= 0) CHECK(r.genus == genus);
    for (double a : ks::face_areas(m)) REQUIRE(a > 0);
    std::set<std::array<double, 3>> seen;
    for (const auto& v : m.vertices) seen.insert({v.x(), v.y(), v.z()});
    CHECK(seen.size() == m.vertices.size());
    // Outward: the enclosed volume is positive (every component encloses inside vertices).
    CHECK(ks::signed_volume(m) > 0);
}

std::vector<std::uint8_t> label(const kintsugi_test::TetGrid& g, const std::vector<double>& f) {
    std::vector<std::uint8_t> in(g.vertices.size());
    for (std::size_t i = 0; i < f.size(); ++i) in[i] = f[i] > 0;
    return in;
}

}  // namespace

TEST_CASE("marching_tetrahedra: sphere is closed, genus 0, on the zero set") {
    const auto g = make_tet_grid(24, -1, 1);
    const double R = 0.63;
    std::vector<double> f;
    for (const auto& p : g.vertices) f.push_back(R - p.norm());
    const auto r = ks::marching_tetrahedra(g.vertices, g.tets, label(g, f), f);
    REQUIRE(r.status == ks::Status::ok);
    check_guarantee(r.mesh, 1, 0);
    CHECK(r.cap_faces == 0);
    CHECK(r.same_sign_vertices == 0);
    const double h = 2.0 / 24;
    double worst = 0;
    for (const auto& v : r.mesh.vertices) worst = std::max(worst, std::abs(v.norm() - R));
    CHECK(worst < 0.1 * h);  // linear interpolation of a distance along an edge
    CHECK(ks::signed_volume(r.mesh) == doctest::Approx(4.0 / 3.0 * std::numbers::pi * R * R * R).epsilon(0.03));
    REQUIRE(r.vertex_edges.size() == r.mesh.vertices.size());
    for (const auto& e : r.vertex_edges) {
        CHECK(f[e[0]] > 0);
        CHECK(f[e[1]] <= 0);
    }
}

TEST_CASE("marching_tetrahedra: torus has genus 1") {
    const auto g = make_tet_grid(30, -1, 1);
    std::vector<double> f;
    for (const auto& p : g.vertices) {
        const double q = std::hypot(p.x(), p.y()) - 0.55;
        f.push_back(0.22 - std::hypot(q, p.z()));
    }
    const auto r = ks::marching_tetrahedra(g.vertices, g.tets, label(g, f), f);
    check_guarantee(r.mesh, 1, 1);
}

TEST_CASE("marching_tetrahedra: inside vertices touching only diagonally stay separate manifolds") {
    const auto g = make_tet_grid(6, 0, 1);
    // (2,2,2) and (3,3,2) share a cube face diagonal that is not a tet edge in this
    // tetrahedralisation (their dual cells touch along an edge); (2,2,2) and (1,3,3)
    // touch only at a corner of their cells.
    std::vector<std::uint8_t> in(g.vertices.size(), 0);
    SUBCASE("edge-touching cells") {
        in[g.id(2, 2, 2)] = 1;
        in[g.id(3, 1, 2)] = 1;
        const auto r = ks::marching_tetrahedra(g.vertices, g.tets, in);
        check_guarantee(r.mesh, 2, 0);
    }
    SUBCASE("vertex-touching cells") {
        in[g.id(2, 2, 2)] = 1;
        in[g.id(1, 3, 3)] = 1;
        const auto r = ks::marching_tetrahedra(g.vertices, g.tets, in);
        check_guarantee(r.mesh, 2, 0);
    }
    SUBCASE("inside vertices joined by a tet edge form one component") {
        in[g.id(2, 2, 2)] = 1;
        in[g.id(3, 3, 3)] = 1;  // the Kuhn diagonal is an edge
        const auto r = ks::marching_tetrahedra(g.vertices, g.tets, in);
        check_guarantee(r.mesh, 1, 0);
    }
    SUBCASE("outside pocket inside an inside block (a cavity) is a second, inward-facing shell") {
        for (int k = 1; k <= 4; ++k)
            for (int j = 1; j <= 4; ++j)
                for (int i = 1; i <= 4; ++i) in[g.id(i, j, k)] = 1;
        in[g.id(2, 3, 2)] = 0;
        const auto r = ks::marching_tetrahedra(g.vertices, g.tets, in);
        const auto rep = ks::topology_report(r.mesh);
        CHECK(rep.closed);
        CHECK(rep.manifold);
        CHECK(rep.consistently_oriented);
        CHECK(rep.components == 2);
        CHECK(ks::signed_volume(r.mesh) > 0);
    }
}

TEST_CASE("marching_tetrahedra: inside vertices on the hull are capped") {
    const auto g = make_tet_grid(5, 0, 1);
    std::vector<std::uint8_t> in(g.vertices.size(), 0);
    SUBCASE("a corner") {
        in[g.id(0, 0, 0)] = 1;
        const auto r = ks::marching_tetrahedra(g.vertices, g.tets, in);
        CHECK(r.cap_faces > 0);
        check_guarantee(r.mesh, 1, 0);
    }
    SUBCASE("an edge of the box and a face point") {
        for (int i = 0; i <= 5; ++i) in[g.id(i, 0, 0)] = 1;
        in[g.id(2, 2, 5)] = 1;
        const auto r = ks::marching_tetrahedra(g.vertices, g.tets, in);
        check_guarantee(r.mesh, 2, 0);
    }
    SUBCASE("everything inside gives the box surface") {
        std::fill(in.begin(), in.end(), 1);
        const auto r = ks::marching_tetrahedra(g.vertices, g.tets, in);
        check_guarantee(r.mesh, 1, 0);
        CHECK(ks::signed_volume(r.mesh) == doctest::Approx(1.0));
        CHECK(r.mesh.faces.size() == 6 * 25 * 2);
    }
    SUBCASE("a slab through the box (a tunnel-free ring through opposite faces)") {
        for (int k = 0; k <= 5; ++k)
            for (int j = 0; j <= 5; ++j) in[g.id(2, j, k)] = 1;
        const auto r = ks::marching_tetrahedra(g.vertices, g.tets, in);
        check_guarantee(r.mesh, 1, 0);
    }
}

TEST_CASE("marching_tetrahedra: random labellings are always closed oriented manifolds") {
    const auto g = make_tet_grid(7, 0, 1);
    std::mt19937 rng(99);
    for (int trial = 0; trial < 40; ++trial) {
        std::vector<std::uint8_t> in(g.vertices.size());
        const double p = 0.1 + 0.8 * (trial % 9) / 8.0;
        std::uniform_real_distribution<double> u(0, 1);
        std::vector<double> f(g.vertices.size());
        for (std::size_t i = 0; i < in.size(); ++i) {
            in[i] = u(rng) < p;
            f[i] = u(rng) - 0.5;  // sign independent of the label: both placement rules used
        }
        CAPTURE(trial);
        const auto r = ks::marching_tetrahedra(g.vertices, g.tets, in, f);
        if (r.mesh.faces.empty()) continue;
        const auto rep = ks::topology_report(r.mesh);
        CHECK(rep.closed);
        CHECK(rep.manifold);
        CHECK(rep.consistently_oriented);
        CHECK(rep.degenerate_faces == 0);
        CHECK(rep.non_manifold_vertices == 0);
        CHECK(ks::signed_volume(r.mesh) > 0);
        CHECK(r.same_sign_vertices > 0);
    }
}

TEST_CASE("marching_tetrahedra: tet orientation does not matter") {
    auto g = make_tet_grid(8, -1, 1);
    std::vector<double> f;
    for (const auto& p : g.vertices) f.push_back(0.5 - p.norm());
    const auto ref = ks::marching_tetrahedra(g.vertices, g.tets, label(g, f), f);
    for (std::size_t t = 0; t < g.tets.size(); t += 3) std::swap(g.tets[t][0], g.tets[t][1]);
    const auto r = ks::marching_tetrahedra(g.vertices, g.tets, label(g, f), f);
    check_guarantee(r.mesh, 1, 0);
    CHECK(ks::signed_volume(r.mesh) == doctest::Approx(ks::signed_volume(ref.mesh)));
}

TEST_CASE("marching_tetrahedra: same-sign rule puts the vertex near the end with smaller |f|") {
    const std::vector<ks::Vec3> v{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const std::vector<ks::Tet> t{{0, 1, 2, 3}};
    const std::vector<std::uint8_t> in{1, 0, 0, 0};
    // edge 0-1: f changes sign, zero at 0.25; edge 0-2: same sign, |f| smaller at 2;
    // edge 0-3: same sign, |f| smaller at 0.
    const std::vector<double> f{0.3, -0.9, 0.1, 2.0};
    const auto r = ks::marching_tetrahedra(v, t, in, f, {.same_sign_fraction = 0.1});
    // The single tet is its own hull: 3 edge vertices + vertex 0 for the caps on its 3 faces.
    REQUIRE(r.mesh.vertices.size() == 4);
    REQUIRE(r.mesh.faces.size() == 4);
    CHECK(r.cap_faces == 3);
    CHECK(r.same_sign_vertices == 2);
    check_guarantee(r.mesh, 1, 0);
    for (std::size_t i = 0; i < 4; ++i) {
        const auto& e = r.vertex_edges[i];
        CHECK(e[0] == 0);
        if (e[1] == 0) {
            CHECK(r.mesh.vertices[i] == v[0]);
            continue;
        }
        const ks::Vec3& p = r.mesh.vertices[i];
        if (e[1] == 1) {
            CHECK(r.same_sign[i] == 0);
            CHECK((p - ks::Vec3(0.25, 0, 0)).norm() < 1e-12);
        } else if (e[1] == 2) {
            CHECK(r.same_sign[i] == 1);
            CHECK((p - ks::Vec3(0, 0.9, 0)).norm() < 1e-12);
        } else {
            CHECK(r.same_sign[i] == 1);
            CHECK((p - ks::Vec3(0, 0, 0.1)).norm() < 1e-12);
        }
    }
    // Outward: the normal points away from the inside vertex 0.
    CHECK(ks::face_normal(r.mesh, 0).dot(ks::Vec3(1, 1, 1)) > 0);
    // A zero of f right at an end is kept min_edge_fraction away from it.
    const auto r2 = ks::marching_tetrahedra(v, t, in, std::vector<double>{0.0, -1, -1, -1},
                                            {.min_edge_fraction = 0.02});
    for (std::size_t i = 0; i < r2.mesh.vertices.size(); ++i)
        if (r2.vertex_edges[i][1] != 0) CHECK(r2.mesh.vertices[i].norm() == doctest::Approx(0.02));
}

TEST_CASE("marching_tetrahedra: bad input and cancellation") {
    const std::vector<ks::Vec3> v{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const std::vector<ks::Tet> t{{0, 1, 2, 3}};
    const std::vector<std::uint8_t> in{1, 0, 0, 0};
    CHECK_THROWS_WITH_AS((void)ks::marching_tetrahedra(v, {{0, 1, 2, 4}}, in), doctest::Contains("tet 0"),
                         ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)ks::marching_tetrahedra(v, t, {1, 0}), doctest::Contains("one label per vertex"),
                         ks::invalid_input);
    CHECK_THROWS_AS((void)ks::marching_tetrahedra(v, t, in, {1.0}), ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)ks::marching_tetrahedra(v, t, in, {1.0, std::nan(""), 0, 0}),
                         doctest::Contains("f[1]"), ks::invalid_input);
    auto vbad = v;
    vbad[2].x() = std::numeric_limits<double>::infinity();
    CHECK_THROWS_AS((void)ks::marching_tetrahedra(vbad, t, in), ks::invalid_input);
    const std::vector<ks::Vec3> flat{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
    CHECK_THROWS_WITH_AS((void)ks::marching_tetrahedra(flat, t, in), doctest::Contains("degenerate"),
                         ks::invalid_input);
    CHECK_THROWS_AS((void)ks::marching_tetrahedra(v, t, in, {}, {.min_edge_fraction = 0.6}), ks::invalid_input);
    std::stop_source stop;
    stop.request_stop();
    ks::MarchingTetrahedraParams p;
    p.control.stop = stop.get_token();
    const auto r = ks::marching_tetrahedra(v, t, in, {}, p);
    CHECK(r.status == ks::Status::cancelled);
    CHECK(r.mesh.faces.empty());
}
