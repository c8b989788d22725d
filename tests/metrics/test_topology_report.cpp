// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// topology_report: exact counts on meshes of known topology through every mesh
// adapter, non-manifold and non-orientable input, and the Stanford bunny.
#include "test_data.hpp"
#include <doctest/doctest.h>

#include <kintsugi/metrics/topology_report.hpp>

#include "metrics/mesh_fixtures.hpp"

namespace ks = kintsugi;
using fixtures::EigenHolder;
using fixtures::IndexedHolder;
using fixtures::SurfaceMeshHolder;
using ks::Index;
using ks::IndexedMesh;
using ks::TopologyReport;
using ks::Vec3;

namespace {

/// Klein bottle: the torus grid glued with a twist (i = n wraps to 0 with j -> -j).
IndexedMesh klein_bottle(int n = 10, int m = 6) {
    IndexedMesh k = fixtures::torus(n, m);
    k.faces.clear();
    auto id = [&](int i, int j) {
        if (i == n) {
            i = 0;
            j = -j;
        }
        return Index(i * m + ((j % m) + m) % m);
    };
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < m; ++j) {
            k.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            k.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    return k;
}

/// Moebius strip of n quads.
IndexedMesh moebius(int n = 12) {
    IndexedMesh s;
    for (int i = 0; i < n; ++i)
        for (int side = 0; side < 2; ++side) s.vertices.push_back(Vec3(i, side, 0.1 * i * side));
    auto id = [&](int i, int side) {
        if (i == n) {
            i = 0;
            side = 1 - side;
        }
        return Index(2 * i + side);
    };
    for (int i = 0; i < n; ++i) {
        s.faces.push_back({id(i, 0), id(i + 1, 0), id(i + 1, 1)});
        s.faces.push_back({id(i, 0), id(i + 1, 1), id(i, 1)});
    }
    return s;
}

void check_closed_manifold(const TopologyReport& r, std::size_t v, std::size_t f, long genus, std::size_t components = 1) {
    CHECK(r.vertices == v);
    CHECK(r.faces == f);
    CHECK(r.components == components);
    CHECK(r.edges == (3 * f) / 2);
    CHECK(r.euler == static_cast<long>(v) - static_cast<long>(r.edges) + static_cast<long>(f));
    CHECK(r.genus == genus);
    CHECK(r.isolated_vertices == 0);
    CHECK(r.boundary_loops == 0);
    CHECK(r.boundary_edges == 0);
    CHECK(r.non_manifold_edges == 0);
    CHECK(r.non_manifold_vertices == 0);
    CHECK(r.degenerate_faces == 0);
    CHECK(r.closed);
    CHECK(r.manifold);
    CHECK(r.consistently_oriented);
}

}  // namespace

TEST_CASE_TEMPLATE("topology_report: manifold meshes through every adapter", H, IndexedHolder, EigenHolder,
                   SurfaceMeshHolder) {
    SUBCASE("tetrahedron") {
        H h(fixtures::tetrahedron());
        const auto r = ks::topology_report(h.mesh());
        check_closed_manifold(r, 4, 4, 0);
        CHECK(r.euler == 2);
    }
    SUBCASE("cube") {
        H h(fixtures::cube());
        check_closed_manifold(ks::topology_report(h.mesh()), 8, 12, 0);
    }
    SUBCASE("torus: genus 1") {
        H h(fixtures::torus(16, 9));
        const auto r = ks::topology_report(h.mesh());
        check_closed_manifold(r, 144, 288, 1);
        CHECK(r.euler == 0);
    }
    SUBCASE("two components: genus adds up") {
        H h(fixtures::concat(fixtures::torus(12, 8), fixtures::cube(Vec3(10, 0, 0))));
        const auto r = ks::topology_report(h.mesh());
        check_closed_manifold(r, 96 + 8, 192 + 12, 1, 2);
        CHECK(r.euler == 2);
    }
    SUBCASE("grid with a hole") {
        H h(fixtures::grid(3, 3, {4}));
        const auto r = ks::topology_report(h.mesh());
        CHECK(r.vertices == 16);
        CHECK(r.faces == 16);
        CHECK(r.edges == 32);
        CHECK(r.components == 1);
        CHECK(r.boundary_loops == 2);
        CHECK(r.boundary_edges == 16);
        CHECK(r.euler == 0);
        CHECK(r.genus == 0);
        CHECK_FALSE(r.closed);
        CHECK(r.manifold);
        CHECK(r.consistently_oriented);
    }
    SUBCASE("eight.off: genus 2") {
        const auto path = fixtures::test_data("eight.off");  // in the repository
        REQUIRE(std::filesystem::exists(path));
        H h(fixtures::load(path));
        const auto r = ks::topology_report(h.mesh());
        check_closed_manifold(r, 315, 634, 2);
        CHECK(r.euler == -2);
    }
}

TEST_CASE_TEMPLATE("topology_report: defects", H, IndexedHolder, EigenHolder) {
    SUBCASE("non-manifold edge: three faces") {
        IndexedMesh m;
        m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1)};
        m.faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
        H h(m);
        const auto r = ks::topology_report(h.mesh());
        CHECK(r.non_manifold_edges == 1);
        CHECK(r.non_manifold_vertices == 0);  // its endpoints are reported through the edge
        CHECK(r.boundary_edges == 6);
        CHECK(r.edges == 7);
        CHECK(r.components == 1);
        CHECK_FALSE(r.manifold);
        CHECK(r.genus == -1);
        CHECK_FALSE(r.closed);
    }
    SUBCASE("bow-tie vertex") {
        IndexedMesh m;
        m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(-1, 0, 0), Vec3(-1, -1, 0)};
        m.faces = {{0, 1, 2}, {0, 3, 4}};
        H h(m);
        const auto r = ks::topology_report(h.mesh());
        CHECK(r.non_manifold_vertices == 1);
        CHECK(r.non_manifold_edges == 0);
        CHECK(r.components == 1);
        CHECK(r.boundary_loops == 2);
        CHECK(r.boundary_edges == 6);
        CHECK_FALSE(r.manifold);
        CHECK(r.genus == -1);
    }
    SUBCASE("two cones touching at their apex (two closed fans at one vertex)") {
        // two tetrahedra sharing vertex 0
        IndexedMesh m = fixtures::tetrahedron();
        IndexedMesh t2 = fixtures::tetrahedron();
        for (auto& v : t2.vertices) v = -v;
        m.vertices.insert(m.vertices.end(), t2.vertices.begin() + 1, t2.vertices.end());
        for (auto f : t2.faces) {
            for (auto& i : f) i = i == 0 ? 0 : i + 3;
            m.faces.push_back(f);
        }
        H h(m);
        const auto r = ks::topology_report(h.mesh());
        CHECK(r.vertices == 7);
        CHECK(r.non_manifold_vertices == 1);
        CHECK(r.boundary_edges == 0);
        CHECK(r.closed);
        CHECK_FALSE(r.manifold);
        CHECK(r.genus == -1);
    }
    SUBCASE("one face flipped: inconsistent but orientable") {
        IndexedMesh m = fixtures::cube();
        std::swap(m.faces[5][1], m.faces[5][2]);
        H h(m);
        const auto r = ks::topology_report(h.mesh());
        CHECK_FALSE(r.consistently_oriented);
        CHECK(r.manifold);
        CHECK(r.closed);
        CHECK(r.genus == 0);
    }
    SUBCASE("Moebius strip: non-orientable") {
        H h(moebius(12));
        const auto r = ks::topology_report(h.mesh());
        CHECK(r.boundary_loops == 1);
        CHECK(r.boundary_edges == 24);
        CHECK(r.euler == 0);
        CHECK(r.manifold);
        CHECK_FALSE(r.consistently_oriented);
        CHECK(r.genus == -1);
    }
    SUBCASE("Klein bottle: closed, non-orientable, genus undefined") {
        H h(klein_bottle(10, 6));
        const auto r = ks::topology_report(h.mesh());
        CHECK(r.closed);
        CHECK(r.manifold);
        CHECK(r.euler == 0);
        CHECK_FALSE(r.consistently_oriented);
        CHECK(r.genus == -1);  // (2C - chi - B)/2 would wrongly say 1
    }
    SUBCASE("isolated vertex, collinear face, collapsed face") {
        IndexedMesh m = fixtures::tetrahedron();
        m.vertices.push_back(Vec3(7, 7, 7));  // 4: isolated
        m.vertices.push_back(Vec3(3, 0, 0));  // 5
        m.vertices.push_back(Vec3(5, 0, 0));  // 6: collinear with 1 and 5
        m.vertices.push_back(Vec3(0, 4, 0));  // 7: used only by a collapsed face
        m.faces.push_back({1, 5, 6});
        m.faces.push_back({7, 7, 2});
        H h(m);
        const auto r = ks::topology_report(h.mesh());
        CHECK(r.vertices == 8);
        CHECK(r.faces == 6);
        CHECK(r.isolated_vertices == 1);
        CHECK(r.degenerate_faces == 2);
        CHECK(r.edges == 9);            // collapsed face adds none
        CHECK(r.components == 1);       // the collinear face shares vertex 1
        CHECK(r.euler == 6 - 9 + 5);    // vertex 7 is used only by the collapsed face
        CHECK(r.boundary_loops == 1);
        CHECK(r.boundary_edges == 3);
    }
}

TEST_CASE("topology_report: empty mesh and bad input") {
    SUBCASE("empty") {
        const auto r = ks::topology_report(IndexedMesh{});
        CHECK(r.vertices == 0);
        CHECK(r.components == 0);
        CHECK_FALSE(r.closed);
        CHECK(r.genus == 0);
    }
    SUBCASE("index out of range") {
        IndexedMesh m = fixtures::tetrahedron();
        m.faces.push_back({0, 1, 4});
        CHECK_THROWS_WITH_AS((void)ks::topology_report(m),
                             doctest::Contains("kintsugi::topology_report: face 4 uses vertex 4"), ks::invalid_input);
        EigenHolder e(m);
        CHECK_THROWS_AS((void)ks::topology_report(e.mesh()), ks::invalid_input);
    }
}

TEST_CASE("topology_report: bun_zipper_res4.ply (non-manifold decimation, in the repository)") {
    // Counts measured independently with Open3D (non-manifold edges, Euler) and a
    // Python edge map (see tests/data/metrics/README.md): 453 V, 948 F, 1363 edges,
    // 26 boundary edges, 70 non-manifold edges, 3 pinched vertices, no orientation
    // conflict, Euler 38. (The file itself is shared with other modules' tests.)
    const auto path = fixtures::test_data("bun_zipper_res4.ply");  // in the repository
    REQUIRE(std::filesystem::exists(path));
    const IndexedMesh m = fixtures::load(path);
    const auto r = ks::topology_report(m);
    CHECK(r.vertices == 453);
    CHECK(r.faces == 948);
    CHECK(r.edges == 1363);
    CHECK(r.components == 1);
    CHECK(r.isolated_vertices == 0);
    CHECK(r.boundary_edges == 26);
    CHECK(r.non_manifold_edges == 70);
    CHECK(r.non_manifold_vertices == 3);  // pinched vertices not on a non-manifold edge
    CHECK(r.degenerate_faces == 0);
    CHECK(r.euler == 38);
    CHECK(r.consistently_oriented);
    CHECK_FALSE(r.manifold);
    CHECK_FALSE(r.closed);
    CHECK(r.genus == -1);
}

TEST_CASE("topology_report: Stanford bunny bun_zipper.ply (acceptance)") {
    const auto path = fixtures::shared_data("stanford_bunny/reconstruction/bun_zipper.ply");
    KINTSUGI_REQUIRE_DATA(path);
    const IndexedMesh m = fixtures::load(path);
    const auto r = ks::topology_report(m);
    CHECK(r.vertices == 35947);
    CHECK(r.faces == 69451);
    CHECK(r.components == 1);
    CHECK(r.isolated_vertices == 1113);
    CHECK(r.boundary_loops == 5);
    CHECK(r.boundary_edges == 223);
    CHECK(r.edges == 104288);
    CHECK(r.non_manifold_edges == 0);
    CHECK(r.non_manifold_vertices == 0);
    CHECK(r.euler == -3);
    CHECK(r.genus == 0);
    CHECK(r.manifold);
    CHECK(r.consistently_oriented);
    CHECK_FALSE(r.closed);
}
