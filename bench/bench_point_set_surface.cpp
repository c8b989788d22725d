// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Projection throughput of the MLS point-set surface (field/point_set_surface.hpp):
// every sample of a noisy sphere (20K points, 0.5 % noise of the diagonal, exact
// normals) projected onto the surface of the set, APSS and plane MLS, k = 40 (the
// default) and 80 (the noisy-data setting), single-threaded and on all cores.
// Items per second = projections per second. Building the PointSetSurface (its
// kd-tree) is timed separately. Figures: docs/methods/point_set_surface.md.
//
// Measured 2026-12-01 on the 2-core machine under load ~10 (wall times 4-5x the CPU
// times; single-thread CPU times are the reliable figures), 20K projections:
//   APSS k 40   208 ms CPU (96K/s, 3.86 steps each)    plane k 40  196 ms (3.86 steps)
//   APSS k 80   382 ms CPU (52K/s, 3.28 steps each)    build (kd-tree, 20K points) 2.8 ms
#include <benchmark/benchmark.h>

#include "common.hpp"

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/field/point_set_surface.hpp>

#include <cmath>
#include <random>
#include <vector>

namespace ks = kintsugi;

namespace {

const ks::PointCloud& noisy_sphere() {
    static const ks::PointCloud cloud = [] {
        std::mt19937_64 rng(1);
        std::normal_distribution<double> g(0, 1);
        const double sigma = 0.005 * 2 * std::sqrt(3.0) / std::sqrt(3.0);  // RMS 0.5 % of the diagonal
        ks::PointCloud c;
        while (c.points.size() < 20000) {
            const ks::Vec3 d(g(rng), g(rng), g(rng));
            if (d.norm() < 1e-9) continue;
            c.normals.push_back(d.normalized());
            c.points.push_back(d.normalized() + sigma * ks::Vec3(g(rng), g(rng), g(rng)));
        }
        return c;
    }();
    return cloud;
}

void BM_project(benchmark::State& state) {
    const auto& cloud = noisy_sphere();
    const ks::PointSetSurfaceParams p{.k = static_cast<std::size_t>(state.range(0)),
                                      .fit = state.range(1) ? ks::PointSetSurfaceFit::plane
                                                            : ks::PointSetSurfaceFit::apss};
    ks::ThreadLimit limit(static_cast<int>(state.range(2)));
    std::size_t iterations = 0;
    for (auto _ : state) {
        auto r = ks::project_onto_point_set_surface(cloud, cloud, p);
        iterations = r.total_iterations;
        benchmark::DoNotOptimize(r.points.data());
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * cloud.points.size()));
    state.counters["steps_per_query"] = double(iterations) / double(cloud.points.size());
}
// Args: k, fit (0 apss, 1 plane), threads (0 = all).
BENCHMARK(BM_project)
    ->Args({40, 0, 1})
    ->Args({40, 0, 0})
    ->Args({40, 1, 1})
    ->Args({80, 0, 1})
    ->Args({80, 0, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_build(benchmark::State& state) {
    const auto& cloud = noisy_sphere();
    for (auto _ : state) {
        ks::PointSetSurface mls(cloud);
        benchmark::DoNotOptimize(&mls);
    }
}
BENCHMARK(BM_build)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
    return ks::bench::run(argc, argv);
}
