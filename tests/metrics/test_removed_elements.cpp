// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// A CGAL::Surface_mesh with a removed face or vertex (no collect_garbage()) through every
// metrics entry point: a clear invalid_input, never CGAL's own element counts (which
// include the removed elements and used to crash topology_report).
#include <doctest/doctest.h>

#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/metrics/denoise.hpp>
#include <kintsugi/metrics/distance.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include "metrics/mesh_fixtures.hpp"

namespace ks = kintsugi;
using fixtures::SurfaceMesh;

TEST_CASE("metrics: a Surface_mesh with removed elements is refused, and accepted after collect_garbage()") {
    const ks::IndexedMesh sphere = fixtures::uv_sphere(8, 12);
    for (const bool remove_face : {true, false}) {
        CAPTURE(remove_face);
        const SurfaceMesh bad = fixtures::surface_mesh_with_garbage(sphere, remove_face);
        const auto refused = doctest::Contains("call collect_garbage()");
        CHECK_THROWS_WITH_AS((void)ks::topology_report(bad), refused, ks::invalid_input);
        CHECK_THROWS_WITH_AS((void)ks::compare(bad, sphere), refused, ks::invalid_input);
        CHECK_THROWS_WITH_AS((void)ks::compare(sphere, bad), refused, ks::invalid_input);
        CHECK_THROWS_WITH_AS((void)ks::compare_points(sphere.vertices, bad), refused, ks::invalid_input);
        CHECK_THROWS_WITH_AS((void)ks::distances_to_mesh(sphere.vertices, bad), refused, ks::invalid_input);
        CHECK_THROWS_WITH_AS((void)ks::denoise_metrics(bad, sphere), refused, ks::invalid_input);
        CHECK_THROWS_WITH_AS((void)ks::denoise_metrics(sphere, bad), refused, ks::invalid_input);

        SurfaceMesh dense = bad;
        dense.collect_garbage();
        const ks::TopologyReport r = ks::topology_report(dense);
        CHECK(r.vertices == sphere.vertices.size());
        CHECK(r.faces == sphere.faces.size() - (remove_face ? 1 : 0));
        CHECK(r.boundary_loops == (remove_face ? 1u : 0u));
        CHECK(r.closed == !remove_face);
    }
}
