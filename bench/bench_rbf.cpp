// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Octree RBF (rbf/rbf_octree.hpp): the n_max sweep of the paper (fit time against n_max
// at 100K and 500K points, the optimum independent of N), time against N (100K, 500K, 1M
// points: 3N centres with the offsets), a dense global RBF at small N, and CGAL's
// Poisson reconstruction at the same N. Input: ../shared/data/libigl/fertility.off
// sampled uniformly by area with the face normals (clean oriented points of a closed
// genus-4 model). Wall time (UseRealTime), process CPU time, peak resident set and
// accuracy (mean distance from the reference to the result, % of its diagonal) as
// counters. Measurements and the machine's load: docs/methods/rbf_octree.md.
//
// Run: bench_rbf [--benchmark_filter=nmax]
#include "common.hpp"

#include <kintsugi/rbf/rbf_octree.hpp>
#include <kintsugi/metrics/distance.hpp>
#include <kintsugi/metrics/topology_report.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/adapters/cgal.hpp>

#include <benchmark/benchmark.h>

#ifndef CGAL_EIGEN3_ENABLED
#define CGAL_EIGEN3_ENABLED 1
#endif
#include <CGAL/poisson_surface_reconstruction.h>
#include <CGAL/compute_average_spacing.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/property_map.h>

#include <map>
#include <string>
#include <utility>
#include <vector>

#include <sys/resource.h>

namespace ks = kintsugi;

namespace {

/// fertility.off (../shared/data/libigl), read once.
const ks::IndexedMesh& shape() {
    static const ks::IndexedMesh m = ks::read_mesh(std::string(KINTSUGI_SHARED_DATA_DIR) + "/libigl/fertility.off");
    return m;
}

/// n samples of the shape, uniform by area, with their faces' normals (seed 1).
const ks::PointCloud& samples(std::size_t n) {
    static std::map<std::size_t, ks::PointCloud> cache;
    if (auto it = cache.find(n); it != cache.end()) return it->second;
    const auto s = ks::detail::sample_surface(shape(), n, 1);
    ks::PointCloud c;
    c.points = s.points;
    for (const ks::Index f : s.faces) c.normals.push_back(ks::face_normal(shape(), f));
    return cache.emplace(n, std::move(c)).first->second;
}

double process_cpu_seconds() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
           1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

/// Mean distance from the reference shape to `m`, % of the diagonal; and whether m is
/// one closed manifold.
void accuracy(benchmark::State& state, const ks::IndexedMesh& m) {
    const auto t = ks::topology_report(m);
    state.counters["closed_components"] = t.closed && t.manifold ? static_cast<double>(t.components) : -1.0;
    if (m.faces.empty()) return;
    const auto d = ks::compare(m, shape(), {.samples = 200000});
    state.counters["ref_to_result_pct"] = 100 * d.relative(d.b_to_a).mean;
    state.counters["result_to_ref_pct"] = 100 * d.relative(d.a_to_b).mean;
}

void stage_counters(benchmark::State& state, const std::vector<ks::StageTiming>& t) {
    for (const auto& s : t) state.counters[s.stage + "_s"] = s.seconds;
}

// n_max sweep at 100K and 500K points: the fit only (offsets, octree, solves); the
// paper finds the optimum independent of N.
void BM_rbf_nmax(benchmark::State& state) {
    const auto& pts = samples(static_cast<std::size_t>(state.range(0)));
    const auto n_max = static_cast<std::size_t>(state.range(1));
    ks::RBFOctreeResult r;
    double cpu = 0;
    for (auto _ : state) {
        const double c0 = process_cpu_seconds();
        r = ks::RBFOctreeField::build(pts, {.n_max = n_max});
        cpu = process_cpu_seconds() - c0;
    }
    state.counters["cpu_s"] = cpu;
    state.counters["live_cells"] = static_cast<double>(r.stats.live_cells);
    state.counters["mean_centres"] = r.stats.mean_points_per_cell;
    state.counters["ill_conditioned"] = static_cast<double>(r.stats.ill_conditioned_cells);
    stage_counters(state, r.timings);
}
BENCHMARK(BM_rbf_nmax)->ArgsProduct({{100000, 500000}, {50, 100, 250, 500, 1000}})->Iterations(1)->UseRealTime()
    ->Unit(benchmark::kSecond);

/// Process CPU time per stage, read at each change of stage name in the progress
/// callback (called on the calling thread): counters "<stage>_cpu_s".
struct StageCpu {
    std::vector<std::pair<std::string, double>> marks;
    ks::RunControl control() {
        return {.progress = [this](const ks::ProgressEvent& e) {
            if (marks.empty() || marks.back().first != e.stage) marks.emplace_back(std::string(e.stage), process_cpu_seconds());
            return true;
        }};
    }
    void counters(benchmark::State& state, double end) const {
        for (std::size_t i = 0; i < marks.size(); ++i)
            if (marks[i].first != "done")
                state.counters[marks[i].first + "_cpu_s"] = (i + 1 < marks.size() ? marks[i + 1].second : end) - marks[i].second;
    }
};

// Time against N: the whole reconstruction at resolution 256 (defaults).
void BM_rbf_reconstruct(benchmark::State& state) {
    const auto& pts = samples(static_cast<std::size_t>(state.range(0)));
    ks::RBFReconstructResult r;
    double cpu = 0;
    StageCpu stages;
    for (auto _ : state) {
        stages.marks.clear();
        const double c0 = process_cpu_seconds();
        r = ks::reconstruct_rbf_octree(pts, {.control = stages.control()});
        cpu = process_cpu_seconds() - c0;
        stages.counters(state, c0 + cpu);
    }
    state.counters["cpu_s"] = cpu;
    state.counters["peak_rss_mb"] = ks::bench::peak_rss_mb();
    state.counters["live_cells"] = static_cast<double>(r.stats.live_cells);
    state.counters["evaluations"] = static_cast<double>(r.isosurface.field_evaluations);
    stage_counters(state, r.timings);
    accuracy(state, r.mesh);
}
BENCHMARK(BM_rbf_reconstruct)->Arg(100000)->Arg(500000)->Arg(1000000)->Iterations(1)->UseRealTime()
    ->Unit(benchmark::kSecond);

// Dense collinear points: a sphere of 3,000 random points plus N evenly spaced points
// on a segment through it (normals turning about the segment), fit only. The cost of
// every stage should grow linearly with N (docs/methods/rbf_octree.md, "Not done").
void BM_rbf_line(benchmark::State& state) {
    const auto n = static_cast<std::size_t>(state.range(0));
    ks::PointCloud c;
    std::uint64_t seed = 7;
    auto uniform = [&seed] { return static_cast<double>(ks::detail::splitmix64(seed++) >> 11) * 0x1p-53; };
    for (int i = 0; i < 3000; ++i) {
        const double z = 2 * uniform() - 1, a = 2 * 3.141592653589793 * uniform(), r = std::sqrt(1 - z * z);
        c.points.emplace_back(r * std::cos(a), r * std::sin(a), z);
        c.normals.push_back(c.points.back());
    }
    const ks::Vec3 a(-0.5, -0.3, -0.2), b(0.5, 0.3, 0.2);
    const ks::Vec3 n1 = (b - a).cross(ks::Vec3(0, 0, 1)).normalized(), n2 = (b - a).normalized().cross(n1);
    for (std::size_t i = 0; i < n; ++i) {
        c.points.push_back(a + (static_cast<double>(i) + 0.5) / static_cast<double>(n) * (b - a));
        c.normals.push_back(std::cos(0.7 * static_cast<double>(i)) * n1 + std::sin(0.7 * static_cast<double>(i)) * n2);
    }
    ks::RBFOctreeResult r;
    double cpu = 0;
    for (auto _ : state) {
        const double c0 = process_cpu_seconds();
        r = ks::RBFOctreeField::build(c);
        cpu = process_cpu_seconds() - c0;
    }
    state.counters["cpu_s"] = cpu;
    state.counters["cpu_us_per_point"] = 1e6 * cpu / static_cast<double>(c.points.size());
    state.counters["live_cells"] = static_cast<double>(r.stats.live_cells);
    state.counters["ill_conditioned"] = static_cast<double>(r.stats.ill_conditioned_cells);
    stage_counters(state, r.timings);
}
BENCHMARK(BM_rbf_line)->Arg(20000)->Arg(80000)->Arg(320000)->Iterations(1)->UseRealTime()->Unit(benchmark::kSecond);

// One global dense system over all 3N centres (what the octree avoids), and the octree
// fit at the same N.
void BM_dense_rbf(benchmark::State& state) {
    const auto& pts = samples(static_cast<std::size_t>(state.range(0)));
    // The centres of the octree fit (points and offsets), in one system.
    const auto fit = ks::RBFOctreeField::build(pts);
    const auto C = fit.field.centres();
    std::vector<double> v(C.size());
    for (std::size_t i = 0; i < C.size(); ++i) v[i] = fit.field(C[i]);  // 0 and ±d
    ks::BoundingBox box;
    for (const auto& c : C) box.extend(c);
    std::vector<ks::Vec3> u(C.size());
    for (std::size_t i = 0; i < C.size(); ++i) u[i] = (C[i] - box.center()) / box.diagonal();
    std::vector<double> w;
    Eigen::Vector4d a;
    for (auto _ : state) benchmark::DoNotOptimize(ks::detail::rbf_solve_cell(u, v, 0, w, a));
    state.counters["centres"] = static_cast<double>(C.size());
    state.counters["peak_rss_mb"] = ks::bench::peak_rss_mb();
}
BENCHMARK(BM_dense_rbf)->Arg(1000)->Arg(2000)->Arg(3000)->Iterations(1)->UseRealTime()->Unit(benchmark::kSecond);

void BM_rbf_fit(benchmark::State& state) {
    const auto& pts = samples(static_cast<std::size_t>(state.range(0)));
    for (auto _ : state) benchmark::DoNotOptimize(ks::RBFOctreeField::build(pts).status);
}
BENCHMARK(BM_rbf_fit)->Arg(1000)->Arg(2000)->Arg(3000)->Iterations(1)->UseRealTime()->Unit(benchmark::kSecond);

// CGAL's Poisson reconstruction (Kazhdan et al. 2006; CGAL 5.5, Delaunay refinement
// mesher, average spacing over 6 neighbours) on the same points.
void BM_cgal_poisson(benchmark::State& state) {
    using K = CGAL::Exact_predicates_inexact_constructions_kernel;
    using PN = std::pair<K::Point_3, K::Vector_3>;
    const auto& pts = samples(static_cast<std::size_t>(state.range(0)));
    std::vector<PN> pn;
    for (std::size_t i = 0; i < pts.points.size(); ++i)
        pn.emplace_back(K::Point_3(pts.points[i].x(), pts.points[i].y(), pts.points[i].z()),
                        K::Vector_3(pts.normals[i].x(), pts.normals[i].y(), pts.normals[i].z()));
    CGAL::Surface_mesh<K::Point_3> out;
    double cpu = 0;
    for (auto _ : state) {
        const double c0 = process_cpu_seconds();
        out.clear();
        const double spacing = CGAL::compute_average_spacing<CGAL::Sequential_tag>(
            pn, 6, CGAL::parameters::point_map(CGAL::First_of_pair_property_map<PN>()));
        CGAL::poisson_surface_reconstruction_delaunay(pn.begin(), pn.end(), CGAL::First_of_pair_property_map<PN>(),
                                                      CGAL::Second_of_pair_property_map<PN>(), out, spacing);
        cpu = process_cpu_seconds() - c0;
    }
    state.counters["cpu_s"] = cpu;
    state.counters["peak_rss_mb"] = ks::bench::peak_rss_mb();
    accuracy(state, ks::to_indexed_mesh(out));
}
BENCHMARK(BM_cgal_poisson)->Arg(100000)->Iterations(1)->UseRealTime()->Unit(benchmark::kSecond);

}  // namespace

int main(int argc, char** argv) {
    return ks::bench::run(argc, argv, [](const ks::bench::RatioReporter& r) {
        r.print_ratio("BM_rbf_reconstruct/100000", "BM_cgal_poisson/100000", "s");
        r.print_ratio("BM_rbf_fit/3000", "BM_dense_rbf/3000", "s");
    });
}
