// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Boundary loops, the outer-border rule and the thin-plate hole fill (CGAL's
// triangulate_refine_and_fair_hole as the peer: tests/peers/cgal_fair_fill.hpp).
#include <doctest/doctest.h>

#include "mesh/edit_fixtures.hpp"
#include "peers/cgal_fair_fill.hpp"
#include "test_data.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/mesh/holes.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <cmath>
#include <stop_token>

namespace ks = kintsugi;
using SurfaceMesh = CGAL::Surface_mesh<CGAL::Exact_predicates_inexact_constructions_kernel::Point_3>;

namespace {

template <class M>
M convert(const ks::IndexedMesh& m) {
    M out;
    ks::assign_mesh(out, m);
    return out;
}

// 30 x 30 cells of 0.1 with three holes: 4 x 4 cells, 3 x 2 cells and one triangle.
ks::IndexedMesh holed_grid() {
    const double h = 0.1;
    return kintsugi_test::remove_faces(kintsugi_test::grid_mesh(30, h), [h](const ks::Vec3& c) {
        const double x = c.x() / h, y = c.y() / h;
        const bool a = x > 5 && x < 9 && y > 5 && y < 9;
        const bool b = x > 15 && x < 18 && y > 20 && y < 22;
        const bool t = std::abs(x - (25 + 2.0 / 3)) < 1e-6 && std::abs(y - (25 + 1.0 / 3)) < 1e-6;
        return a || b || t;
    });
}

// Unit sphere (icosphere, 5 subdivisions: 20,480 faces before the cut) minus the cap z > zcut.
ks::IndexedMesh sphere_with_cap_hole(double zcut) {
    return kintsugi_test::remove_faces(kintsugi_test::icosphere(5), [zcut](const ks::Vec3& c) { return c.z() > zcut; });
}

}  // namespace

TEST_CASE_TEMPLATE("find_boundary_loops: exact counts, lengths, areas and the outer border of an open grid", M,
                   ks::IndexedMesh, SurfaceMesh) {
    const M mesh = convert<M>(holed_grid());
    const auto r = ks::find_boundary_loops(mesh);
    REQUIRE(r.loops.size() == 4);
    CHECK(r.components == 1);
    const auto holes = r.holes();
    REQUIRE(holes.size() == 3);
    std::size_t outer = 0;
    std::vector<double> lengths, areas;
    for (const auto& l : r.loops) {
        if (l.outer) {
            ++outer;
            CHECK(l.length == doctest::Approx(12.0).epsilon(1e-12));
            CHECK(l.area == doctest::Approx(9.0).epsilon(1e-12));
            CHECK(l.vertices.size() == 120);
            CHECK(std::abs(l.normal.z()) == doctest::Approx(1.0));
        } else {
            lengths.push_back(l.length);
            areas.push_back(l.area);
            // The hole's normal is the surface's (+z): loops run against their faces.
            CHECK(l.normal.z() == doctest::Approx(1.0));
        }
    }
    CHECK(outer == 1);
    std::sort(lengths.begin(), lengths.end());
    std::sort(areas.begin(), areas.end());
    CHECK(lengths[0] == doctest::Approx(0.2 + 0.1 * std::sqrt(2.0)).epsilon(1e-12));
    CHECK(lengths[1] == doctest::Approx(1.0).epsilon(1e-12));
    CHECK(lengths[2] == doctest::Approx(1.6).epsilon(1e-12));
    CHECK(areas[0] == doctest::Approx(0.005).epsilon(1e-12));
    CHECK(areas[1] == doctest::Approx(0.06).epsilon(1e-12));
    CHECK(areas[2] == doctest::Approx(0.16).epsilon(1e-12));
    // Above 1 the rule never names an outer border.
    CHECK(ks::find_boundary_loops(mesh, {.outer_border_extent = 1.01}).holes().size() == 4);
}

TEST_CASE("find_boundary_loops: a cap cut from a sphere is a hole, the rim of a hemisphere an outer border") {
    const auto cap = ks::find_boundary_loops(sphere_with_cap_hole(0.8));
    REQUIRE(cap.loops.size() == 1);
    CHECK_FALSE(cap.loops[0].outer);
    // The cut follows the mesh near the circle z = 0.8 of radius 0.6.
    // The cut follows the mesh's edges near the circle z = 0.8 of radius 0.6: a zigzag
    // longer than the circle.
    CHECK(cap.loops[0].length > 2 * 3.14159265 * 0.6);
    CHECK(cap.loops[0].length < 1.5 * 2 * 3.14159265 * 0.6);
    const auto hemi = ks::find_boundary_loops(
        kintsugi_test::remove_faces(kintsugi_test::icosphere(3), [](const ks::Vec3& c) { return c.z() < 0; }));
    REQUIRE(hemi.loops.size() == 1);
    CHECK(hemi.loops[0].outer);
    // Two separate patches: each has its own outer border.
    auto two = kintsugi_test::grid_mesh(4, 1.0);
    const auto n = two.vertices.size();
    for (std::size_t v = 0; v < n; ++v) two.vertices.push_back(two.vertices[v] + ks::Vec3(10, 0, 0));
    const auto nf = two.faces.size();
    for (std::size_t f = 0; f < nf; ++f)
        two.faces.push_back({two.faces[f][0] + n, two.faces[f][1] + n, two.faces[f][2] + n});
    const auto r2 = ks::find_boundary_loops(two);
    CHECK(r2.components == 2);
    REQUIRE(r2.loops.size() == 2);
    CHECK(r2.loops[0].outer);
    CHECK(r2.loops[1].outer);
    CHECK_THROWS_WITH_AS(ks::find_boundary_loops(two, {.outer_border_extent = -1}),
                         doctest::Contains("outer_border_extent"), ks::invalid_input);
}

TEST_CASE("find_boundary_loops: a flap that touches the surface at one vertex has its own outer border") {
    // A 6 x 6 grid and a vertical 2 x 2 flap in the plane y = 0.3 whose corner is the
    // grid's interior vertex (3, 3): the flap shares no edge with the grid.
    ks::IndexedMesh m = kintsugi_test::grid_mesh(6, 0.1);
    const ks::Index pinch = 3 * 7 + 3;
    const auto flap = kintsugi_test::grid_mesh(2, 0.1);
    std::vector<ks::Index> id(flap.vertices.size());
    for (ks::Index v = 0; v < flap.vertices.size(); ++v) {
        if (v == 0) {
            id[v] = pinch;
            continue;
        }
        id[v] = m.vertices.size();
        const ks::Vec3& q = flap.vertices[v];
        m.vertices.emplace_back(0.3 + q.x(), 0.3, q.y());
    }
    for (const auto& f : flap.faces) m.faces.push_back({id[f[0]], id[f[1]], id[f[2]]});
    const auto r = ks::find_boundary_loops(m);
    CHECK(r.components == 2);
    REQUIRE(r.loops.size() == 2);
    // Both borders are outer; the largest-extent-per-vertex-component rule called the
    // flap's border a hole (the flap spans 0.28 of the grid's diagonal).
    CHECK(r.loops[0].outer);
    CHECK(r.loops[1].outer);
    CHECK(r.holes().empty());
}

TEST_CASE("find_boundary_loops on a range scan (shipped bun000_part): the outer borders face away from the scanner") {
    // bun000 was scanned along +z (within 1.3 degrees): seen from the scanner, the outer
    // border of each piece runs clockwise (vector area towards -z), a hole counter-clockwise.
    const auto m = ks::read_mesh(kintsugi::test::test_data("bun000_part.ply"));
    const auto r = ks::find_boundary_loops(m);
    CHECK(r.components == 3);
    REQUIRE(r.loops.size() == 4);
    std::size_t outer = 0;
    for (const auto& l : r.loops) {
        CHECK(l.outer == (l.normal.z() < 0));
        outer += l.outer ? 1 : 0;
    }
    CHECK(outer == 3);  // one per piece
    CHECK(r.holes().size() == 1);
}

TEST_CASE("find_boundary_loops on the full bun000 range scan: every loop classified as the scanner sees it") {
    const auto path = kintsugi::test::shared_data("stanford_bunny/scans/bun000.ply");
    KINTSUGI_REQUIRE_DATA(path);
    const auto m = ks::read_mesh(path);
    const auto r = ks::find_boundary_loops(m);
    REQUIRE(r.loops.size() == 24);
    std::size_t agree = 0, outer = 0;
    for (const auto& l : r.loops) {
        agree += l.outer == (l.normal.z() * l.area < 0) ? 1 : 0;
        outer += l.outer ? 1 : 0;
    }
    MESSAGE("bun000: " << r.loops.size() << " loops, " << r.components << " components, " << outer
            << " outer; agree with the scanner's view: " << agree);
    // Measured 24 of 24 (the extent rule over vertex-sharing components: 23).
    CHECK(agree == r.loops.size());
}

TEST_CASE_TEMPLATE("fill_holes closes the grid's holes with flat, manifold patches at the grid's density", M,
                   ks::IndexedMesh, SurfaceMesh) {
    const ks::IndexedMesh in = holed_grid();
    M mesh = convert<M>(in);
    const auto loops = ks::find_boundary_loops(mesh);
    std::vector<std::vector<ks::Index>> holes;
    for (const auto i : loops.holes()) holes.push_back(loops.loops[i].vertices);
    const auto r = ks::fill_holes(mesh, holes);
    CHECK(r.status == ks::Status::ok);
    CHECK(r.filled_holes == 3);
    CHECK(r.unfilled_holes.empty());
    CHECK(ks::num_vertices(mesh) == in.vertices.size() + r.new_vertices);
    CHECK(ks::num_faces(mesh) == in.faces.size() + r.new_faces);
    // The holes' areas at the grid's density (0.005 per triangle): 32 + 12 + 1 triangles,
    // give or take the refinement's rounding.
    CHECK(r.new_faces >= 45);
    CHECK(r.new_faces <= 90);
    const auto topo = ks::topology_report(mesh);
    CHECK(topo.manifold);
    CHECK(topo.consistently_oriented);
    CHECK(topo.boundary_loops == 1);
    CHECK(topo.genus == 0);
    // A plane stays a plane; the old vertices did not move.
    for (ks::Index v = 0; v < ks::num_vertices(mesh); ++v) {
        const ks::Vec3 p = ks::vertex_position(mesh, v);
        CHECK(std::abs(p.z()) < 1e-9);
        if (v < in.vertices.size()) CHECK(p == in.vertices[v]);
    }
}

TEST_CASE("fill_holes: a loop longer than the whole-loop triangulation is cut into pieces, still flat and manifold") {
    // A slot of 3 x 150 cells in a 160 x 160 grid: its loop has 306 vertices (> 200, so
    // hole_triangulation cuts it before the minimum-area triangulation of each piece).
    const double h = 0.1;
    const ks::IndexedMesh in = kintsugi_test::remove_faces(kintsugi_test::grid_mesh(160, h), [h](const ks::Vec3& c) {
        return c.x() / h > 5 && c.x() / h < 155 && c.y() / h > 2 && c.y() / h < 5;
    });
    const auto loops = ks::find_boundary_loops(in);
    std::vector<std::vector<ks::Index>> holes;
    for (const auto i : loops.holes()) holes.push_back(loops.loops[i].vertices);
    REQUIRE(holes.size() == 1);
    CHECK(holes[0].size() == 306);
    ks::IndexedMesh mesh = in;
    const auto r = ks::fill_holes(mesh, holes);
    CHECK(r.filled_holes == 1);
    // 900 triangles at the grid's density, give or take the refinement's rounding.
    CHECK(r.new_faces >= 700);
    CHECK(r.new_faces <= 2500);
    const auto topo = ks::topology_report(mesh);
    CHECK(topo.manifold);
    CHECK(topo.consistently_oriented);
    CHECK(topo.boundary_loops == 1);
    CHECK(topo.genus == 0);
    double zmax = 0;
    for (const auto& p : mesh.vertices) zmax = std::max(zmax, std::abs(p.z()));
    CHECK(zmax < 1e-9);
}

TEST_CASE("fill_holes on a sphere with a cap cut out: distance to the sphere, beside CGAL's fair fill") {
    const ks::IndexedMesh in = sphere_with_cap_hole(0.8);
    const auto loops = ks::find_boundary_loops(in);
    REQUIRE(loops.loops.size() == 1);
    ks::IndexedMesh ours = in;
    const auto r = ks::fill_hole(ours, loops.loops[0].vertices);
    REQUIRE(r.status == ks::Status::ok);
    const auto topo = ks::topology_report(ours);
    CHECK(topo.closed);
    CHECK(topo.manifold);
    CHECK(topo.consistently_oriented);
    CHECK(topo.genus == 0);
    double our_max = 0, our_mean = 0, top = 0;
    for (ks::Index v = in.vertices.size(); v < ours.vertices.size(); ++v) {
        const double d = std::abs(ours.vertices[v].norm() - 1);
        our_max = std::max(our_max, d);
        our_mean += d;
        top = std::max(top, ours.vertices[v].z());
    }
    our_mean /= static_cast<double>(r.new_vertices);

    const kintsugi_test::CgalFairFill cg = kintsugi_test::cgal_fair_fill(in, {loops.loops[0].vertices});
    CHECK(cg.ok);
    REQUIRE(!cg.new_vertices.empty());
    double cgal_max = 0, cgal_mean = 0;
    for (const ks::Vec3& p : cg.new_vertices) {
        const double d = std::abs(p.norm() - 1);
        cgal_max = std::max(cgal_max, d);
        cgal_mean += d;
    }
    cgal_mean /= static_cast<double>(cg.new_vertices.size());
    MESSAGE("cap hole z > 0.8 (radius 0.6) on the unit sphere: kintsugi " << r.new_vertices << " new vertices, "
            << r.new_faces << " faces, distance to the sphere max " << our_max << " mean " << our_mean
            << ", apex z " << top << "; CGAL triangulate_refine_and_fair_hole " << cg.new_vertices.size()
            << " new vertices, max " << cgal_max << " mean " << cgal_mean);
    // The patch continues the sphere: measured largest distance 1.97 % of the radius, mean
    // 0.62 % (CGAL's fill: 1.78 % / 0.63 %; before the cotangent bi-Laplace fairing,
    // uniform least squares: 3.9 % / 1.2 %, apex z 0.961). Bounds keep ~15 % headroom.
    CHECK(top > 0.97);
    CHECK(our_max < 0.023);
    CHECK(our_mean < 0.0072);
    CHECK(our_max < 1.3 * cgal_max);
    // Density like the surrounding mesh: the cap held `removed` vertices.
    const double removed = static_cast<double>(kintsugi_test::icosphere(5).vertices.size() - in.vertices.size());
    MESSAGE("vertices removed with the cap: " << removed);
    CHECK(static_cast<double>(r.new_vertices) > 0.7 * removed);
    CHECK(static_cast<double>(r.new_vertices) < 2.0 * removed);
}

TEST_CASE("fill_holes on bun_zipper.ply's 5 real holes: every new vertex stays inside the model's box") {
    // The cotangent bi-Laplace system of these refined patches is near-singular: its
    // solution put vertices 1e28 diagonals away. Such a solution is refused and the
    // uniform thin-plate system fairs the patch instead.
    const auto path = ks::test::shared_data("stanford_bunny/reconstruction/bun_zipper.ply");
    KINTSUGI_REQUIRE_DATA(path);
    ks::IndexedMesh m = ks::read_mesh(path.string());
    ks::BoundingBox box;
    for (const auto& p : m.vertices) box.extend(p);
    std::vector<std::vector<ks::Index>> holes;
    for (const auto& l : ks::find_boundary_loops(m).loops)
        if (!l.outer) holes.push_back(l.vertices);
    REQUIRE(holes.size() == 5);
    const std::size_t nv0 = m.vertices.size();
    const auto r = ks::fill_holes(m, holes);
    CHECK(r.filled_holes == 5);
    REQUIRE(m.vertices.size() > nv0);
    double outside = 0;
    for (std::size_t v = nv0; v < m.vertices.size(); ++v) {
        const ks::Vec3& q = m.vertices[v];
        REQUIRE(q.allFinite());
        outside = std::max({outside, (box.min - q).maxCoeff(), (q - box.max).maxCoeff()});
    }
    CHECK(outside <= 0.01 * box.diagonal());
    const auto topo = ks::topology_report(m);
    CHECK(topo.closed);
    CHECK(topo.manifold);
}

TEST_CASE("fill_holes: cancellation and bad input leave the mesh untouched") {
    const ks::IndexedMesh in = sphere_with_cap_hole(0.8);
    const auto loop = ks::find_boundary_loops(in).loops.at(0).vertices;
    ks::IndexedMesh mesh = in;
    std::stop_source stop;
    stop.request_stop();
    ks::FillParams p;
    p.control.stop = stop.get_token();
    CHECK(ks::fill_hole(mesh, loop, p).status == ks::Status::cancelled);
    // Cancelled from the progress callback in the middle of the refinement.
    int calls = 0;
    ks::FillParams q;
    q.control.progress = [&calls](const ks::ProgressEvent& e) { return ++calls < 5 || e.fraction < 0.35; };
    CHECK(ks::fill_hole(mesh, loop, q).status == ks::Status::cancelled);
    CHECK(mesh.vertices == in.vertices);
    CHECK(mesh.faces == in.faces);

    CHECK_THROWS_WITH_AS(ks::fill_hole(mesh, {loop[0], loop[1]}), doctest::Contains("loop 0 has 2 vertices"),
                         ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::fill_hole(mesh, {0, 1, 2}), doctest::Contains("not joined by a boundary edge"),
                         ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::fill_hole(mesh, loop, {.split_factor = 0.5}), doctest::Contains("split_factor"),
                         ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::fill_holes(mesh, {loop, loop}), doctest::Contains("already in loop 0"),
                         ks::invalid_input);
    // A non-manifold mesh: a third face on an edge of the loop.
    ks::IndexedMesh bad = in;
    bad.vertices.emplace_back(0, 0, 0);
    bad.faces.push_back({loop[1], loop[0], bad.vertices.size() - 1});
    const ks::IndexedMesh bad_copy = bad;
    CHECK_THROWS_WITH_AS(ks::fill_hole(bad, loop), doctest::Contains("kintsugi::fill_holes: kintsugi::HalfedgeMesh: edge"),
                         ks::invalid_input);
    CHECK(bad.faces == bad_copy.faces);
    CHECK(mesh.vertices == in.vertices);
    CHECK(mesh.faces == in.faces);
}
