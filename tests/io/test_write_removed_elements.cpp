// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// write_mesh on a CGAL::Surface_mesh with a removed face or vertex (no collect_garbage()):
// a clear invalid_input and no file, never CGAL's own element counts.
#include <doctest/doctest.h>

#include <kintsugi/io/write.hpp>

#include "io/io_test_util.hpp"
#include "metrics/mesh_fixtures.hpp"

namespace ks = kintsugi;

TEST_CASE("write_mesh refuses a Surface_mesh with removed elements and writes nothing") {
    const io_test::TempDir dir;
    const ks::IndexedMesh sphere = fixtures::uv_sphere(6, 8);
    for (const bool remove_face : {true, false}) {
        CAPTURE(remove_face);
        const fixtures::SurfaceMesh bad = fixtures::surface_mesh_with_garbage(sphere, remove_face);
        const auto out = dir.path / "out.ply";
        CHECK_THROWS_WITH_AS(ks::write_mesh(out, bad), doctest::Contains("call collect_garbage()"), ks::invalid_input);
        CHECK(!std::filesystem::exists(out));
    }
}
