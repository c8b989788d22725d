// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// MeshTopology: exact edge / incidence / one-ring counts and boundary loops on meshes
// with known combinatorics, through every mesh adapter; non-manifold input.
#include <doctest/doctest.h>

#include <kintsugi/mesh/topology.hpp>

#include "metrics/mesh_fixtures.hpp"

#include <algorithm>
#include <map>
#include <set>

namespace ks = kintsugi;
using fixtures::EigenHolder;
using fixtures::IndexedHolder;
using fixtures::SurfaceMeshHolder;
using ks::Face;
using ks::Index;
using ks::IndexedMesh;
using ks::MeshTopology;

namespace {

/// Histogram of edge_faces sizes.
std::map<std::size_t, std::size_t> edge_valence(const MeshTopology& t) {
    std::map<std::size_t, std::size_t> h;
    for (Index e = 0; e < t.num_edges(); ++e) ++h[t.edge_faces(e).size()];
    return h;
}

/// Checks every structural invariant against a brute-force recomputation.
void check_invariants(const MeshTopology& t, const IndexedMesh& m) {
    REQUIRE(t.num_vertices() == m.vertices.size());
    REQUIRE(t.num_faces() == m.faces.size());
    // brute force edge -> faces
    std::map<std::array<Index, 2>, std::set<Index>> ref;
    for (Index f = 0; f < m.faces.size(); ++f)
        for (int k = 0; k < 3; ++k) {
            Index a = m.faces[f][k], b = m.faces[f][(k + 1) % 3];
            ref[{std::min(a, b), std::max(a, b)}].insert(f);
        }
    REQUIRE(t.num_edges() == ref.size());
    Index e = 0;
    for (const auto& [key, fs] : ref) {
        CHECK(t.edges()[e] == key);
        const auto ef = t.edge_faces(e);
        CHECK(std::vector<Index>(ef.begin(), ef.end()) == std::vector<Index>(fs.begin(), fs.end()));
        CHECK(t.find_edge(key[0], key[1]) == e);
        CHECK(t.find_edge(key[1], key[0]) == e);
        ++e;
    }
    for (Index f = 0; f < m.faces.size(); ++f)
        for (int k = 0; k < 3; ++k) {
            const auto [a, b] = t.edges()[t.face_edges(f)[k]];
            Index x = m.faces[f][k], y = m.faces[f][(k + 1) % 3];
            CHECK(a == std::min(x, y));
            CHECK(b == std::max(x, y));
        }
    for (Index v = 0; v < m.vertices.size(); ++v) {
        std::set<Index> nb, vf;
        for (Index f = 0; f < m.faces.size(); ++f)
            for (int k = 0; k < 3; ++k)
                if (m.faces[f][k] == v) {
                    vf.insert(f);
                    for (int j = 0; j < 3; ++j)
                        if (m.faces[f][j] != v) nb.insert(m.faces[f][j]);
                }
        const auto n = t.vertex_neighbors(v);
        CHECK(std::vector<Index>(n.begin(), n.end()) == std::vector<Index>(nb.begin(), nb.end()));
        const auto fv = t.vertex_faces(v);
        CHECK(std::vector<Index>(fv.begin(), fv.end()) == std::vector<Index>(vf.begin(), vf.end()));
        const auto ve = t.vertex_edges(v);
        REQUIRE(ve.size() == n.size());
        for (std::size_t i = 0; i < n.size(); ++i) {
            const auto [a, b] = t.edges()[ve[i]];
            CHECK(((a == v && b == n[i]) || (b == v && a == n[i])));
        }
    }
}

/// Each loop is a closed cycle of boundary edges whose face runs opposite to the loop.
void check_loops_oriented(const MeshTopology& t, const IndexedMesh& m, const std::vector<std::vector<Index>>& loops) {
    std::size_t total = 0;
    for (const auto& loop : loops) {
        total += loop.size();
        for (std::size_t i = 0; i < loop.size(); ++i) {
            const Index a = loop[i], b = loop[(i + 1) % loop.size()];
            const auto e = t.find_edge(a, b);
            REQUIRE(e.has_value());
            CHECK(t.is_boundary_edge(*e));
            const Face& f = m.faces[t.edge_faces(*e)[0]];
            bool face_runs_b_to_a = false;
            for (int k = 0; k < 3; ++k) face_runs_b_to_a |= (f[k] == b && f[(k + 1) % 3] == a);
            CHECK(face_runs_b_to_a);
        }
    }
    std::size_t boundary_edges = 0;
    for (Index e = 0; e < t.num_edges(); ++e) boundary_edges += t.is_boundary_edge(e);
    CHECK(total == boundary_edges);
}

}  // namespace

TEST_CASE_TEMPLATE("MeshTopology: closed meshes through every adapter", H, IndexedHolder, EigenHolder,
                   SurfaceMeshHolder) {
    SUBCASE("tetrahedron") {
        H h(fixtures::tetrahedron());
        const IndexedMesh src = ks::to_indexed_mesh(h.mesh());
        const MeshTopology t(h.mesh());
        CHECK(t.num_vertices() == 4);
        CHECK(t.num_faces() == 4);
        CHECK(t.num_edges() == 6);
        CHECK(edge_valence(t) == std::map<std::size_t, std::size_t>{{2, 6}});
        CHECK(t.boundary_loops().empty());
        for (Index v = 0; v < 4; ++v) {
            CHECK(t.vertex_neighbors(v).size() == 3);
            CHECK(t.vertex_faces(v).size() == 3);
            CHECK_FALSE(t.is_boundary_vertex(v));
        }
        check_invariants(t, src);
    }
    SUBCASE("cube") {
        H h(fixtures::cube());
        const IndexedMesh src = ks::to_indexed_mesh(h.mesh());
        const MeshTopology t(h.mesh());
        CHECK(t.num_edges() == 18);
        CHECK(edge_valence(t) == std::map<std::size_t, std::size_t>{{2, 18}});
        CHECK(t.boundary_loops().empty());
        check_invariants(t, src);
    }
    SUBCASE("torus 12 x 8") {
        H h(fixtures::torus(12, 8));
        const IndexedMesh src = ks::to_indexed_mesh(h.mesh());
        const MeshTopology t(h.mesh());
        CHECK(t.num_vertices() == 96);
        CHECK(t.num_faces() == 192);
        CHECK(t.num_edges() == 288);
        for (Index v = 0; v < t.num_vertices(); ++v) CHECK(t.vertex_neighbors(v).size() == 6);
        CHECK(t.boundary_loops().empty());
        check_invariants(t, src);
    }
    SUBCASE("grid with a hole") {
        H h(fixtures::grid(3, 3, {4}));  // centre cell removed
        const IndexedMesh src = ks::to_indexed_mesh(h.mesh());
        const MeshTopology t(h.mesh());
        CHECK(t.num_vertices() == 16);
        CHECK(t.num_faces() == 16);
        // 3x3 grid has 12 + 12 axis edges and 9 diagonals; the hole removes one diagonal
        CHECK(t.num_edges() == 32);
        CHECK(edge_valence(t).at(1) == 16);
        auto loops = t.boundary_loops();
        REQUIRE(loops.size() == 2);
        std::sort(loops.begin(), loops.end(), [](auto& a, auto& b) { return a.size() > b.size(); });
        CHECK(loops[0].size() == 12);
        CHECK(loops[1].size() == 4);
        CHECK(std::set<Index>(loops[1].begin(), loops[1].end()) == std::set<Index>{5, 6, 9, 10});
        check_loops_oriented(t, src, loops);
        CHECK(t.is_boundary_vertex(5));
        CHECK(t.is_boundary_vertex(0));
        check_invariants(t, src);
    }
}

TEST_CASE("MeshTopology: two holes touching at a vertex are two loops") {
    // 4x4 grid; cells (1,1) and (2,2) removed: they share the corner vertex (2,2) = 12.
    const IndexedMesh src = fixtures::grid(4, 4, {1 + 4 * 1, 2 + 4 * 2});
    const MeshTopology t(src);
    auto loops = t.boundary_loops();
    REQUIRE(loops.size() == 3);
    std::sort(loops.begin(), loops.end(), [](auto& a, auto& b) { return a.size() > b.size(); });
    CHECK(loops[0].size() == 16);
    CHECK(loops[1].size() == 4);
    CHECK(loops[2].size() == 4);
    CHECK(std::count(loops[1].begin(), loops[1].end(), Index(12)) == 1);
    CHECK(std::count(loops[2].begin(), loops[2].end(), Index(12)) == 1);
    check_loops_oriented(t, src, loops);
    check_invariants(t, src);
}

TEST_CASE("MeshTopology: bow-tie vertex gives two loops") {
    IndexedMesh m;
    m.vertices = {ks::Vec3(0, 0, 0), ks::Vec3(1, 0, 0), ks::Vec3(1, 1, 0), ks::Vec3(-1, 0, 0), ks::Vec3(-1, -1, 0)};
    m.faces = {{0, 1, 2}, {0, 3, 4}};
    const MeshTopology t(m);
    CHECK(t.num_edges() == 6);
    CHECK(t.vertex_faces(0).size() == 2);
    CHECK(t.vertex_neighbors(0).size() == 4);
    const auto loops = t.boundary_loops();
    REQUIRE(loops.size() == 2);
    CHECK(loops[0].size() == 3);
    CHECK(loops[1].size() == 3);
    check_loops_oriented(t, m, loops);
    check_invariants(t, m);
}

TEST_CASE("MeshTopology: non-manifold edge, isolated vertex, repeated index") {
    SUBCASE("three faces on one edge") {
        IndexedMesh m;
        m.vertices = {ks::Vec3(0, 0, 0), ks::Vec3(1, 0, 0), ks::Vec3(0, 1, 0), ks::Vec3(0, -1, 0),
                      ks::Vec3(0, 0, 1)};
        m.faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
        const MeshTopology t(m);
        CHECK(t.num_edges() == 7);
        const auto e = t.find_edge(1, 0);
        REQUIRE(e.has_value());
        CHECK(t.edge_faces(*e).size() == 3);
        CHECK_FALSE(t.is_boundary_edge(*e));
        CHECK(edge_valence(t) == std::map<std::size_t, std::size_t>{{1, 6}, {3, 1}});
        // The boundary half-edges 0->2->1->3->0 close up; 0->4->1 cannot (three faces on
        // one edge cannot be oriented consistently), so it comes as an open chain.
        const auto loops = t.boundary_loops();
        REQUIRE(loops.size() == 2);
        CHECK(loops[0] == std::vector<Index>{0, 2, 1, 3});
        CHECK(loops[1] == std::vector<Index>{0, 4, 1});
        check_invariants(t, m);
    }
    SUBCASE("isolated vertex") {
        IndexedMesh m = fixtures::tetrahedron();
        m.vertices.push_back(ks::Vec3(5, 5, 5));
        const MeshTopology t(m);
        CHECK(t.num_vertices() == 5);
        CHECK(t.vertex_faces(4).empty());
        CHECK(t.vertex_neighbors(4).empty());
        CHECK_FALSE(t.is_boundary_vertex(4));
        CHECK_FALSE(t.find_edge(4, 0).has_value());
        CHECK_FALSE(t.find_edge(0, 99).has_value());
        check_invariants(t, m);
    }
    SUBCASE("face with a repeated index") {
        IndexedMesh m = fixtures::tetrahedron();
        m.faces.push_back({1, 1, 2});
        const MeshTopology t(m);
        CHECK(t.num_edges() == 7);  // 6 + the self edge (1,1)
        const auto self = t.find_edge(1, 1);
        REQUIRE(self.has_value());
        CHECK(t.edges()[*self] == std::array<Index, 2>{1, 1});
        CHECK_FALSE(t.is_boundary_edge(*self));
        CHECK(t.edge_faces(*t.find_edge(1, 2)).size() == 3);
        CHECK(t.vertex_faces(1).size() == 4);
        CHECK(std::count(t.vertex_neighbors(1).begin(), t.vertex_neighbors(1).end(), Index(1)) == 0);
        (void)t.boundary_loops();
    }
}

TEST_CASE("MeshTopology: eight.off has the expected edge count (genus 2)") {
    const auto path = fixtures::test_data("eight.off");  // in the repository
    REQUIRE(std::filesystem::exists(path));
    const IndexedMesh m = fixtures::load(path);
    const MeshTopology t(m);
    CHECK(t.num_vertices() == 315);
    CHECK(t.num_faces() == 634);
    // closed genus 2: V - E + F = -2
    CHECK(t.num_edges() == 315 + 634 + 2);
    CHECK(edge_valence(t) == std::map<std::size_t, std::size_t>{{2, 951}});
    CHECK(t.boundary_loops().empty());
}

TEST_CASE("MeshTopology: bad input") {
    SUBCASE("vertex index out of range") {
        const std::vector<Face> faces = {{0, 1, 2}, {0, 2, 7}};
        try {
            const MeshTopology t(3, faces);
            FAIL("no exception");
        } catch (const ks::invalid_input& e) {
            const std::string what = e.what();
            CHECK(what.find("MeshTopology") != std::string::npos);
            CHECK(what.find("face 1") != std::string::npos);
            CHECK(what.find("vertex 7") != std::string::npos);
        }
    }
    SUBCASE("empty mesh is fine") {
        const MeshTopology t(0, {});
        CHECK(t.num_edges() == 0);
        CHECK(t.boundary_loops().empty());
    }
}
