// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#include "peers/cgal_fair_fill.hpp"

#include <kintsugi/adapters/cgal.hpp>

#ifndef CGAL_EIGEN3_ENABLED
#define CGAL_EIGEN3_ENABLED 1  // CGAL's fairing needs Eigen
#endif
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Surface_mesh.h>

#include <iterator>
#include <stdexcept>
#include <string>
#include <tuple>

namespace kintsugi_test {

CgalFairFill cgal_fair_fill(const kintsugi::IndexedMesh& in, const std::vector<std::vector<kintsugi::Index>>& loops) {
    using SurfaceMesh = CGAL::Surface_mesh<CGAL::Exact_predicates_inexact_constructions_kernel::Point_3>;
    SurfaceMesh sm;
    kintsugi::assign_mesh(sm, in);
    CgalFairFill out;
    for (const auto& l : loops) {
        if (l.size() < 3) throw std::invalid_argument("cgal_fair_fill: a loop of " + std::to_string(l.size()) + " vertices");
        const auto h = sm.halfedge(SurfaceMesh::Vertex_index(static_cast<SurfaceMesh::size_type>(l[1])),
                                   SurfaceMesh::Vertex_index(static_cast<SurfaceMesh::size_type>(l[0])));
        if (h == SurfaceMesh::null_halfedge()) throw std::invalid_argument("cgal_fair_fill: a loop edge is not in the mesh");
        const auto border = sm.is_border(h) ? h : sm.opposite(h);
        if (!sm.is_border(border)) throw std::invalid_argument("cgal_fair_fill: a loop edge is not on the border");
        std::vector<SurfaceMesh::Face_index> pf;
        std::vector<SurfaceMesh::Vertex_index> pv;
        const auto r = CGAL::Polygon_mesh_processing::triangulate_refine_and_fair_hole(
            sm, border, std::back_inserter(pf), std::back_inserter(pv));
        out.ok = out.ok && std::get<0>(r);
        for (auto v : pv) out.new_vertices.emplace_back(sm.point(v).x(), sm.point(v).y(), sm.point(v).z());
    }
    return out;
}

}  // namespace kintsugi_test
