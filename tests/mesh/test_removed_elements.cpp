// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// A CGAL::Surface_mesh with a removed face or vertex (no collect_garbage()) through the
// mesh module's entry points: a clear invalid_input and an untouched mesh.
#include <doctest/doctest.h>

#include <kintsugi/mesh/fair.hpp>
#include <kintsugi/mesh/holes.hpp>
#include <kintsugi/mesh/taubin.hpp>
#include <kintsugi/mesh/topology.hpp>

#include "metrics/mesh_fixtures.hpp"

namespace ks = kintsugi;
using fixtures::SurfaceMesh;

TEST_CASE("mesh: a Surface_mesh with removed elements is refused and left untouched") {
    const ks::IndexedMesh sphere = fixtures::uv_sphere(8, 12);
    for (const bool remove_face : {true, false}) {
        CAPTURE(remove_face);
        SurfaceMesh bad = fixtures::surface_mesh_with_garbage(sphere, remove_face);
        const auto refused = doctest::Contains("call collect_garbage()");
        CHECK_THROWS_WITH_AS((void)ks::MeshTopology(bad), refused, ks::invalid_input);
        CHECK_THROWS_WITH_AS((void)ks::smooth_taubin(bad), refused, ks::invalid_input);
        const std::vector<std::uint8_t> free_all(sphere.vertices.size() + (remove_face ? 0 : 1), 1);
        CHECK_THROWS_WITH_AS((void)ks::fair_biharmonic(bad, free_all), refused, ks::invalid_input);
        CHECK_THROWS_WITH_AS((void)ks::find_boundary_loops(bad), refused, ks::invalid_input);
        CHECK_THROWS_WITH_AS((void)ks::fill_holes(bad, {}), refused, ks::invalid_input);
        for (std::size_t v = 0; v < sphere.vertices.size(); ++v)
            CHECK(ks::detail::to_vec3(bad.point(SurfaceMesh::Vertex_index(static_cast<SurfaceMesh::size_type>(v)))) ==
                  sphere.vertices[v]);
        bad.collect_garbage();
        CHECK(ks::MeshTopology(bad).num_faces() == sphere.faces.size() - (remove_face ? 1 : 0));
        CHECK(ks::smooth_taubin(bad).status == ks::Status::ok);
    }
}
