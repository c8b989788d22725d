// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Example-based completion (kintsugi::complete_holes_example_based) at the bunny's size:
// ../shared/data/cgal/meshes/bunny00.off (37,706 vertices) with 3 holes cut around
// vertices 7500, 18000 and 29000 (faces whose centroid lies within `radius` of the
// diagonal), default parameters, seconds per level as counters; CGAL's
// triangulate_refine_and_fair_hole on the same holes in the same run.
// Measured 2026-12-01 on the shared 2-core machine (other builds running): radius 5 %
// (36,340 vertices, 1,323 new) 15.8 s wall, levels 2.9 / 3.7 / 8.7 s; radius 2 % (215 new)
// 11.5 s; CGAL 0.046 s and 0.060 s. 2026-12-02 with the blend (load 7.5-8.5 on 2 cores):
// radius 5 % 12.5-13.8 s CPU (19.0-21.1 s wall), radius 2 % 9.5 s CPU. More in
// docs/methods/example_completion.md.
#include "common.hpp"

#include <kintsugi/io/read.hpp>
#include <kintsugi/complete/example_completion.hpp>
#include <kintsugi/adapters/cgal.hpp>

#define CGAL_EIGEN3_ENABLED 1  // CGAL's fairing needs Eigen
#include <CGAL/Surface_mesh.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <benchmark/benchmark.h>

#include <filesystem>
#include <string>
#include <vector>

namespace ks = kintsugi;
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;

namespace {

const std::string bunny_path = std::string(KINTSUGI_SHARED_DATA_DIR) + "/cgal/meshes/bunny00.off";

// bunny00 with the 3 holes of radius `radius` (fraction of the diagonal).
ks::IndexedMesh holey_bunny(double radius) {
    const ks::IndexedMesh in = ks::read_mesh(bunny_path);
    ks::BoundingBox box;
    for (const auto& p : in.vertices) box.extend(p);
    const std::vector<ks::Vec3> c{in.vertices[7500], in.vertices[18000], in.vertices[29000]};
    ks::IndexedMesh out;
    std::vector<ks::Index> map(in.vertices.size(), ks::HalfedgeMesh::invalid);
    for (const auto& f : in.faces) {
        const ks::Vec3 m = (in.vertices[f[0]] + in.vertices[f[1]] + in.vertices[f[2]]) / 3;
        bool cut = false;
        for (const auto& x : c) cut = cut || (m - x).norm() < radius * box.diagonal();
        if (cut) continue;
        ks::Face g{};
        for (int k = 0; k < 3; ++k) {
            if (map[f[k]] == ks::HalfedgeMesh::invalid) {
                map[f[k]] = out.vertices.size();
                out.vertices.push_back(in.vertices[f[k]]);
            }
            g[k] = map[f[k]];
        }
        out.faces.push_back(g);
    }
    return out;
}

void BM_kintsugi_complete(benchmark::State& state) {
    if (!std::filesystem::exists(bunny_path)) {
        state.SkipWithError("../shared/data/cgal/meshes/bunny00.off not found");
        return;
    }
    const ks::IndexedMesh in = holey_bunny(static_cast<double>(state.range(0)) / 1000);
    ks::CompletionResult r;
    for (auto _ : state) {
        ks::IndexedMesh m = in;
        r = ks::complete_holes_example_based(m);
        benchmark::DoNotOptimize(m.vertices.data());
    }
    state.counters["vertices"] = static_cast<double>(in.vertices.size());
    state.counters["new_vertices"] = static_cast<double>(r.new_vertices);
    state.counters["holes"] = static_cast<double>(r.filled_holes);
    for (const auto& t : r.timings)
        if (t.stage.rfind("level", 0) == 0 || t.stage == "initial patch") state.counters[t.stage] = t.seconds;
}

void BM_cgal_fair_fill(benchmark::State& state) {
    if (!std::filesystem::exists(bunny_path)) {
        state.SkipWithError("../shared/data/cgal/meshes/bunny00.off not found");
        return;
    }
    const ks::IndexedMesh in = holey_bunny(static_cast<double>(state.range(0)) / 1000);
    std::size_t added = 0;
    for (auto _ : state) {
        SurfaceMesh sm;
        ks::assign_mesh(sm, in);
        std::vector<SurfaceMesh::Halfedge_index> borders;
        for (auto h : sm.halfedges())
            if (sm.is_border(h)) borders.push_back(h);
        std::vector<bool> done(sm.number_of_halfedges(), false);
        added = 0;
        for (auto h : borders) {
            if (done[h.idx()] || !sm.is_border(h)) continue;
            for (auto g : CGAL::halfedges_around_face(h, sm)) done[g.idx()] = true;
            std::vector<SurfaceMesh::Face_index> pf;
            std::vector<SurfaceMesh::Vertex_index> pv;
            CGAL::Polygon_mesh_processing::triangulate_refine_and_fair_hole(sm, h, std::back_inserter(pf),
                                                                            std::back_inserter(pv));
            added += pv.size();
        }
        benchmark::DoNotOptimize(added);
    }
    state.counters["new_vertices"] = static_cast<double>(added);
}

}  // namespace

// Hole radius in thousandths of the diagonal: 20 (the test's 4 % holes), 50 (~1.5K new vertices).
BENCHMARK(BM_kintsugi_complete)->Arg(20)->Arg(50)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();
BENCHMARK(BM_cgal_fair_fill)->Arg(20)->Arg(50)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

int main(int argc, char** argv) {
    return ks::bench::run(argc, argv, [](const ks::bench::RatioReporter& r) {
        r.print_ratio("BM_kintsugi_complete/20", "BM_cgal_fair_fill/20", "s");
        r.print_ratio("BM_kintsugi_complete/50", "BM_cgal_fair_fill/50", "s");
    });
}
