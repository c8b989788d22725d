// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// extract_isosurface: closed manifold output of the right genus on analytic fields,
// distance to the true zero set, cost growing with the area, output mesh types,
// determinism, cancellation, bad input.
#include <doctest/doctest.h>

#include "closed_mesh.hpp"
#include "field/iso_fields.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/field/isosurface.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <atomic>
#include <cstring>
#include <random>
#include <set>
#include <stop_token>

namespace ks = kintsugi;
using kintsugi_test::Genus3Field;
using kintsugi_test::SphereField;
using kintsugi_test::TorusField;

namespace {

using SurfaceMesh = CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3>;

/// Largest |f| over the vertices and over area-weighted points of the triangles
/// (exact distance to the zero set for the sphere and torus, and outside the union).
template <class F>
void max_distances(const F& f, const ks::IndexedMesh& m, double& at_vertices, double& on_faces) {
    at_vertices = 0;
    for (const auto& v : m.vertices) at_vertices = std::max(at_vertices, std::abs(f(v)));
    on_faces = 0;
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(0, 1);
    for (const auto& t : m.faces)
        for (int s = 0; s < 3; ++s) {
            double a = u(rng), b = u(rng);
            if (a + b > 1) {
                a = 1 - a;
                b = 1 - b;
            }
            const ks::Vec3 p = m.vertices[t[0]] + a * (m.vertices[t[1]] - m.vertices[t[0]]) +
                               b * (m.vertices[t[2]] - m.vertices[t[0]]);
            on_faces = std::max(on_faces, std::abs(f(p)));
        }
}

template <class F>
struct Counted {
    const F* f;
    std::atomic<std::size_t>* calls;
    double operator()(const ks::Vec3& x) const {
        calls->fetch_add(1, std::memory_order_relaxed);
        return (*f)(x);
    }
};

template <class F>
ks::IsoRegion band(const F& f, int cells) {
    const auto grid = ks::IsoGrid::fit(f.box(), cells);
    return ks::IsoRegion::narrow_band(grid, kintsugi_test::surface_samples(f, 6), grid.cell_size);
}

template <class F, class M>
void check_shape(const F& f, int cells, M& out) {
    const ks::IsoRegion region = band(f, cells);
    std::atomic<std::size_t> calls{0};
    const auto r = ks::extract_isosurface(Counted<F>{&f, &calls}, region, out);
    REQUIRE(r.status == ks::Status::ok);
    CHECK(r.field_evaluations == calls.load());
    CHECK(r.field_evaluations == r.lattice_evaluations + r.root_evaluations);
    CHECK(r.vertices == ks::num_vertices(out));
    CHECK(r.faces == ks::num_faces(out));
    CHECK(r.cells >= r.crossed_cells);
    CHECK(r.crossed_cells > 0);
    CHECK(r.timings.size() == 3);
    const ks::IndexedMesh m = ks::to_indexed_mesh(out);
    const auto rep = kintsugi_test::check_closed_manifold(m);
    CHECK(rep.components == 1);
    CHECK(rep.genus == f.genus());
    CHECK(ks::signed_volume(m) > 0);  // outward: from f < 0 to f > 0
    const double diag = f.box().diagonal();
    double dv = 0, df = 0;
    max_distances(f, m, dv, df);
    MESSAGE(cells << " cubes: " << m.vertices.size() << " vertices, " << r.field_evaluations << " evaluations, max |f| "
                  << dv / diag << " (vertices) " << df / diag << " (faces) of the diagonal");
    CHECK(dv < 1e-3 * diag);
    CHECK(df < 1e-3 * diag);
}

}  // namespace

TEST_CASE_TEMPLATE("extract_isosurface: sphere, torus, genus 3 — closed, manifold, right genus, on the zero set",
                   Mesh, ks::IndexedMesh, SurfaceMesh) {
    Mesh out;
    SUBCASE("sphere") { check_shape(SphereField{}, 64, out); }
    SUBCASE("torus") { check_shape(TorusField{}, 64, out); }
    SUBCASE("genus 3") { check_shape(Genus3Field{}, 160, out); }
}

TEST_CASE("extract_isosurface: vertices on the zero set to the root tolerance; linear interpolation is worse") {
    const TorusField f;
    const auto region = band(f, 48);
    ks::IndexedMesh a, b;
    REQUIRE(ks::extract_isosurface(f, region, a).status == ks::Status::ok);
    ks::IsosurfaceParams lin;
    lin.root.max_iterations = 0;
    const auto rl = ks::extract_isosurface(f, region, b, lin);
    REQUIRE(rl.status == ks::Status::ok);
    CHECK(rl.root_evaluations == 0);
    // the same crossed edges and cases; only positions (and so quad diagonals) differ
    REQUIRE(a.vertices.size() == b.vertices.size());
    REQUIRE(a.faces.size() == b.faces.size());
    double da = 0, db = 0, fa = 0, fb = 0;
    max_distances(f, a, da, fa);
    max_distances(f, b, db, fb);
    MESSAGE("torus 48: max |f| at vertices, root search " << da << ", linear " << db);
    // clamp to min_edge_fraction of a cube side at most
    CHECK(da <= 1e-3 * region.grid.cell_size * std::sqrt(3.0) + 1e-12);
    CHECK(db > 10 * da);
}

TEST_CASE("extract_isosurface: field evaluations grow with the area, not the volume") {
    const SphereField f;
    std::size_t evals[3] = {0, 0, 0}, cells[3] = {0, 0, 0}, lattice[3] = {0, 0, 0};
    const int res[3] = {32, 64, 128};
    for (int i = 0; i < 3; ++i) {
        ks::IndexedMesh m;
        const auto r = ks::extract_isosurface(f, band(f, res[i]), m);
        REQUIRE(r.status == ks::Status::ok);
        evals[i] = r.field_evaluations;
        cells[i] = r.cells;
        lattice[i] = r.lattice_evaluations;
    }
    MESSAGE("evaluations at 32/64/128 cubes: " << evals[0] << " " << evals[1] << " " << evals[2] << "; lattice "
                                               << lattice[0] << " " << lattice[1] << " " << lattice[2] << "; cubes "
                                               << cells[0] << " " << cells[1] << " " << cells[2]);
    // Doubling the resolution multiplies an area-bound cost by 4 and a volume-bound one by 8.
    for (int i = 0; i < 2; ++i) {
        const double ratio = double(evals[i + 1]) / double(evals[i]);
        CHECK(ratio > 3.0);
        CHECK(ratio < 5.0);
    }
    // lattice values far below the lattice's 129³ = 2.1M vertices
    CHECK(lattice[2] < 0.1 * 129.0 * 129.0 * 129.0);
}

TEST_CASE("extract_isosurface: one seed cube finds the whole component; a region over the whole grid gives the same mesh") {
    const TorusField f;
    const auto grid = ks::IsoGrid::fit(f.box(), 40);
    // seed: the cube holding one point of the torus
    const std::vector<ks::Vec3> one{ks::Vec3(1.4, 0, 0)};
    ks::IndexedMesh a, b;
    const auto ra = ks::extract_isosurface(f, ks::IsoRegion::narrow_band(grid, one, 0.0), a);
    const auto rb = ks::extract_isosurface(f, ks::IsoRegion::full(grid), b);
    REQUIRE(ra.status == ks::Status::ok);
    CHECK(ra.seed_cells == 1);
    CHECK(rb.seed_cells == std::size_t(grid.cells[0]) * grid.cells[1] * grid.cells[2]);
    CHECK(rb.lattice_evaluations == std::size_t(grid.cells[0] + 1) * (grid.cells[1] + 1) * (grid.cells[2] + 1));
    CHECK(ra.lattice_evaluations < rb.lattice_evaluations / 2);
    CHECK(ra.root_evaluations == rb.root_evaluations);
    // the same surface, vertex for vertex (both numbered in cube order)
    CHECK(a.faces == b.faces);
    REQUIRE(a.vertices.size() == b.vertices.size());
    CHECK(std::memcmp(a.vertices.data(), b.vertices.data(), a.vertices.size() * sizeof(ks::Vec3)) == 0);
    CHECK(ks::topology_report(a).genus == 1);
    // Seeds away from the surface find nothing.
    const std::vector<ks::Vec3> far{ks::Vec3(0, 0, 0)};
    ks::IndexedMesh c;
    const auto rc = ks::extract_isosurface(f, ks::IsoRegion::narrow_band(grid, far, 0.0), c);
    CHECK(rc.status == ks::Status::ok);
    CHECK(c.faces.empty());
    CHECK(rc.lattice_evaluations == 8);
}

TEST_CASE("extract_isosurface: seeded by the leaves of an octree built on surface samples") {
    const TorusField f;
    const auto pts = kintsugi_test::surface_samples(f, 30);
    REQUIRE(pts.size() > 1000);
    // a cube with room around the torus (the default cube would touch it)
    const ks::Octree oct(pts, ks::OctreeParams{.max_level = 6, .cube_side = 3.2, .cube_min = ks::Vec3::Constant(-1.6)});
    const ks::IsoRegion region = ks::IsoRegion::from_octree(oct);
    CHECK(region.grid.cells == std::array<int, 3>{64, 64, 64});
    CHECK(region.grid.cell_size == doctest::Approx(oct.cube_side() / 64));
    // every sample lies in a seed cube
    std::set<std::array<int, 3>> seeds(region.cells.begin(), region.cells.end());
    for (std::size_t i = 0; i < pts.size(); i += 17) {
        std::array<int, 3> c{};
        for (int k = 0; k < 3; ++k)
            c[k] = static_cast<int>(std::floor((pts[i][k] - region.grid.origin[k]) / region.grid.cell_size));
        CHECK(seeds.count(c) == 1);
    }
    ks::IndexedMesh m;
    const auto r = ks::extract_isosurface(f, region, m);
    REQUIRE(r.status == ks::Status::ok);
    const auto rep = ks::topology_report(m);
    CHECK(rep.closed);
    CHECK(rep.manifold);
    CHECK(rep.genus == 1);
    CHECK_THROWS_WITH_AS((void)ks::IsoRegion::from_octree(ks::Octree{}), doctest::Contains("empty"), ks::invalid_input);
}

TEST_CASE("extract_isosurface: a surface leaving the grid is cut open there; NaN counts as outside") {
    const SphereField f;
    // the grid covers the lower half of the sphere only
    ks::IsoGrid grid = ks::IsoGrid::fit({ks::Vec3(-1.1, -1.1, -1.1), ks::Vec3(1.1, 1.1, 0.0)}, 44, 0);
    ks::IndexedMesh m;
    REQUIRE(ks::extract_isosurface(f, ks::IsoRegion::full(grid), m).status == ks::Status::ok);
    const auto rep = ks::topology_report(m);
    CHECK(rep.manifold);
    CHECK(rep.components == 1);
    CHECK(rep.boundary_loops == 1);
    // NaN above z = 0 (outside the field's domain): the surface closes along z = 0.
    auto cut = [&f](const ks::Vec3& x) { return x.z() > 0 ? std::numeric_limits<double>::quiet_NaN() : f(x); };
    ks::IndexedMesh c;
    REQUIRE(ks::extract_isosurface(cut, ks::IsoRegion::full(ks::IsoGrid::fit(f.box(), 40)), c).status ==
            ks::Status::ok);
    const auto rc = ks::topology_report(c);
    CHECK(rc.closed);
    CHECK(rc.manifold);
    CHECK(rc.genus == 0);
    double zmax = -1;
    for (const auto& v : c.vertices) zmax = std::max(zmax, v.z());
    CHECK(zmax < 1e-6);
    CHECK(zmax > -1e-6);
}

TEST_CASE("extract_isosurface: identical with 1 and 2 threads") {
    const Genus3Field f;
    const auto region = band(f, 80);
    ks::IndexedMesh one, two;
    {
        ks::ThreadLimit limit(1);
        REQUIRE(ks::extract_isosurface(f, region, one).status == ks::Status::ok);
    }
    {
        ks::ThreadLimit limit(2);
        REQUIRE(ks::extract_isosurface(f, region, two).status == ks::Status::ok);
    }
    CHECK(one.faces == two.faces);
    REQUIRE(one.vertices.size() == two.vertices.size());
    CHECK(std::memcmp(one.vertices.data(), two.vertices.data(), one.vertices.size() * sizeof(ks::Vec3)) == 0);
}

TEST_CASE("extract_isosurface: cancellation leaves the output untouched") {
    const TorusField f;
    const auto region = band(f, 64);
    ks::IndexedMesh out;
    out.vertices = {ks::Vec3(1, 2, 3)};
    SUBCASE("progress callback returns false") {
        for (const char* stop_at : {"isosurface_cells", "isosurface_vertices", "isosurface_faces"}) {
            ks::IsosurfaceParams p;
            std::vector<std::string> seen;
            p.control.progress = [&](const ks::ProgressEvent& e) {
                seen.emplace_back(e.stage);
                return e.stage != stop_at;
            };
            const auto r = ks::extract_isosurface(f, region, out, p);
            CHECK(r.status == ks::Status::cancelled);
            CHECK(r.faces == 0);
            CHECK(seen.back() == stop_at);
            CHECK(out.vertices.size() == 1);
            CHECK(out.faces.empty());
        }
    }
    SUBCASE("stop token") {
        std::stop_source src;
        src.request_stop();
        ks::IsosurfaceParams p;
        p.control.stop = src.get_token();
        CHECK(ks::extract_isosurface(f, region, out, p).status == ks::Status::cancelled);
        CHECK(out.vertices.size() == 1);
    }
}

TEST_CASE("extract_isosurface: bad input throws invalid_input naming the problem, output untouched") {
    const SphereField f;
    const auto grid = ks::IsoGrid::fit(f.box(), 16);
    ks::IndexedMesh out;
    out.vertices = {ks::Vec3(1, 2, 3)};
    auto throws_with = [&](const ks::IsoRegion& r, const ks::IsosurfaceParams& p, const char* what) {
        CHECK_THROWS_WITH_AS(ks::extract_isosurface(f, r, out, p), doctest::Contains(what), ks::invalid_input);
        CHECK(out.vertices.size() == 1);
    };
    const ks::IsoRegion ok = ks::IsoRegion::full(grid);
    throws_with(ks::IsoRegion{grid, {}}, {}, "no cube");
    throws_with(ks::IsoRegion{grid, {{0, 0, grid.cells[2]}}}, {}, "outside the grid");
    throws_with(ks::IsoRegion{grid, {{-1, 0, 0}}}, {}, "region cube 0");
    ks::IsoRegion bad = ok;
    bad.grid.cell_size = 0;
    throws_with(bad, {}, "cell_size");
    bad = ok;
    bad.grid.origin.x() = std::numeric_limits<double>::quiet_NaN();
    throws_with(bad, {}, "finite origin");
    bad = ok;
    bad.grid.cells[1] = 0;
    throws_with(bad, {}, "along axis 1");
    ks::IsosurfaceParams p;
    p.min_edge_fraction = 0.5;
    throws_with(ok, p, "min_edge_fraction");
    p = {};
    p.root.samples = 0;
    throws_with(ok, p, "root.samples");
    p = {};
    p.root.tolerance = 0;
    throws_with(ok, p, "root.tolerance");
    CHECK_THROWS_WITH_AS((void)ks::IsoGrid::fit(ks::BoundingBox{}, 10), doctest::Contains("empty"), ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)ks::IsoGrid::fit(f.box(), 0), doctest::Contains("cells_longest_side"),
                         ks::invalid_input);
    const std::vector<ks::Vec3> nan_pt{ks::Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0)};
    CHECK_THROWS_WITH_AS((void)ks::IsoRegion::narrow_band(grid, nan_pt, 0.1), doctest::Contains("point 0"),
                         ks::invalid_input);
    CHECK_THROWS_WITH_AS((void)ks::IsoRegion::narrow_band(grid, std::vector<ks::Vec3>{ks::Vec3::Zero()}, -1.0),
                         doctest::Contains("radius"), ks::invalid_input);
}

TEST_CASE("extract_isosurface: a DifferentiableScalarField that is NaN outside its domain") {
    // Concept check: a field with an extra member (gradient) and a NaN outside its domain.
    struct Clipped {
        SphereField s;
        double operator()(const ks::Vec3& x) const { return x.norm() > 3 ? std::numeric_limits<double>::quiet_NaN() : s(x); }
        ks::Vec3 gradient(const ks::Vec3& x) const { return (x - s.c).normalized(); }
    };
    static_assert(ks::DifferentiableScalarField<Clipped>);
    static_assert(!ks::ScalarField<int>);
    const Clipped f;
    ks::IndexedMesh m;
    const auto r = ks::extract_isosurface(f, band(SphereField{}, 24), m);
    REQUIRE(r.status == ks::Status::ok);
    CHECK(ks::topology_report(m).genus == 0);
}
