// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// PU + graph-cut reconstruction against CGAL's Poisson surface reconstruction on the
// same inputs, in the same run: the bunny (../shared/data/cgal/meshes/bunny00.off)
// sampled at 100K and 2M oriented points with 0.1 % noise, 3 holes and 10 %
// outliers. Reports per-stage times, peak memory and accuracy (distances of the
// result to the true mesh, relative to its bounding-box diagonal) side by side.
#ifndef CGAL_EIGEN3_ENABLED
#define CGAL_EIGEN3_ENABLED 1
#endif

#include <benchmark/benchmark.h>

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/metrics/distance.hpp>
#include <kintsugi/metrics/topology_report.hpp>
#include <kintsugi/reconstruct/pu_graphcut.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/compute_average_spacing.h>
#include <CGAL/poisson_surface_reconstruction.h>
#include <CGAL/property_map.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <random>
#include <string>

namespace ks = kintsugi;

namespace {

const std::string kBunny = std::string(KINTSUGI_SHARED_DATA_DIR) + "/cgal/meshes/bunny00.off";

double peak_rss_mb() {
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
    return 0;
}

const ks::IndexedMesh& reference() {
    static const ks::IndexedMesh m = ks::read_mesh(kBunny);
    return m;
}

// 90 % area-weighted samples of the mesh (minus 3 holes of radius 4 % of the
// diagonal), Gaussian noise sigma = 0.1 % of the diagonal, and 10 % uniform outliers
// in the bounding box enlarged by 10 %, with random normals.
const ks::PointCloud& input(std::size_t n) {
    static std::map<std::size_t, ks::PointCloud> cache;
    auto it = cache.find(n);
    if (it != cache.end()) return it->second;
    const auto& ref = reference();
    const auto areas = ks::face_areas(ref);
    std::vector<double> cum(areas.size());
    std::partial_sum(areas.begin(), areas.end(), cum.begin());
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0, 1);
    std::normal_distribution<double> g(0, 1);
    ks::BoundingBox bb;
    for (const auto& v : ref.vertices) bb.extend(v);
    const double diag = bb.diagonal();
    std::vector<ks::Vec3> holes;
    for (int h = 0; h < 3; ++h) holes.push_back(ref.vertices[rng() % ref.vertices.size()]);
    ks::PointCloud pc;
    const auto n_surface = static_cast<std::size_t>(0.9 * static_cast<double>(n));
    while (pc.points.size() < n_surface) {
        const auto f = static_cast<std::size_t>(std::lower_bound(cum.begin(), cum.end(), u(rng) * cum.back()) -
                                                cum.begin());
        double a = u(rng), b = u(rng);
        if (a + b > 1) {
            a = 1 - a;
            b = 1 - b;
        }
        const auto& F = ref.faces[f];
        ks::Vec3 p = ref.vertices[F[0]] + a * (ref.vertices[F[1]] - ref.vertices[F[0]]) +
                     b * (ref.vertices[F[2]] - ref.vertices[F[0]]);
        bool in_hole = false;
        for (const auto& h : holes) in_hole = in_hole || (p - h).norm() < 0.04 * diag;
        if (in_hole) continue;
        p += 0.001 * diag / std::sqrt(3.0) * ks::Vec3(g(rng), g(rng), g(rng));
        pc.points.push_back(p);
        pc.normals.push_back(ks::face_normal(ref, f));
    }
    const ks::Vec3 c = bb.center(), e = 1.1 * bb.extent();
    while (pc.points.size() < n) {
        pc.points.push_back(c + ks::Vec3((u(rng) - .5) * e.x(), (u(rng) - .5) * e.y(), (u(rng) - .5) * e.z()));
        pc.normals.push_back(ks::Vec3(g(rng), g(rng), g(rng)).normalized());
    }
    return cache.emplace(n, std::move(pc)).first->second;
}

void accuracy_counters(benchmark::State& state, const ks::IndexedMesh& result) {
    const auto rep = ks::topology_report(result);
    state.counters["components"] = static_cast<double>(rep.components);
    state.counters["closed_manifold"] = rep.closed && rep.manifold ? 1 : 0;
    state.counters["faces"] = static_cast<double>(rep.faces);
    if (result.faces.empty()) return;
    const auto d = ks::compare(result, reference(), {.samples = 200000});
    const auto ab = d.relative(d.a_to_b), ba = d.relative(d.b_to_a);
    state.counters["mean_to_truth_%"] = 100 * ab.mean;
    state.counters["hausdorff_to_truth_%"] = 100 * ab.hausdorff;
    state.counters["mean_truth_to_result_%"] = 100 * ba.mean;
    state.counters["area_ratio"] = [&] {
        const auto ar = ks::face_areas(result), at = ks::face_areas(reference());
        return std::accumulate(ar.begin(), ar.end(), 0.0) / std::accumulate(at.begin(), at.end(), 0.0);
    }();
}

bool have_data(benchmark::State& state) {
    if (std::filesystem::exists(kBunny)) return true;
    state.SkipWithError(("skipped: " + kBunny + " not found (needs ../shared/data)").c_str());
    return false;
}

void BM_PUGraphcut(benchmark::State& state) {
    if (!have_data(state)) return;
    const auto& pts = input(static_cast<std::size_t>(state.range(0)));
    ks::PUGraphcutResult r;
    for (auto _ : state) {
        const auto t0 = std::chrono::steady_clock::now();
        r = ks::reconstruct_pu_graphcut(pts, {.max_level = static_cast<int>(state.range(1))});
        state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    for (const auto& t : r.timings) state.counters["s_" + t.stage] = t.seconds;
    state.counters["supports"] = static_cast<double>(r.supports);
    state.counters["graph_nodes"] = static_cast<double>(r.graph_nodes);
    state.counters["peak_rss_MB"] = peak_rss_mb();
    accuracy_counters(state, r.mesh);
}

void BM_CGALPoisson(benchmark::State& state) {
    if (!have_data(state)) return;
    using K = CGAL::Exact_predicates_inexact_constructions_kernel;
    using PN = std::pair<K::Point_3, K::Vector_3>;
    const auto& pts = input(static_cast<std::size_t>(state.range(0)));
    std::vector<PN> pn(pts.points.size());
    for (std::size_t i = 0; i < pn.size(); ++i)
        pn[i] = {K::Point_3(pts.points[i].x(), pts.points[i].y(), pts.points[i].z()),
                 K::Vector_3(pts.normals[i].x(), pts.normals[i].y(), pts.normals[i].z())};
    CGAL::Surface_mesh<K::Point_3> out;
    bool ok = false;
    for (auto _ : state) {
        out.clear();
        const auto t0 = std::chrono::steady_clock::now();
        try {
            const double spacing = CGAL::compute_average_spacing<CGAL::Sequential_tag>(
                pn, 6, CGAL::parameters::point_map(CGAL::First_of_pair_property_map<PN>()));
            ok = CGAL::poisson_surface_reconstruction_delaunay(pn.begin(), pn.end(),
                                                               CGAL::First_of_pair_property_map<PN>(),
                                                               CGAL::Second_of_pair_property_map<PN>(), out, spacing);
        } catch (const std::exception& e) {
            std::fprintf(stderr, "CGAL Poisson threw: %s\n", e.what());
            ok = false;
        }
        state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    state.counters["poisson_ok"] = ok ? 1 : 0;
    state.counters["peak_rss_MB"] = peak_rss_mb();
    if (!ok || out.number_of_faces() == 0) {
        state.counters["components"] = 0;
        return;
    }
    accuracy_counters(state, ks::to_indexed_mesh(out));
}

}  // namespace

// args: points, max_level
BENCHMARK(BM_PUGraphcut)->Args({100000, 8})->Unit(benchmark::kSecond)->UseManualTime()->Iterations(1);
BENCHMARK(BM_CGALPoisson)->Args({100000, 0})->Unit(benchmark::kSecond)->UseManualTime()->Iterations(1);
BENCHMARK(BM_PUGraphcut)->Args({2000000, 9})->Unit(benchmark::kSecond)->UseManualTime()->Iterations(1);
BENCHMARK(BM_CGALPoisson)->Args({2000000, 0})->Unit(benchmark::kSecond)->UseManualTime()->Iterations(1);

BENCHMARK_MAIN();
