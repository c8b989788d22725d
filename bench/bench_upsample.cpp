// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// fill_surfel_gaps (upsample/surfel_fill.hpp): the paper's sphere cases, a 134K-point
// model at 0.0012 of the diagonal (the paper's igea: 134,344 -> 419,779 surfels in
// 22.6 s), and CGAL's edge_aware_upsample_point_set on a small scan with holes wider
// than its neighbourhood (coverage of the holes and time of both printed).
// Figures: docs/methods/surfel_upsampling.md.
#include "common.hpp"

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/metrics/distance.hpp>
#include <kintsugi/metrics/surfel_coverage.hpp>
#include <kintsugi/upsample/surfel_fill.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/edge_aware_upsample_point_set.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <utility>
#include <vector>

namespace ks = kintsugi;

namespace {

ks::PointCloud fibonacci_sphere(std::size_t n) {
    ks::PointCloud c;
    const double golden = std::numbers::pi * (3 - std::sqrt(5.0));
    for (std::size_t i = 0; i < n; ++i) {
        const double z = 1 - (2 * static_cast<double>(i) + 1) / static_cast<double>(n);
        const double rho = std::sqrt(1 - z * z), phi = golden * static_cast<double>(i);
        c.points.emplace_back(rho * std::cos(phi), rho * std::sin(phi), z);
        c.normals.push_back(c.points.back());
    }
    return c;
}

void fill_sphere(benchmark::State& state, double radius_rel) {
    const ks::PointCloud in = fibonacci_sphere(154);
    ks::SurfelFillResult r;
    for (auto _ : state) r = ks::fill_surfel_gaps(in, {.radius_rel = radius_rel});
    const ks::SurfelCoverage cov = ks::surfel_coverage(r.surfels, fibonacci_sphere(200000));
    state.counters["surfels"] = static_cast<double>(r.surfels.points.size());
    state.counters["coverage_pct"] = 100 * cov.fraction;
}
void BM_sphere_0_018(benchmark::State& state) { fill_sphere(state, 0.018); }
void BM_sphere_0_010(benchmark::State& state) { fill_sphere(state, 0.010); }
BENCHMARK(BM_sphere_0_018)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(BM_sphere_0_010)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

/// 134,344 points (igea's count) uniform by area on the closed bunny00 mesh, with face normals.
bool model_134k(ks::PointCloud& c, ks::IndexedMesh& mesh) {
    const auto path = std::filesystem::path(KINTSUGI_SHARED_DATA_DIR) / "cgal/meshes/bunny00.off";
    if (!std::filesystem::exists(path)) return false;
    mesh = ks::read_mesh(path);
    const auto s = ks::detail::sample_surface(mesh, 134344, 7);
    c.points = s.points;
    for (ks::Index f : s.faces) {
        const ks::Face& t = mesh.faces[f];
        c.normals.push_back((mesh.vertices[t[1]] - mesh.vertices[t[0]]).cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]).normalized());
    }
    return true;
}

void BM_model_134k_0_0012(benchmark::State& state) {
    ks::PointCloud in;
    ks::IndexedMesh mesh;
    if (!model_134k(in, mesh)) {
        state.SkipWithError("../shared/data/cgal/meshes/bunny00.off not found");
        return;
    }
    ks::SurfelFillResult r;
    for (auto _ : state) r = ks::fill_surfel_gaps(in, {.radius_rel = 0.0012});
    const auto dense = ks::detail::sample_surface(mesh, 1000000, 99);
    const ks::SurfelCoverage cov = ks::surfel_coverage(r.surfels, dense.points);
    state.counters["surfels"] = static_cast<double>(r.surfels.points.size());
    state.counters["coverage_pct"] = 100 * cov.fraction;
    state.counters["verified"] = r.coverage_verified ? 1 : 0;
}
// The fill runs in parallel: wall time, and the CPU time of all threads.
BENCHMARK(BM_model_134k_0_0012)->Unit(benchmark::kMillisecond)->Iterations(1)->MeasureProcessCPUTime()->UseRealTime();

/// The kitten scan (tests/data, 5,210 points), every second point, with 3 holes of
/// radius 4 % of the diagonal: kintsugi at radius 0.01 of the diagonal, CGAL's
/// edge_aware_upsample_point_set to 4x the points; the share of the removed points
/// (the true surface in the holes) that disks of that radius around either output cover.
struct HoleyKitten {
    ks::PointCloud kept;
    std::vector<ks::Vec3> removed;
    double diag = 0;
};
HoleyKitten holey_kitten() {
    const ks::PointCloud full = ks::read_point_cloud(std::filesystem::path(KINTSUGI_TEST_DATA_DIR) / "kitten.xyz");
    HoleyKitten h;
    ks::BoundingBox box;
    for (const ks::Vec3& p : full.points) box.extend(p);
    h.diag = box.diagonal();
    const std::size_t centres[3] = {500, 2500, 4500};
    for (std::size_t i = 0; i < full.points.size(); i += 2) {
        bool hole = false;
        for (std::size_t c : centres) hole = hole || (full.points[i] - full.points[c]).norm() < 0.04 * h.diag;
        if (hole) {
            h.removed.push_back(full.points[i]);
        } else {
            h.kept.points.push_back(full.points[i]);
            h.kept.normals.push_back(full.normals[i]);
        }
    }
    return h;
}

void BM_kintsugi_holes(benchmark::State& state) {
    const HoleyKitten h = holey_kitten();
    ks::SurfelFillResult r;
    for (auto _ : state) r = ks::fill_surfel_gaps(h.kept, {.radius_rel = 0.01});
    state.counters["points_out"] = static_cast<double>(r.surfels.points.size());
    state.counters["hole_coverage_pct"] = 100 * ks::surfel_coverage(r.surfels, h.removed).fraction;
}
BENCHMARK(BM_kintsugi_holes)->Unit(benchmark::kMillisecond);

void BM_cgal_edge_aware_holes(benchmark::State& state) {
    using K = CGAL::Exact_predicates_inexact_constructions_kernel;
    using PN = std::pair<K::Point_3, K::Vector_3>;
    const HoleyKitten h = holey_kitten();
    std::vector<PN> in;
    for (std::size_t i = 0; i < h.kept.points.size(); ++i) {
        const ks::Vec3& p = h.kept.points[i];
        const ks::Vec3& n = h.kept.normals[i];
        in.emplace_back(K::Point_3(p.x(), p.y(), p.z()), K::Vector_3(n.x(), n.y(), n.z()));
    }
    std::vector<PN> out;
    for (auto _ : state) {
        out.clear();
        CGAL::edge_aware_upsample_point_set<CGAL::Parallel_if_available_tag>(
            in, std::back_inserter(out),
            CGAL::parameters::point_map(CGAL::First_of_pair_property_map<PN>())
                .normal_map(CGAL::Second_of_pair_property_map<PN>())
                .number_of_output_points(4 * in.size()));
    }
    ks::PointCloud disks = h.kept;
    for (const PN& pn : out) {
        disks.points.emplace_back(pn.first.x(), pn.first.y(), pn.first.z());
        disks.normals.emplace_back(pn.second.x(), pn.second.y(), pn.second.z());
    }
    disks.radii.assign(disks.points.size(), 0.01 * h.diag);
    state.counters["points_out"] = static_cast<double>(disks.points.size());
    state.counters["hole_coverage_pct"] = 100 * ks::surfel_coverage(disks, h.removed).fraction;
}
BENCHMARK(BM_cgal_edge_aware_holes)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace

int main(int argc, char** argv) {
    return ks::bench::run(argc, argv, [](const ks::bench::RatioReporter& r) {
        r.print_ratio("BM_kintsugi_holes", "BM_cgal_edge_aware_holes");
    });
}
