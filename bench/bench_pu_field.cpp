// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Octree and PU field (steps 1-3 of the PU + graph-cut reconstruction), with peers
// measured in the same run:
//   - Octree build vs CGAL::Octree (refine to the same depth, bucket 1, then grade()
//     for the same 2:1 balance);
//   - PUField::build vs CGAL's Poisson_reconstruction_function::compute_implicit_function
//     (the implicit-field step of CGAL's Poisson reconstruction) on 100K points;
//   - PUField::values vs the Poisson function's evaluation at the same points.
// Inputs: a torus sampled with 0.1 % noise and 10 % uniform outliers (synthetic,
// seeded: 100K and 2M points), and the Stanford bunny vertices with normals from
// ../shared/data (skipped with a message when missing).
// Run: bench_pu_field --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include "common.hpp"

#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/reconstruct/pu_field.hpp>
#include <kintsugi/spatial/octree.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Octree.h>
#include <CGAL/Poisson_reconstruction_function.h>
#include <CGAL/property_map.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <utility>
#include <vector>

namespace ks = kintsugi;
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Vector = Kernel::Vector_3;
using PointWithNormal = std::pair<Point, Vector>;

namespace {

struct Input {
    std::vector<ks::Vec3> points, normals;  // outward normals
    bool ok = false;
};

// Torus R = 1, r = 0.4 (uniform area density), Gaussian noise of 0.1 % of the
// bounding-box diagonal, plus 10 % uniform outliers in the bounding box enlarged by 10 %.
Input make_torus(std::size_t n, std::uint64_t seed) {
    Input in;
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> g;
    std::uniform_real_distribution<double> ang(0, 2 * M_PI), acc(0, 1);
    const double R = 1, r = 0.4;
    const double diag = std::sqrt(2.8 * 2.8 * 2 + 0.8 * 0.8);
    const double sigma = 1e-3 * diag;
    while (in.points.size() < n) {
        const double a = ang(rng), b = ang(rng);
        if (acc(rng) > (R + r * std::cos(b)) / (R + r)) continue;
        const ks::Vec3 nn(std::cos(a) * std::cos(b), std::sin(a) * std::cos(b), std::sin(b));
        in.points.push_back(ks::Vec3(R * std::cos(a), R * std::sin(a), 0) + r * nn +
                            sigma * ks::Vec3(g(rng), g(rng), g(rng)));
        in.normals.push_back(nn);
    }
    std::uniform_real_distribution<double> ux(-1.54, 1.54), uz(-0.44, 0.44);
    for (std::size_t i = 0; i < n / 10; ++i) {
        in.points.emplace_back(ux(rng), ux(rng), uz(rng));
        in.normals.push_back(ks::Vec3(g(rng), g(rng), g(rng)).normalized());
    }
    in.ok = true;
    return in;
}

Input load_bunny() {
    Input in;
    const std::filesystem::path f = std::filesystem::path(KINTSUGI_SHARED_DATA_DIR) /
                                    "stanford_bunny/reconstruction/bun_zipper_points_normals.xyz";
    std::ifstream s(f);
    double a[6];
    while (s >> a[0] >> a[1] >> a[2] >> a[3] >> a[4] >> a[5]) {
        in.points.emplace_back(a[0], a[1], a[2]);
        in.normals.emplace_back(a[3], a[4], a[5]);
    }
    in.ok = !in.points.empty();
    return in;
}

const Input& input(const std::string& name) {
    static std::map<std::string, Input> cache;
    auto it = cache.find(name);
    if (it != cache.end()) return it->second;
    Input in;
    if (name == "torus100k")
        in = make_torus(100000, 1);
    else if (name == "torus2m")
        in = make_torus(2000000, 2);
    else if (name == "bunny")
        in = load_bunny();
    return cache.emplace(name, std::move(in)).first->second;
}

void set_stage_counters(benchmark::State& state, const ks::PUFieldResult& r) {
    state.counters["points"] = double(r.points);
    state.counters["cells"] = double(r.octree_cells);
    state.counters["supports"] = double(r.supports);
    state.counters["fits"] = double(r.fits_evaluated);
    for (const auto& t : r.timings) state.counters[t.stage + "_s"] = t.seconds;
}

// ------------------------------------------------------------------ octree
void BM_Octree_kintsugi(benchmark::State& state, const std::string& name, int level) {
    const Input& in = input(name);
    if (!in.ok) {
        state.SkipWithError("input missing (../shared/data not present)");
        return;
    }
    std::size_t cells = 0;
    for (auto _ : state) {
        ks::Octree t(in.points, {.max_level = level});
        cells = t.size();
        benchmark::DoNotOptimize(cells);
    }
    state.counters["points"] = double(in.points.size());
    state.counters["cells"] = double(cells);
}

void BM_Octree_CGAL(benchmark::State& state, const std::string& name, int level) {
    const Input& in = input(name);
    if (!in.ok) {
        state.SkipWithError("input missing (../shared/data not present)");
        return;
    }
    std::vector<Point> pts;
    pts.reserve(in.points.size());
    for (const auto& p : in.points) pts.emplace_back(p.x(), p.y(), p.z());
    std::size_t leaves = 0;
    for (auto _ : state) {
        CGAL::Octree<Kernel, std::vector<Point>> oct(pts);
        oct.refine(std::size_t(level), 1);
        oct.grade();
        leaves = 0;
        for (auto node : oct.traverse<CGAL::Orthtrees::Leaves_traversal>()) {
            (void)node;
            ++leaves;
        }
        benchmark::DoNotOptimize(leaves);
    }
    state.counters["points"] = double(in.points.size());
    state.counters["cells"] = double(leaves);
}

// ------------------------------------------------------------------ PU field
void BM_PUField_build(benchmark::State& state, const std::string& name, int level) {
    const Input& in = input(name);
    if (!in.ok) {
        state.SkipWithError("input missing (../shared/data not present)");
        return;
    }
    ks::PUFieldResult last;
    for (auto _ : state) {
        last = ks::PUField::build(ks::with_normals(in.points, in.normals), {.max_level = level});
        benchmark::DoNotOptimize(last.supports);
    }
    set_stage_counters(state, last);
}

void BM_Poisson_implicit_function(benchmark::State& state, const std::string& name) {
    const Input& in = input(name);
    if (!in.ok) {
        state.SkipWithError("input missing (../shared/data not present)");
        return;
    }
    std::vector<PointWithNormal> pwn;
    for (std::size_t i = 0; i < in.points.size(); ++i)
        pwn.emplace_back(Point(in.points[i].x(), in.points[i].y(), in.points[i].z()),
                         Vector(in.normals[i].x(), in.normals[i].y(), in.normals[i].z()));
    bool ok = true;
    for (auto _ : state) {
        CGAL::Poisson_reconstruction_function<Kernel> f(pwn.begin(), pwn.end(),
                                                        CGAL::First_of_pair_property_map<PointWithNormal>(),
                                                        CGAL::Second_of_pair_property_map<PointWithNormal>());
        ok = f.compute_implicit_function();
        benchmark::DoNotOptimize(ok);
    }
    if (!ok) state.SkipWithError("CGAL Poisson: compute_implicit_function failed");
    state.counters["points"] = double(in.points.size());
}

// Evaluation speed at 1M points in the bounding box (PU: parallel batch).
void BM_PUField_values(benchmark::State& state, const std::string& name) {
    const Input& in = input(name);
    const auto r = ks::PUField::build(ks::with_normals(in.points, in.normals), {.max_level = 8});
    std::vector<ks::Vec3> xs(1000000);
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(0, 1);
    const ks::BoundingBox box = r.field.bounding_box();
    for (auto& x : xs) x = box.min + box.extent().cwiseProduct(ks::Vec3(u(rng), u(rng), u(rng)));
    for (auto _ : state) {
        auto v = r.field.values(xs);
        benchmark::DoNotOptimize(v.data());
    }
    state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(xs.size()));
}

void BM_Poisson_values(benchmark::State& state, const std::string& name) {
    const Input& in = input(name);
    std::vector<PointWithNormal> pwn;
    for (std::size_t i = 0; i < in.points.size(); ++i)
        pwn.emplace_back(Point(in.points[i].x(), in.points[i].y(), in.points[i].z()),
                         Vector(in.normals[i].x(), in.normals[i].y(), in.normals[i].z()));
    CGAL::Poisson_reconstruction_function<Kernel> f(pwn.begin(), pwn.end(),
                                                    CGAL::First_of_pair_property_map<PointWithNormal>(),
                                                    CGAL::Second_of_pair_property_map<PointWithNormal>());
    if (!f.compute_implicit_function()) {
        state.SkipWithError("CGAL Poisson: compute_implicit_function failed");
        return;
    }
    std::vector<Point> xs(100000);
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(0, 1);
    for (auto& x : xs) x = Point(-1.54 + 3.08 * u(rng), -1.54 + 3.08 * u(rng), -0.44 + 0.88 * u(rng));
    for (auto _ : state) {
        double s = 0;
        for (const auto& x : xs) s += f(x);
        benchmark::DoNotOptimize(s);
    }
    state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(xs.size()));
}

}  // namespace

BENCHMARK_CAPTURE(BM_Octree_kintsugi, torus2m_L8, std::string("torus2m"), 8)->Unit(benchmark::kMillisecond)->Iterations(2);
BENCHMARK_CAPTURE(BM_Octree_CGAL, torus2m_L8, std::string("torus2m"), 8)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK_CAPTURE(BM_Octree_kintsugi, bunny_L8, std::string("bunny"), 8)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Octree_CGAL, bunny_L8, std::string("bunny"), 8)->Unit(benchmark::kMillisecond);

BENCHMARK_CAPTURE(BM_PUField_build, bunny_L8, std::string("bunny"), 8)->Unit(benchmark::kMillisecond)->Iterations(2);
BENCHMARK_CAPTURE(BM_Poisson_implicit_function, bunny, std::string("bunny"))->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK_CAPTURE(BM_PUField_build, torus100k_L8, std::string("torus100k"), 8)->Unit(benchmark::kMillisecond)->Iterations(2);
BENCHMARK_CAPTURE(BM_Poisson_implicit_function, torus100k, std::string("torus100k"))->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK_CAPTURE(BM_PUField_build, torus2m_L8, std::string("torus2m"), 8)->Unit(benchmark::kMillisecond)->Iterations(1);

BENCHMARK_CAPTURE(BM_PUField_values, torus100k, std::string("torus100k"))->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK_CAPTURE(BM_Poisson_values, torus100k, std::string("torus100k"))->Unit(benchmark::kMillisecond)->Iterations(3);

int main(int argc, char** argv) {
    if (!std::filesystem::exists(std::filesystem::path(KINTSUGI_SHARED_DATA_DIR) /
                                 "stanford_bunny/reconstruction/bun_zipper_points_normals.xyz"))
        std::printf("note: %s not found; the bunny benchmarks are skipped\n", KINTSUGI_SHARED_DATA_DIR);
    return ks::bench::run(argc, argv, [](const ks::bench::RatioReporter& r) {
        std::printf("\nSame run, real time (ratio > 1: kintsugi faster):\n");
        for (const char* in : {"torus2m_L8", "bunny_L8"})
            r.print_ratio(std::string("BM_Octree_kintsugi/") + in, std::string("BM_Octree_CGAL/") + in);
        for (const char* in : {"bunny", "torus100k"})
            r.print_ratio(std::string("BM_PUField_build/") + in + "_L8", std::string("BM_Poisson_implicit_function/") + in);
        const double pu = r.counter("BM_PUField_values/torus100k", "items_per_second"),
                     po = r.counter("BM_Poisson_values/torus100k", "items_per_second");
        if (pu > 0 && po > 0)
            std::printf("  evaluation: PUField::values %.3g /s (parallel) vs Poisson function %.3g /s (1 thread): %.2fx\n",
                        pu, po, pu / po);
    });
}
