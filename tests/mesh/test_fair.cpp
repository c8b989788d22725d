// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Thin-plate (biharmonic) fairing of a vertex subset.
#include <doctest/doctest.h>

#include "mesh/edit_fixtures.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/mesh/fair.hpp>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <cmath>
#include <stop_token>

namespace ks = kintsugi;
using SurfaceMesh = CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3>;

namespace {

double paraboloid(double x, double y) { return 0.7 * x * x - 0.4 * x * y + 0.3 * y * y + 0.1 * x; }

// 21 x 21 grid on the paraboloid; the vertices at least 4 rings from the border are
// free and flattened to z = 0.
struct FairCase {
    ks::IndexedMesh exact, start;
    std::vector<std::uint8_t> free;
};
FairCase fair_case() {
    FairCase c;
    c.exact = kintsugi_test::grid_mesh(20, 0.05, paraboloid);
    c.start = c.exact;
    c.free.assign(c.exact.vertices.size(), 0);
    for (int j = 4; j <= 16; ++j)
        for (int i = 4; i <= 16; ++i) {
            const auto v = static_cast<ks::Index>(j * 21 + i);
            c.free[v] = 1;
            c.start.vertices[v].z() = 0;
        }
    return c;
}

template <class M>
M convert(const ks::IndexedMesh& m) {
    M out;
    ks::assign_mesh(out, m);
    return out;
}

}  // namespace

TEST_CASE_TEMPLATE("fair_biharmonic restores a quadratic patch exactly on a regular grid", M, ks::IndexedMesh,
                   SurfaceMesh) {
    // On a regular 6-valent grid the umbrella of a quadratic is constant, so the
    // quadratic is the minimiser of sum |Lx|^2 with its two outer rings fixed.
    const FairCase c = fair_case();
    auto worst_after = [&](const ks::FairParams& p) {
        M mesh = convert<M>(c.start);
        const auto r = ks::fair_biharmonic(mesh, c.free, p);
        CHECK(r.status == ks::Status::ok);
        CHECK(r.moved_vertices == 13 * 13);
        double worst = 0;
        for (ks::Index v = 0; v < c.exact.vertices.size(); ++v)
            worst = std::max(worst, (ks::vertex_position(mesh, v) - c.exact.vertices[v]).norm());
        return worst;
    };
    CHECK(worst_after({.delta = 0}) < 1e-10);
    // The default pull to the start (delta = 1e-8, start 0.3 away) moves the patch by ~1e-6.
    const double with_delta = worst_after({});
    CHECK(with_delta > 1e-8);
    CHECK(with_delta < 1e-5);
}

TEST_CASE("fair_biharmonic writes through an Eigen V/F view") {
    const FairCase c = fair_case();
    Eigen::MatrixXd V(static_cast<Eigen::Index>(c.start.vertices.size()), 3);
    Eigen::MatrixXi F(static_cast<Eigen::Index>(c.start.faces.size()), 3);
    for (std::size_t v = 0; v < c.start.vertices.size(); ++v) V.row(static_cast<Eigen::Index>(v)) = c.start.vertices[v];
    for (std::size_t f = 0; f < c.start.faces.size(); ++f)
        for (int k = 0; k < 3; ++k) F(static_cast<Eigen::Index>(f), k) = static_cast<int>(c.start.faces[f][k]);
    auto view = ks::eigen_mesh(V, F);
    CHECK(ks::fair_biharmonic(view, c.free, {.delta = 0}).moved_vertices == 169);
    CHECK(std::abs(V(21 * 10 + 10, 2) - c.exact.vertices[21 * 10 + 10].z()) < 1e-10);
}

TEST_CASE("fair_biharmonic rejects bad input and leaves the mesh untouched") {
    FairCase c = fair_case();
    ks::IndexedMesh mesh = c.start;
    std::vector<std::uint8_t> short_free(3, 1);
    CHECK_THROWS_WITH_AS(ks::fair_biharmonic(mesh, short_free),
                         doctest::Contains("free has 3 entries for 441 vertices"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::fair_biharmonic(mesh, c.free, {.delta = -1}), doctest::Contains("delta"),
                         ks::invalid_input);
    mesh.vertices[7].x() = std::nan("");
    CHECK_THROWS_WITH_AS(ks::fair_biharmonic(mesh, c.free), doctest::Contains("vertex 7"), ks::invalid_input);
    mesh.vertices[7] = c.start.vertices[7];
    CHECK(mesh.vertices == c.start.vertices);
}

TEST_CASE("fair_biharmonic cancelled leaves the mesh untouched") {
    FairCase c = fair_case();
    ks::IndexedMesh mesh = c.start;
    std::stop_source stop;
    stop.request_stop();
    ks::FairParams p;
    p.control.stop = stop.get_token();
    const auto r = ks::fair_biharmonic(mesh, c.free, p);
    CHECK(r.status == ks::Status::cancelled);
    CHECK(mesh.vertices == c.start.vertices);
}
