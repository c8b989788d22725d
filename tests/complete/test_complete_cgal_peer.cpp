// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The peer of the completion tests: CGAL's triangulate_refine_and_fair_hole, in a
// translation unit of its own (its instantiation under the sanitizers is the larger half
// of test_complete_peer.cpp's compile time; complete_fixtures.hpp declares it).
#include "complete/complete_fixtures.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>

#ifndef CGAL_EIGEN3_ENABLED
#define CGAL_EIGEN3_ENABLED 1  // CGAL's fairing needs Eigen
#endif
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Surface_mesh.h>
#include <doctest/doctest.h>

#include <iterator>
#include <vector>

namespace kintsugi_test::completion {

namespace {
using SurfaceMesh = CGAL::Surface_mesh<CGAL::Exact_predicates_inexact_constructions_kernel::Point_3>;
}  // namespace

// CGAL's fair fill of every selected hole; returns the new vertices.
std::vector<ks::Vec3> cgal_fill(const ks::IndexedMesh& in, const std::vector<std::vector<ks::Index>>& loops) {
    SurfaceMesh sm;
    ks::assign_mesh(sm, in);
    std::vector<ks::Vec3> out;
    for (const auto& l : loops) {
        const auto h = sm.halfedge(SurfaceMesh::Vertex_index(static_cast<SurfaceMesh::size_type>(l[1])),
                                   SurfaceMesh::Vertex_index(static_cast<SurfaceMesh::size_type>(l[0])));
        auto border = sm.is_border(h) ? h : sm.opposite(h);
        REQUIRE(sm.is_border(border));
        std::vector<SurfaceMesh::Face_index> pf;
        std::vector<SurfaceMesh::Vertex_index> pv;
        CGAL::Polygon_mesh_processing::triangulate_refine_and_fair_hole(sm, border, std::back_inserter(pf),
                                                                        std::back_inserter(pv));
        for (auto v : pv) out.emplace_back(sm.point(v).x(), sm.point(v).y(), sm.point(v).z());
    }
    return out;
}

}  // namespace kintsugi_test::completion
