// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// HalfedgeMesh: split / collapse / flip with manifold checks and attributes.
#include <doctest/doctest.h>

#include "mesh/edit_fixtures.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/mesh/halfedge_mesh.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <random>

namespace ks = kintsugi;
using SurfaceMesh = CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3>;

namespace {

template <class M>
M convert(const ks::IndexedMesh& m) {
    M out;
    ks::assign_mesh(out, m);
    return out;
}

double linear(const ks::Vec3& p) { return 2.0 * p.x() - p.y() + 3.0 * p.z() + 0.5; }

struct OpCounts {
    std::size_t splits = 0, collapses = 0, flips = 0, refused_collapses = 0, refused_flips = 0;
};

// Seeded random split / collapse / flip on live halfedges; the scalar channel 0 holds
// linear(position) and must keep doing so.
OpCounts random_edits(ks::HalfedgeMesh& hm, std::size_t ops, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    OpCounts n;
    for (std::size_t i = 0; i < ops; ++i) {
        ks::Index h = 0;
        do {
            h = static_cast<ks::Index>(rng() % hm.halfedge_capacity());
        } while (hm.is_removed_face(ks::HalfedgeMesh::face(h)));
        const auto op = rng() % 3;
        const double t = 0.2 + 0.6 * static_cast<double>(rng() % 1000) / 1000.0;
        if (op == 0) {
            hm.split(h, t);
            ++n.splits;
        } else if (op == 1) {
            if (hm.collapse(h, t) == ks::HalfedgeMesh::invalid) ++n.refused_collapses;
            else ++n.collapses;
        } else {
            if (hm.flip(h)) ++n.flips;
            else ++n.refused_flips;
        }
        if (i % 2000 == 0) REQUIRE(hm.validate() == "");
    }
    return n;
}

}  // namespace

TEST_CASE_TEMPLATE("random split / collapse / flip keep a closed mesh manifold with its genus", M, ks::IndexedMesh,
                   SurfaceMesh) {
    struct Case {
        std::string name;
        ks::IndexedMesh mesh;
        long genus;
    };
    const Case cases[] = {{"sphere", kintsugi_test::icosphere(3), 0},
                          {"torus", kintsugi_test::torus(24, 12), 1},
                          {"coarse torus", kintsugi_test::torus(16, 8), 1}};
    for (const Case& c : cases) {
        CAPTURE(c.name);
        const M input = convert<M>(c.mesh);
        auto hm = ks::HalfedgeMesh::from_mesh(input);
        const auto ch = hm.add_scalar("f");
        hm.enable_normals();
        for (ks::Index v = 0; v < hm.vertex_capacity(); ++v) {
            hm.scalar(ch, v) = linear(hm.position(v));
            hm.normal(v) = hm.position(v).normalized();
        }
        const OpCounts n = random_edits(hm, 30000, 7);
        MESSAGE(c.name << ": " << n.splits << " splits, " << n.collapses << " collapses (" << n.refused_collapses
                       << " refused), " << n.flips << " flips (" << n.refused_flips << " refused), "
                       << hm.num_vertices() << " vertices");
        CHECK(n.collapses > 5000);
        CHECK(n.flips > 5000);
        CHECK(n.refused_collapses > 0);
        CHECK(hm.validate() == "");
        double worst = 0;
        for (ks::Index v = 0; v < hm.vertex_capacity(); ++v)
            if (!hm.is_removed_vertex(v)) {
                worst = std::max(worst, std::abs(hm.scalar(ch, v) - linear(hm.position(v))));
                CHECK(std::abs(hm.normal(v).norm() - 1) < 1e-12);
            }
        CHECK(worst < 1e-9);
        M out;
        const auto map = hm.to_mesh(out);
        CHECK(ks::num_vertices(out) == hm.num_vertices());
        CHECK(ks::num_faces(out) == hm.num_faces());
        const auto topo = ks::topology_report(out);
        CHECK(topo.closed);
        CHECK(topo.manifold);
        CHECK(topo.consistently_oriented);
        CHECK(topo.components == 1);
        CHECK(topo.genus == c.genus);
        // The vertex map carries the attributes to the output's indices.
        for (ks::Index v = 0; v < map.size(); ++v)
            if (map[v] != ks::HalfedgeMesh::invalid)
                REQUIRE((ks::vertex_position(out, map[v]) - hm.position(v)).norm() == 0.0);
    }
}

TEST_CASE("random edits on an open grid keep its single boundary loop") {
    const auto grid = kintsugi_test::grid_mesh(12, 0.1);
    auto hm = ks::HalfedgeMesh::from_mesh(grid);
    hm.add_scalar("f");
    for (ks::Index v = 0; v < hm.vertex_capacity(); ++v) hm.scalar(0, v) = linear(hm.position(v));
    random_edits(hm, 5000, 3);
    CHECK(hm.validate() == "");
    ks::IndexedMesh out;
    hm.to_mesh(out);
    const auto topo = ks::topology_report(out);
    CHECK(topo.manifold);
    CHECK(topo.boundary_loops == 1);
    CHECK(topo.genus == 0);
    CHECK(topo.components == 1);
    hm.collect_garbage();
    CHECK(hm.validate() == "");
    CHECK(hm.vertex_capacity() == out.vertices.size());
    for (ks::Index v = 0; v < hm.vertex_capacity(); ++v) CHECK(std::abs(hm.scalar(0, v) - linear(hm.position(v))) < 1e-9);
}

TEST_CASE("split, flip and collapse do what they say") {
    // Two triangles (0, 1, 2), (0, 2, 3) of the unit square.
    ks::IndexedMesh sq;
    sq.vertices = {ks::Vec3(0, 0, 0), ks::Vec3(1, 0, 0), ks::Vec3(1, 1, 0), ks::Vec3(0, 1, 0)};
    sq.faces = {{0, 1, 2}, {0, 2, 3}};
    auto hm = ks::HalfedgeMesh::from_mesh(sq);
    const auto u = hm.add_scalar("u", 0);
    hm.scalar(u, 2) = 4;
    const ks::Index h = hm.find_halfedge(0, 2);
    REQUIRE(h != ks::HalfedgeMesh::invalid);
    // The diagonal joins two boundary vertices through the interior: no collapse.
    CHECK_FALSE(hm.can_collapse(h));
    CHECK(hm.collapse(h) == ks::HalfedgeMesh::invalid);
    // Flip: the diagonal becomes 3 -> 1 (from the vertex opposite twin(h) to the one opposite h).
    REQUIRE(hm.can_flip(h));
    CHECK(hm.flip(h));
    CHECK(hm.source(h) == 1);
    CHECK(hm.target(h) == 3);
    CHECK(hm.find_halfedge(0, 2) == ks::HalfedgeMesh::invalid);
    CHECK(hm.validate() == "");
    // Boundary edges cannot flip.
    CHECK_FALSE(hm.can_flip(hm.find_halfedge(0, 1)));
    // Split the boundary edge 1 -> 2 at t = 0.25: one new vertex, one new face.
    const ks::Index b = hm.find_halfedge(1, 2);
    const ks::Index m = hm.split(b, 0.25);
    CHECK(m == 4);
    CHECK(hm.num_faces() == 3);
    CHECK((hm.position(m) - ks::Vec3(1, 0.25, 0)).norm() < 1e-15);
    CHECK(hm.scalar(u, m) == doctest::Approx(1.0));
    CHECK(hm.source(b) == 1);
    CHECK(hm.target(b) == m);
    CHECK(hm.is_boundary_vertex(m));
    CHECK(hm.valence(m) == 3);
    CHECK(hm.validate() == "");
    // Collapse the boundary edge m -> 2 back: vertex 2 stays, at t = 1 it keeps its place.
    const ks::Index c = hm.find_halfedge(m, 2);
    REQUIRE(hm.can_collapse(c));
    CHECK(hm.collapse(c, 1.0) == 2);
    CHECK(hm.is_removed_vertex(m));
    CHECK(hm.num_faces() == 2);
    CHECK(hm.scalar(u, 2) == 4);
    CHECK(hm.validate() == "");
}

TEST_CASE("collapse refuses a tetrahedron and flip a duplicate edge") {
    ks::IndexedMesh tet;
    tet.vertices = {ks::Vec3(0, 0, 0), ks::Vec3(1, 0, 0), ks::Vec3(0, 1, 0), ks::Vec3(0, 0, 1)};
    tet.faces = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
    auto hm = ks::HalfedgeMesh::from_mesh(tet);
    REQUIRE(hm.validate() == "");
    for (ks::Index h = 0; h < hm.halfedge_capacity(); ++h) {
        CHECK_FALSE(hm.can_collapse(h));
        CHECK_FALSE(hm.can_flip(h));
    }
    // Every triangulated sphere but the tetrahedron has a collapsible edge: greedy
    // collapses of the icosahedron stop at exactly 4 vertices, valid all the way.
    auto ho = ks::HalfedgeMesh::from_mesh(kintsugi_test::icosphere(0));
    std::size_t collapses = 0;
    for (int round = 0; round < 20; ++round)
        for (ks::Index h = 0; h < ho.halfedge_capacity(); ++h)
            if (!ho.is_removed_face(ks::HalfedgeMesh::face(h)) && ho.collapse(h) != ks::HalfedgeMesh::invalid) {
                ++collapses;
                REQUIRE(ho.validate() == "");
            }
    // An icosahedron (12 vertices) collapses down to the smallest closed surface, a tetrahedron.
    CHECK(collapses == 8);
    CHECK(ho.num_vertices() == 4);
    CHECK(ho.num_faces() == 4);
}

TEST_CASE("HalfedgeMesh rejects non-manifold and bad input, naming the element") {
    using V = ks::Vec3;
    // Three faces on edge (0, 1).
    CHECK_THROWS_WITH_AS(ks::HalfedgeMesh::from_faces({V(0, 0, 0), V(1, 0, 0), V(0, 1, 0), V(0, -1, 0), V(0, 0, 1)},
                                                      {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}}),
                         doctest::Contains("edge (0, 1)"), ks::invalid_input);
    // Two faces running 0 -> 1 the same way (inconsistent orientation).
    CHECK_THROWS_WITH_AS(ks::HalfedgeMesh::from_faces({V(0, 0, 0), V(1, 0, 0), V(0, 1, 0), V(0, -1, 0)},
                                                      {{0, 1, 2}, {0, 1, 3}}),
                         doctest::Contains("inconsistently oriented"), ks::invalid_input);
    // A bow-tie: two triangles sharing only vertex 0.
    CHECK_THROWS_WITH_AS(ks::HalfedgeMesh::from_faces({V(0, 0, 0), V(1, 0, 0), V(1, 1, 0), V(-1, 0, 0), V(-1, -1, 0)},
                                                      {{0, 1, 2}, {0, 3, 4}}),
                         doctest::Contains("vertex 0 is non-manifold"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::HalfedgeMesh::from_faces({V(0, 0, 0), V(1, 0, 0), V(0, 1, 0)}, {{0, 1, 1}}),
                         doctest::Contains("face 0 (0, 1, 1) repeats a vertex"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::HalfedgeMesh::from_faces({V(0, 0, 0), V(1, 0, 0), V(0, 1, 0)}, {{0, 1, 5}}),
                         doctest::Contains("face 0 uses vertex 5"), ks::invalid_input);
    CHECK_THROWS_WITH_AS(ks::HalfedgeMesh::from_faces({V(0, 0, 0), V(1, 0, std::nan("")), V(0, 1, 0)}, {{0, 1, 2}}),
                         doctest::Contains("vertex 1 has a NaN"), ks::invalid_input);
    // Through a user container: the Eigen view of a bow-tie.
    Eigen::MatrixXd Vm(5, 3);
    Vm << 0, 0, 0, 1, 0, 0, 1, 1, 0, -1, 0, 0, -1, -1, 0;
    Eigen::MatrixXi Fm(2, 3);
    Fm << 0, 1, 2, 0, 3, 4;
    CHECK_THROWS_AS(ks::HalfedgeMesh::from_mesh(ks::eigen_mesh(Vm, Fm)), ks::invalid_input);
}
