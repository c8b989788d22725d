// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Metrics on the Stanford bunny, against CGAL's own tools in the same run.
//
// Input: ../shared/data/stanford_bunny/reconstruction/bun_zipper.ply (35,947 V, 69,451 F,
// the reference B) and ../shared/data/cgal/meshes/bunny00.off (37,706 V, 75,408 F) moved
// onto it with the transform of ../shared/data/README.md (mesh A). Without ../shared/data,
// tests/data/bun_zipper_res4.ply is used as B and a jittered copy of it as A (said on stdout).
//
// topology_report vs CGAL: building a CGAL::Surface_mesh from the same arrays and
// asking PMP for connected components, boundary cycles and the non-manifold vertices
// (what kintsugi's report covers; the report also counts non-manifold edges, which a
// Surface_mesh cannot hold).
// compare vs CGAL: PMP::approximate_Hausdorff_distance in both directions with the same
// number of samples per mesh (200,000), sequential; kintsugi's compare on 1 thread and
// on all threads. kintsugi computes more (mean, RMS, p99, F-score, normal consistency).
// The ratios are printed at the end.
//
// compare on a fan against a grid of as many faces (issue 16): a disk of 20,000 (or 200,000)
// slivers around one vertex, and a square grid, each against a copy with every vertex moved by
// Gaussian noise (sigma 0.002 of the radius), 200,000 samples, 1 thread. Axis-aligned boxes made
// the 20K fan 60x slower than the grid (docs/methods/spatial.md); the ratio is printed at the end.
#include <benchmark/benchmark.h>

#include "common.hpp"

#include <kintsugi/core/parallel.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/metrics/distance.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/distance.h>
#include <CGAL/Polygon_mesh_processing/manifoldness.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/repair.h>
#include <CGAL/Surface_mesh.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace fs = std::filesystem;
namespace ks = kintsugi;
namespace PMP = CGAL::Polygon_mesh_processing;
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<K::Point_3>;

namespace {

constexpr std::size_t kSamples = 200'000;

struct Inputs {
    ks::IndexedMesh a, b;
    SurfaceMesh sa, sb;
    std::string source;
};

SurfaceMesh to_surface_mesh(const ks::IndexedMesh& m) {
    SurfaceMesh sm;
    for (const auto& p : m.vertices) sm.add_vertex(K::Point_3(p.x(), p.y(), p.z()));
    for (const auto& f : m.faces)
        sm.add_face(SurfaceMesh::Vertex_index(static_cast<SurfaceMesh::size_type>(f[0])),
                    SurfaceMesh::Vertex_index(static_cast<SurfaceMesh::size_type>(f[1])),
                    SurfaceMesh::Vertex_index(static_cast<SurfaceMesh::size_type>(f[2])));
    return sm;
}

Inputs& inputs() {
    static Inputs in = [] {
        Inputs r;
        const fs::path shared = KINTSUGI_SHARED_DATA_DIR;
        const fs::path zipper = shared / "stanford_bunny/reconstruction/bun_zipper.ply";
        const fs::path remesh = shared / "cgal/meshes/bunny00.off";
        if (fs::exists(zipper) && fs::exists(remesh)) {
            r.b = ks::read_mesh(zipper);
            r.a = ks::read_mesh(remesh);
            for (auto& v : r.a.vertices) v = 0.155884 * v + ks::Vec3(-0.016805, 0.110267, -0.001525);
            r.source = "bunny00.off (registered) vs bun_zipper.ply";
        } else {
            std::cout << "bench_metrics: ../shared/data not found; using tests/data/bun_zipper_res4.ply "
                         "(and a jittered copy) instead of the full-resolution bunny\n";
            r.b = ks::read_mesh(fs::path(KINTSUGI_TEST_DATA_DIR) / "bun_zipper_res4.ply");
            r.a = r.b;
            for (std::size_t i = 0; i < r.a.vertices.size(); ++i)
                r.a.vertices[i].z() += 1e-4 * static_cast<double>((i * 2654435761u) % 1000) / 1000.0;
            r.source = "bun_zipper_res4.ply jittered vs itself";
        }
        r.a.normals.clear();
        r.b.normals.clear();
        r.sa = to_surface_mesh(r.a);
        r.sb = to_surface_mesh(r.b);
        std::cout << "bench_metrics input: " << r.source << " — A " << r.a.vertices.size() << " V / "
                  << r.a.faces.size() << " F, B " << r.b.vertices.size() << " V / " << r.b.faces.size() << " F\n";
        return r;
    }();
    return in;
}

void BM_kintsugi_topology_report(benchmark::State& state) {
    const auto& in = inputs();
    for (auto _ : state) {
        const auto r = ks::topology_report(in.b);
        benchmark::DoNotOptimize(r.genus);
    }
    const auto r = ks::topology_report(in.b);
    state.counters["components"] = static_cast<double>(r.components);
    state.counters["boundary_loops"] = static_cast<double>(r.boundary_loops);
}

void BM_cgal_topology(benchmark::State& state) {
    const auto& in = inputs();
    std::size_t comps = 0, loops = 0;
    for (auto _ : state) {
        SurfaceMesh sm = to_surface_mesh(in.b);  // kintsugi's report also starts from the arrays
        auto fcc = sm.add_property_map<SurfaceMesh::Face_index, std::size_t>("f:cc").first;
        comps = PMP::connected_components(sm, fcc);
        std::vector<SurfaceMesh::Halfedge_index> cycles;
        PMP::extract_boundary_cycles(sm, std::back_inserter(cycles));
        loops = cycles.size();
        std::vector<SurfaceMesh::Halfedge_index> nm;
        PMP::non_manifold_vertices(sm, std::back_inserter(nm));  // one pass (is_non_manifold_vertex is O(n) per call)
        benchmark::DoNotOptimize(nm.data());
    }
    state.counters["components"] = static_cast<double>(comps);
    state.counters["boundary_loops"] = static_cast<double>(loops);
}

void BM_kintsugi_compare(benchmark::State& state) {
    const auto& in = inputs();
    const int threads = static_cast<int>(state.range(0));
    ks::ThreadLimit limit(threads);
    ks::DistanceReport r;
    for (auto _ : state) {
        r = ks::compare(in.a, in.b, {.samples = kSamples});
        benchmark::DoNotOptimize(r.chamfer);
    }
    state.counters["hausdorff_ab"] = r.a_to_b.hausdorff;
    state.counters["hausdorff_ba"] = r.b_to_a.hausdorff;
    state.counters["mean_ab"] = r.a_to_b.mean;
}

void BM_cgal_approximate_Hausdorff(benchmark::State& state) {
    const auto& in = inputs();
    const double area_a = PMP::area(in.sa), area_b = PMP::area(in.sb);
    double ab = 0, ba = 0;
    for (auto _ : state) {
        ab = PMP::approximate_Hausdorff_distance<CGAL::Sequential_tag>(
            in.sa, in.sb, CGAL::parameters::number_of_points_per_area_unit(kSamples / area_a));
        ba = PMP::approximate_Hausdorff_distance<CGAL::Sequential_tag>(
            in.sb, in.sa, CGAL::parameters::number_of_points_per_area_unit(kSamples / area_b));
        benchmark::DoNotOptimize(ab + ba);
    }
    state.counters["hausdorff_ab"] = ab;
    state.counters["hausdorff_ba"] = ba;
}

/// A fan of n slivers (centre, n rim vertices on the unit circle, faces (0, i, i + 1)) or a grid
/// of about n faces on [-1, 1]^2, and a copy of it with every vertex moved by noise.
std::pair<ks::IndexedMesh, ks::IndexedMesh> fan_or_grid(bool fan, int n) {
    ks::IndexedMesh m;
    if (fan) {
        m.vertices.push_back(ks::Vec3::Zero());
        for (int i = 0; i < n; ++i) {
            const double a = 2 * std::numbers::pi * i / n;
            m.vertices.push_back(ks::Vec3(std::cos(a), std::sin(a), 0));
        }
        for (int i = 0; i < n; ++i) m.faces.push_back({0, ks::Index(1 + i), ks::Index(1 + (i + 1) % n)});
    } else {
        const int k = static_cast<int>(std::sqrt(n / 2.0));
        for (int j = 0; j <= k; ++j)
            for (int i = 0; i <= k; ++i) m.vertices.push_back(ks::Vec3(2.0 * i / k - 1, 2.0 * j / k - 1, 0));
        for (int j = 0; j < k; ++j)
            for (int i = 0; i < k; ++i) {
                const ks::Index a = ks::Index(j * (k + 1) + i);
                m.faces.push_back({a, a + 1, a + ks::Index(k) + 2});
                m.faces.push_back({a, a + ks::Index(k) + 2, a + ks::Index(k) + 1});
            }
    }
    ks::IndexedMesh noisy = m;
    std::mt19937 rng(1);
    std::normal_distribution<double> g(0, 0.002);
    for (auto& v : noisy.vertices) v += ks::Vec3(g(rng), g(rng), g(rng));
    return {std::move(noisy), std::move(m)};
}

/// compare(noisy copy, mesh) on a fan (range(0) = 1) or a grid (0) of range(1) faces, 1 thread.
void BM_compare_fan_vs_grid(benchmark::State& state) {
    const auto [a, b] = fan_or_grid(state.range(0) == 1, static_cast<int>(state.range(1)));
    ks::ThreadLimit limit(1);
    ks::DistanceReport r;
    for (auto _ : state) {
        r = ks::compare(a, b, {.samples = kSamples});
        benchmark::DoNotOptimize(r.chamfer);
    }
    state.counters["faces"] = static_cast<double>(b.faces.size());
    state.counters["mean_ab"] = r.a_to_b.mean;
}

BENCHMARK(BM_kintsugi_topology_report)->Unit(benchmark::kMillisecond)->MinTime(1.0);
BENCHMARK(BM_cgal_topology)->Unit(benchmark::kMillisecond)->MinTime(1.0);
BENCHMARK(BM_kintsugi_compare)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond)->MinTime(2.0)->UseRealTime();
BENCHMARK(BM_cgal_approximate_Hausdorff)->Unit(benchmark::kMillisecond)->MinTime(2.0)->UseRealTime();
BENCHMARK(BM_compare_fan_vs_grid)
    ->ArgNames({"fan", "faces"})
    ->Args({1, 20000})
    ->Args({0, 20000})
    ->Args({1, 200000})
    ->Args({0, 200000})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(1.0);

}  // namespace

int main(int argc, char** argv) {
    inputs();
    return ks::bench::run(argc, argv, [](const ks::bench::RatioReporter& r) {
        std::cout << "\nMetrics on " << inputs().source << " (real time):\n";
        const double kt = r.real("BM_kintsugi_topology_report"), ct = r.real("BM_cgal_topology");
        if (kt > 0 && ct > 0)
            std::printf("  topology_report %.1f ms vs CGAL Surface_mesh + PMP %.1f ms: %.2fx\n", kt, ct, ct / kt);
        const double k1 = r.real("BM_kintsugi_compare/1"), kn = r.real("BM_kintsugi_compare/0"),
                     ch = r.real("BM_cgal_approximate_Hausdorff");
        if (k1 > 0 && ch > 0)
            std::printf("  compare (1 thread) %.1f ms vs CGAL approximate_Hausdorff_distance x2 (sequential) %.1f ms: "
                        "%.2fx\n",
                        k1, ch, ch / k1);
        if (kn > 0 && ch > 0)
            std::printf("  compare (%d threads) %.1f ms: %.2fx\n", ks::max_threads(), kn, ch / kn);
        for (const char* faces : {"20000", "200000"}) {
            const double f = r.cpu(std::string("BM_compare_fan_vs_grid/fan:1/faces:") + faces),
                         g = r.cpu(std::string("BM_compare_fan_vs_grid/fan:0/faces:") + faces);
            if (f > 0 && g > 0)
                std::printf("  compare, %s faces, 1 thread (CPU): fan %.1f ms vs grid %.1f ms: %.2fx\n", faces, f, g, f / g);
        }
    });
}
