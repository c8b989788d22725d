// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The checks every closed-surface output shares (reconstruction, isosurfaces, marching
// tetrahedra, handle removal), in one place.
#pragma once

#include <doctest/doctest.h>

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/metrics/topology_report.hpp>

namespace kintsugi_test {

/// Closed, 2-manifold, consistently oriented, no degenerate face; the report is returned
/// for the caller's own counts (components, genus, ...).
inline kintsugi::TopologyReport check_closed_manifold(const kintsugi::IndexedMesh& m) {
    const auto r = kintsugi::topology_report(m);
    CHECK(r.closed);
    CHECK(r.manifold);
    CHECK(r.consistently_oriented);
    CHECK(r.degenerate_faces == 0);
    return r;
}

}  // namespace kintsugi_test
