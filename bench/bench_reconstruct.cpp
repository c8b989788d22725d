// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// PU + graph-cut reconstruction against CGAL's Poisson surface reconstruction on the
// same inputs, in the same run: the bunny (../shared/data/cgal/meshes/bunny00.off)
// sampled at 100K, 2M and 10M oriented points with 0.1 % noise, 3 holes and 10 %
// outliers (PU at octree level 8 for 100K, 9 for 2M, 10 for 10M, as in the paper for
// the size of the data; Poisson at 100K and 2M). Reports wall and CPU time, per-stage
// times and peak memory (the resident peak is reset at each stage's start), peak memory and
// accuracy (distances of the result to the true mesh and back, relative to its
// bounding-box diagonal; components; closed and manifold; area ratio) side by side,
// with ratios, in a table at the end.
//
// Each reconstruction runs in a child process (fork) that builds its input itself:
// its peak resident set (VmHWM) is its own, and a peer that aborts, throws, runs out
// of memory or runs too long is recorded as such instead of taking the benchmark
// down. Limits per run: KINTSUGI_BENCH_TIMEOUT seconds (default 900) and
// KINTSUGI_BENCH_MEMORY_GB of address space (default 12). The parent process never
// starts the thread pool (forking a process that runs TBB threads is unsafe).
//
// Run: bench_reconstruct [--benchmark_filter=100000] (the 10M run alone: --benchmark_filter=10000000)
//
// Measured 2026-12-01 13:21 UTC on this 2-core machine with no other process running
// (load average 0.7-1.1), PU+graph-cut with its defaults untrusted_weight = 1e-3 and
// fill_radius_fraction = 0.75; CGAL Poisson's column from the run of 2026-11-23 19:05 UTC
// (load 0.6-2.7; same input). Wall / CPU seconds, peak RSS of the run's process:
//   100K points        PU+graph-cut   CGAL Poisson   Poisson / PU
//     wall / CPU (s)    2.19 / 3.03    41.0 / 41.0    19x wall
//     peak RSS (MB)     182            663            3.6x
//     components        1              15
//     closed manifold   yes (genus 0)  no (genus sum 441)
//     mean to truth     0.036 %        16.3 %         455x
//     Hausdorff         1.27 %         71.6 %
//     truth to result   0.037 %        0.056 %
//     area / true area  0.996          14.6
//     (Poisson's run under load gave 18 components, Hausdorff 59.9 %: not repeatable)
//     PU stages (wall s): pu_octree 0.21, pu_cover 0.71, pu_index 0.03, triangulation
//     0.93, graph_cut 0.11, marching_tetrahedra 0.16, smoothing 0.03 (with the fill).
//     Three other runs the same day: 1.75-2.28 s wall.
//   2M points (PU at level 9): PU+graph-cut 30.1 s wall / 41.9 s CPU, peak RSS 2.0 GB
//     (1993 MB), 1 closed manifold component (genus 0), mean to truth 0.013 %,
//     Hausdorff 0.82 %, truth to result 0.013 %, area ratio 1.003; stages: pu_octree
//     2.63, pu_cover 9.56, pu_index 0.30, triangulation 13.70, graph_cut 2.27,
//     marching_tetrahedra 1.32, smoothing 0.14 (with the fill). A second quiet run:
//     33.7 s / 46.1 s (pu_cover 10.51, triangulation 16.45).
//     Before the two defaults (2026-11-23, quiet): 100K 1.91 s / 2.67 s, 181 MB, mean
//     0.040 %, Hausdorff 1.63 %; 2M 27.0 s / 37.4 s, 2.0 GB, mean 0.024 %, Hausdorff
//     3.1 %, area ratio 1.013, smoothing 0.06 s. The fill adds about 0.08 s at 2M; the
//     rest of the difference lies in pu_octree, pu_cover and triangulation (2.05, 8.79
//     and 12.06 s then), which the two defaults do not touch.
//     CGAL Poisson at 2M (2026-11-23): not finished after 901 s wall / 819 s CPU, 8.9 GB
//     resident and growing, when killed at the time limit: > 29x the PU wall time, > 4.4x
//     its memory.
// With step 8 (the refinement to the samples' spacing), 2026-12-03 17:31 UTC, idle VM, a
// 20-point MLS fit: 100K 3.13 s wall / 4.58 s CPU, 192 MB, mean 0.0164 %, Hausdorff 1.27 %,
// truth to result 0.0176 %, refine 0.88 s; 2M 62.4 s / 95.3 s, 2.27 GB, mean 0.0172 %,
// Hausdorff 0.84 %, area ratio 1.071 (the fit followed the noise), stages pu_octree 2.59,
// pu_cover 9.07, pu_index 0.58, triangulation 16.26, graph_cut 3.10, marching_tetrahedra
// 1.72, smoothing 0.18, handles 0.11, refine 28.29. Step 8 has since widened its fit for
// data denser than their noise (docs/methods/pu_graphcut.md: the CLI on the same recipe,
// 89 neighbours, mean 0.0090 %, refine 59 s).
// 2026-12-04 00:34-01:10 UTC, idle VM: before (k = 89 raw samples per fit): 2M 69.8 s wall /
// 101.1 s CPU, 2.27 GB, mean 0.0089 %, Hausdorff 1.03 %, truth to result 0.0083 %; stages
// pu_octree 6.27, pu_cover 8.81, pu_index 0.68, triangulation 14.42, graph_cut 5.09,
// marching_tetrahedra 1.60, smoothing 0.20, handles 0.07, refine 31.45. After (step 8 fits
// k = 20 means of groups of noisy samples, its noise estimate from at most 2^18 inliers; the
// triangulation's edges taken from its tets): 2M 31.4 s wall / 42.8 s CPU, 2.05 GB, mean
// 0.0093 %, Hausdorff 0.84 %, truth to result 0.0087 %, area ratio 1.005; stages pu_octree
// 5.28, pu_cover 7.48, pu_index 0.54, triangulation 6.66, graph_cut 4.40,
// marching_tetrahedra 1.31, smoothing 0.10, handles 0.05, refine 4.65. 100K unchanged
// in output: 2.51 s wall / 3.42 s CPU, 190 MB, mean 0.0164 %, triangulation 0.47 s.
// Then with groups of one sample dropped (isolated outliers): 2M 31.1 s / 42.1 s, 2.05 GB,
// mean 0.0081 %, Hausdorff 0.632 %, truth to result 0.0082 %, area ratio 1.002; stages
// pu_octree 5.35, pu_cover 8.09, pu_index 0.55, triangulation 6.47, graph_cut 4.25,
// marching_tetrahedra 1.23, smoothing 0.12, handles 0.05, refine 4.02. 10M 153.0 s / 204.5 s,
// 8.1 GB, mean 0.0079 %, Hausdorff 1.039 %, truth to result 0.0079 %, area ratio 1.008;
// stages (wall s / peak MB) pu_octree 40.51 / 7273, pu_cover 36.81 / 5620, pu_index 1.61 /
// 5590, triangulation 24.98 / 5530, graph_cut 16.84 / 6319, marching_tetrahedra 3.37 /
// 8098, smoothing 0.18 / 6722, handles 0.10 / 6304, refine 24.02 / 6304 (without step 8:
// mean 0.0119 %, Hausdorff 0.682 %). With the spike guard of step 8 (a driver with this
// bench's recipe, not this bench): 10M mean 0.0079 %, Hausdorff 0.667 %, truth to result
// 0.0079 %; 2M 0.0081 / 0.632 / 0.0082 %.
// 2026-12-04 16:00-17:00 UTC (stop 37; docs/methods/pu_graphcut.md, "2M points: time and memory"):
// octree leaves in one walk, the octree released after the cover, a slimmer flow network, large
// buffers on huge pages, freed memory returned before the cut; output unchanged. Runs of that hour
// on the same VM (which varied by 30 %): 2M 27.3 s wall / 39.3 s CPU, 1182 MB; 27.7 s / 40.7 s,
// 1182 MB; 32.0 s / 44.8 s, 1144 MB (stages pu_octree 2.51, pu_cover 8.62, pu_index 0.58,
// triangulation 8.33, graph_cut 3.26, marching_tetrahedra 1.80, smoothing 0.11, handles 0.09,
// refine 5.71); 100K 1.91-2.77 s, 148 MB (was 190 MB). (The per-stage peaks printed until
// then were shifted by one stage: the PU field's "done" event counted as a stage. The run's
// peak was right.)
// 2026-12-04 19:20 UTC (stop 38; docs/methods/pu_graphcut.md, "2M points: concurrency, Morton
// order, huge pages"): step 8's data side and the terminal values made during CGAL's insertion,
// in Morton order; output unchanged. Without use_huge_page_malloc (KINTSUGI_NO_HUGE_PAGES=1):
// 2M 25.46 s / 41.16 s CPU, 1035 MB and 24.92 s / 39.64 s, 1035 MB (stages pu_octree 1.58 / 791,
// pu_cover 8.21 / 1035, pu_index 0.47 / 683, triangulation 6.48 / 941, graph_cut 3.40 / 1013,
// marching_tetrahedra 1.69 / 894, smoothing 0.19, handles 0.09, refine 2.00 / 649); 100K 2.47 s,
// 119 MB. With it (this program's default): 2M 21.25 s / 35.30 s, 1037 MB and 20.94 s / 35.86 s,
// 1111 MB (pu_octree 1.55, pu_cover 8.18, pu_index 0.18, triangulation 6.14 / 1111, graph_cut
// 1.91, marching_tetrahedra 0.91, refine 1.72); 100K 2.16 s, 121 MB. 10M with the concurrency
// only (no Morton order, default allocator): 127.0 s / 202.4 s CPU, 5066 MB (pu_cover's).
// 20:40 UTC, every change of stop 38 (huge-page malloc): 100K 1.61 s / 2.65 s, 124 MB; 2M
// 19.43 s / 32.99 s, 1111 MB (pu_octree 1.55, pu_cover 7.80 / 1036, pu_index 0.16, triangulation
// 5.50 / 1111, graph_cut 1.55, marching_tetrahedra 0.83, refine 1.43); 10M 85.57 s / 140.05 s,
// 5071 MB (pu_octree 9.00 / 4321, pu_cover 36.79 / 5071, triangulation 20.63 / 3985, graph_cut
// 6.97, marching_tetrahedra 3.26, refine 6.22); mean 0.0079 %, Hausdorff 0.667 % (unchanged).
// 2026-12-04 23:05 UTC (stop 39; docs/methods/pu_graphcut.md, "2M points: memory under 1 GB"):
// octree cells as arrays, 72-byte CGAL cells, 32-bit tets, the flow network in one pass, step 8's
// estimates on a Morton-ordered tree; output unchanged. Huge-page malloc: 100K 1.62 s / 2.59 s,
// 119 MB; 2M 16.70 s / 28.24 s, 884 MB (pu_octree 1.17 / 569, pu_cover 6.73 / 788, pu_index 0.16,
// triangulation 4.55 / 846, graph_cut 1.20 / 884, marching_tetrahedra 0.86, refine 1.36); 10M
// 70.37 s / 118.17 s, 3583 MB (pu_octree 6.21, pu_cover 30.32 / 3583, triangulation 18.04 / 3485,
// graph_cut 5.01, marching_tetrahedra 2.79, refine 5.37). Default allocator: 2M 18.95 s / 30.83 s,
// 882 MB.
// 2026-12-05 01:30-01:45 UTC (stop 40; docs/methods/pu_graphcut.md, "2M points in under 15 s"): the
// cover accepts a batch while it computes the next, bit-map balance, the one-core stages lighter;
// output unchanged. Huge-page malloc: 100K 1.40 s / 2.35 s, 119 MB; 2M 13.52-16.57 s / 24.4-29.5 s
// (eight runs, six under 15 s), 813-948 MB (pu_octree 0.86-1.26 / 674, pu_cover 5.95-7.13 / 747,
// triangulation 4.11-5.02 / 948, graph_cut 0.79-1.12 / 811, marching_tetrahedra 0.48-0.53, refine
// 1.13-1.26); 10M 69.26 s /
// 114.87 s, 3508 MB (pu_octree 6.24, pu_cover 27.98 / 3313, triangulation 19.00 / 3481, graph_cut
// 4.05, marching_tetrahedra 2.07, refine 6.94). Default allocator: 2M 17.38 s / 29.89 s, 802 MB.
// 2026-12-05 05:20 UTC (stop 41; docs/methods/pu_graphcut.md, "the triangulation stage's two
// sides"): step 8's MLS surface built beside the graph cut; output unchanged. Huge-page malloc,
// back to back with stop 40's build: 2M 13.7, 13.7, 13.8 s against 14.0, 14.2, 14.5 s, 815-818 MB
// (triangulation 3.97-4.11 against 4.29-4.36); 100K 1.55 s against 1.58 s, 119 MB.
// 2026-12-05 07:00 UTC (stop 42; docs/methods/pu_graphcut.md, "the triangulation stage's critical
// path"): bounded plane searches, the tets' order beside the graph cut; output unchanged. A slower
// phase of the VM; back to back with stop 41's build: 2M 14.4, 14.8, 15.0, 14.0 s (26.0 s CPU)
// against 14.5, 15.2, 15.1, 14.9 s (26.9 s CPU), 804-831 MB (triangulation 3.87-4.11 against
// 4.27-4.42); 100K 1.29 s against 1.33 s. 08:00 UTC, with step 8's coarse projections beside its
// split and flips and column_means' parallel sort too, an even slower phase: 2M 16.0, 15.2, 14.9 s
// (28.1-30.1 s CPU), 807-827 MB against 17.2, 16.2, 15.8 s (29.0-31.6 s CPU), 821-902 MB.
// 2026-12-05 13:30 UTC (stop 44; docs/methods/pu_graphcut.md, "Memory the system has to back"):
// use_huge_page_malloc keeps freed blocks below 128 MiB in one heap, octree descents through the
// block table; output unchanged. Back to back with stop 43's build: 2M 13.69, 13.47, 13.76 s
// (25.3-25.8 s CPU, 0.8-1.3 s system) against 15.06, 13.49, 13.93 s (25.6-28.1 s CPU, 1.0-2.3 s
// system), 849-895 MB against 821-847 MB. 10M: 63.4 s / 116.6 s CPU, 3649 MB against huge pages
// alone 65.9 s / 121.1 s CPU, 3510 MB.
// 2026-12-05 16:30 UTC (stop 45; docs/methods/pu_graphcut.md, "the support cover's query"): the
// cover lists each ball's cells with Octree::visit_cells_in_ball; output unchanged. Back to back
// with stop 44's build, a fast phase of the VM: 2M 12.48, 12.57, 12.26 s (23.1-23.7 s CPU, cover
// 5.40-5.53 s), 820-905 MB against 12.81, 13.25, 12.78 s (24.2-25.1 s CPU, cover 5.86-6.21 s),
// 819-877 MB; 10M 58.7 s / 107.6 s CPU, 3581 MB against 68.4 s / 123.9 s CPU, 3578 MB. In a slow
// phase minutes later: 2M 15.7 s (15.2-15.7 s with kd-tree leaf sizes 32 and 128).
// 2026-12-05 19:50-20:40 UTC (stop 46; docs/methods/pu_graphcut.md, "far sites thinned out of
// the triangulation"): far_site_band = 8 (2M: 609,567 -> 266,848 sites; mean 0.008133 %,
// Hausdorff 0.6373 % against 0.008141 / 0.6322 %). Back to back with stop 45's build in a slow
// phase: 2M 14.57, 14.35, 13.17 s (24.1-26.3 s CPU), 805-810 MB against 16.99, 16.24, 14.96 s
// (28.3-29.9 s CPU), 809-952 MB; 11.3-14.6 s over 7 runs. 10M 58.8-69.7 s against 61.4-78.8 s
// (4 pairs), 3.58 GB both; step 8 is 2-5 s slower there on the same work (the doc's note).
// 10M points (PU at level 10), 2026-12-03 07:52 UTC, idle VM in a slow phase (the 100K run
// took 3.16 s wall / 4.30 s CPU then, 182 MB): 177.6 s wall / 249.4 s CPU, peak RSS 7.8 GB
// (input 588 MB), 1 closed manifold component (genus 0), mean to truth 0.0119 %, Hausdorff
// 0.682 %, truth to result 0.0113 %, area ratio 1.006, 1.97M supports; stages (wall s /
// peak MB during the stage): pu_octree 18.49 / 6815, pu_cover 60.35 / 5162, pu_index
// 1.65 / 5133, triangulation 73.99 / 5073, graph_cut 14.36 / 6097, marching_tetrahedra
// 5.96 / 7846, smoothing 0.54 / 6470. (That run printed the last stage's peak as the
// run's; the run's peak is now the largest of the stages'.)
// Under load 2.4-3.1 (2026-12-01 13:07 UTC, compilers on the other core): 100K PU 2.28 s
// wall / 2.27 s CPU; 2M PU 41.4 s / 41.2 s (pu_cover 16.88, triangulation 16.63).
// Under load 3.3-5.3 (2026-11-23 18:41 UTC): 100K PU 4.78 s wall / 3.10 s CPU, Poisson
// 68.1 s / 45.2 s (661 MB); 2M PU 59.4 s wall / 44.9 s CPU; Poisson 2M was killed at
// 900 s wall with 5.5 GB resident.
#ifndef CGAL_EIGEN3_ENABLED
#define CGAL_EIGEN3_ENABLED 1
#endif

#include <benchmark/benchmark.h>

#include "common.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/core/memory.hpp>
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

#include <sys/resource.h>
#include <sys/wait.h>
#include <poll.h>
#include <signal.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <random>
#include <iterator>
#include <sstream>
#include <string>

namespace ks = kintsugi;

namespace {

const std::string kBunny = std::string(KINTSUGI_SHARED_DATA_DIR) + "/cgal/meshes/bunny00.off";

using ks::bench::peak_rss_mb;

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

/// What a child process sends back (plain data through a pipe).
struct Outcome {
    int ok = 0;  ///< 1 when the method returned a mesh
    double wall_s = 0, cpu_s = 0;  ///< reconstruction only (input and metrics excluded)
    double peak_rss_mb = 0;        ///< the child's peak resident set, input included
    double input_rss_mb = 0;       ///< resident set once the input was built
    double components = 0, closed_manifold = 0, faces = 0, genus = 0;
    double mean = -1, hausdorff = -1, mean_back = -1, area_ratio = -1;  ///< % of the diagonal / ratio
    double supports = 0, graph_nodes = 0;
    int n_stages = 0;
    std::array<std::array<char, 32>, 12> stage{};
    std::array<double, 12> stage_s{};
    std::array<double, 12> stage_peak_mb{};  ///< peak resident set during each stage (0: unknown)
    std::array<char, 200> note{};
    int timed_out = 0;  ///< killed at the time limit (times and memory are then lower bounds)
};

void set_note(Outcome& o, const std::string& s) { std::snprintf(o.note.data(), o.note.size(), "%s", s.c_str()); }

double cpu_seconds() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
           1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

void measure_accuracy(Outcome& o, const ks::IndexedMesh& result) {
    const auto rep = ks::topology_report(result);
    o.components = static_cast<double>(rep.components);
    o.closed_manifold = rep.closed && rep.manifold ? 1 : 0;
    o.faces = static_cast<double>(rep.faces);
    o.genus = static_cast<double>(rep.genus);
    if (result.faces.empty()) return;
    const auto d = ks::compare(result, reference(), {.samples = 200000});
    const auto ab = d.relative(d.a_to_b), ba = d.relative(d.b_to_a);
    o.mean = 100 * ab.mean;
    o.hausdorff = 100 * ab.hausdorff;
    o.mean_back = 100 * ba.mean;
    const auto ar = ks::face_areas(result), at = ks::face_areas(reference());
    o.area_ratio = std::accumulate(ar.begin(), ar.end(), 0.0) / std::accumulate(at.begin(), at.end(), 0.0);
}

template <class T>
T env_or(const char* name, T fallback) {
    const char* v = std::getenv(name);
    return v && *v ? static_cast<T>(std::atof(v)) : fallback;
}

/// Runs `method(points) -> optional mesh` in a child process with the time and memory
/// limits; the child builds the input and measures the result.
template <class Method>
Outcome run_isolated(std::size_t n, Method&& method) {
    const double timeout = env_or("KINTSUGI_BENCH_TIMEOUT", 900.0);
    // Default: 12 GB, or 2 GB per million points above 6M (the 10M run needs about 2x the 2M one's share).
    const double mem_gb = env_or("KINTSUGI_BENCH_MEMORY_GB", std::max(12.0, 2.0 * static_cast<double>(n) / 1e6));
    Outcome o;
    int fd[2];
    if (pipe(fd) != 0) {
        set_note(o, "pipe() failed");
        return o;
    }
    std::fflush(stdout);
    std::fflush(stderr);
    const pid_t pid = fork();
    if (pid < 0) {
        set_note(o, "fork() failed");
        return o;
    }
    if (pid == 0) {
        close(fd[0]);
        const rlimit lim{static_cast<rlim_t>(mem_gb * 1073741824.0), static_cast<rlim_t>(mem_gb * 1073741824.0)};
        setrlimit(RLIMIT_AS, &lim);
        Outcome c;
        try {
            const ks::PointCloud& pts = input(n);
            c.input_rss_mb = peak_rss_mb();
            const auto t0 = std::chrono::steady_clock::now();
            const double c0 = cpu_seconds();
            ks::IndexedMesh mesh;
            method(pts, mesh, c);
            c.cpu_s = cpu_seconds() - c0;
            c.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            // A method that resets the peak (per-stage peaks) leaves the earlier ones in c.
            c.peak_rss_mb = std::max({peak_rss_mb(), c.peak_rss_mb, c.input_rss_mb});
            if (c.ok) measure_accuracy(c, mesh);
        } catch (const std::bad_alloc&) {
            c.ok = 0;
            c.peak_rss_mb = peak_rss_mb();
            set_note(c, "out of memory (std::bad_alloc; address-space limit " + std::to_string(int(mem_gb)) + " GB)");
        } catch (const std::exception& e) {
            c.ok = 0;
            c.peak_rss_mb = peak_rss_mb();
            set_note(c, std::string("threw: ") + e.what());
        }
        const char* p = reinterpret_cast<const char*>(&c);
        std::size_t left = sizeof c;
        while (left > 0) {
            const ssize_t w = write(fd[1], p, left);
            if (w <= 0) break;
            p += w;
            left -= static_cast<std::size_t>(w);
        }
        close(fd[1]);
        _exit(0);
    }
    close(fd[1]);
    const auto t0 = std::chrono::steady_clock::now();
    std::size_t got = 0;
    char* p = reinterpret_cast<char*>(&o);
    bool timed_out = false;
    while (got < sizeof o) {
        const double left = timeout - std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        if (left <= 0) {
            timed_out = true;
            break;
        }
        pollfd pf{fd[0], POLLIN, 0};
        const int r = poll(&pf, 1, static_cast<int>(std::min(left, 60.0) * 1000) + 1);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) continue;
        const ssize_t k = read(fd[0], p + got, sizeof o - got);
        if (k <= 0) break;  // the child exited without a complete answer
        got += static_cast<std::size_t>(k);
    }
    close(fd[0]);
    // What the child used so far (read before killing it on a timeout).
    double child_cpu = 0, child_peak = 0;
    {
        std::ifstream st("/proc/" + std::to_string(pid) + "/stat");
        std::string all((std::istreambuf_iterator<char>(st)), std::istreambuf_iterator<char>());
        const auto rp = all.rfind(')');
        if (rp != std::string::npos) {
            std::istringstream in(all.substr(rp + 2));
            std::string field;
            double ut = 0, stime = 0;
            for (int i = 3; i <= 15 && in >> field; ++i) {
                if (i == 14) ut = std::atof(field.c_str());
                if (i == 15) stime = std::atof(field.c_str());
            }
            child_cpu = (ut + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
        }
        std::ifstream ss("/proc/" + std::to_string(pid) + "/status");
        std::string line;
        while (std::getline(ss, line))
            if (line.rfind("VmHWM:", 0) == 0) child_peak = std::stod(line.substr(6)) / 1024.0;
    }
    if (timed_out) kill(pid, SIGKILL);
    int status = 0;
    waitpid(pid, &status, 0);
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (got < sizeof o) {
        o = Outcome{};
        o.wall_s = elapsed;
        o.cpu_s = child_cpu;
        o.peak_rss_mb = child_peak;
        o.timed_out = timed_out ? 1 : 0;
        if (timed_out)
            set_note(o, "timed out after " + std::to_string(int(timeout)) + " s (KINTSUGI_BENCH_TIMEOUT), killed; " +
                            "time and memory so far shown (lower bounds)");
        else if (WIFSIGNALED(status))
            set_note(o, std::string("crashed: signal ") + std::to_string(WTERMSIG(status)) + " (" +
                            strsignal(WTERMSIG(status)) + ")");
        else
            set_note(o, "child exited without an answer (status " + std::to_string(status) + ")");
    }
    return o;
}

std::map<std::string, Outcome>& results() {
    static std::map<std::string, Outcome> r;
    return r;
}

std::string key(const char* method, std::size_t n) { return std::string(method) + "/" + std::to_string(n); }

void report(benchmark::State& state, const char* method, std::size_t n, const Outcome& o) {
    state.SetIterationTime(std::max(o.wall_s, 1e-9));
    state.counters["ok"] = o.ok;
    state.counters["cpu_s"] = o.cpu_s;
    state.counters["peak_rss_MB"] = o.peak_rss_mb;
    state.counters["components"] = o.components;
    state.counters["closed_manifold"] = o.closed_manifold;
    state.counters["mean_to_truth_%"] = o.mean;
    state.counters["hausdorff_to_truth_%"] = o.hausdorff;
    state.counters["mean_truth_to_result_%"] = o.mean_back;
    state.counters["area_ratio"] = o.area_ratio;
    for (int i = 0; i < o.n_stages; ++i) state.counters[std::string("s_") + o.stage[std::size_t(i)].data()] = o.stage_s[std::size_t(i)];
    if (o.note[0] != 0) state.SetLabel(o.note.data());
    results()[key(method, n)] = o;
}

bool have_data(benchmark::State& state) {
    if (std::filesystem::exists(kBunny)) return true;
    state.SkipWithError(("skipped: " + kBunny + " not found (needs ../shared/data)").c_str());
    return false;
}

void BM_PUGraphcut(benchmark::State& state) {
    if (!have_data(state)) return;
    const auto n = static_cast<std::size_t>(state.range(0));
    const int level = static_cast<int>(state.range(1));
    Outcome o;
    for (auto _ : state) {
        o = run_isolated(n, [&](const ks::PointCloud& pts, ks::IndexedMesh& mesh, Outcome& c) {
            // Peak memory per stage: the peak is read and reset at each stage's start. The
            // "done" event a sub-run (the PU field) sends at its end is no stage of its own
            // (counted as one, it shifted every later stage's peak by one until 2026-12-04).
            std::vector<double> peaks;
            std::string current;
            const bool can_reset = ks::bench::reset_peak_rss();
            ks::RunControl control;
            control.progress = [&](const ks::ProgressEvent& e) {
                if (can_reset && e.stage != current && e.stage != "done") {
                    if (!current.empty()) peaks.push_back(peak_rss_mb());
                    current = std::string(e.stage);
                    ks::bench::reset_peak_rss();
                }
                return true;
            };
            auto r = ks::reconstruct_pu_graphcut(pts, {.max_level = level, .control = control});
            if (can_reset && !current.empty()) peaks.push_back(peak_rss_mb());  // the last stage's
            c.ok = r.status == ks::Status::ok ? 1 : 0;
            c.supports = static_cast<double>(r.supports);
            c.graph_nodes = static_cast<double>(r.graph_nodes);
            for (const auto& t : r.timings) {
                if (c.n_stages == int(c.stage.size())) break;
                std::snprintf(c.stage[std::size_t(c.n_stages)].data(), 32, "%s", t.stage.c_str());
                c.stage_peak_mb[std::size_t(c.n_stages)] = std::size_t(c.n_stages) < peaks.size() ? peaks[std::size_t(c.n_stages)] : 0;
                c.stage_s[std::size_t(c.n_stages++)] = t.seconds;
            }
            for (double mb : peaks) c.peak_rss_mb = std::max(c.peak_rss_mb, mb);  // the run's peak, all stages
            mesh = std::move(r.mesh);
        });
    }
    state.counters["supports"] = o.supports;
    state.counters["graph_nodes"] = o.graph_nodes;
    report(state, "PU+graph-cut", n, o);
}

void BM_CGALPoisson(benchmark::State& state) {
    if (!have_data(state)) return;
    using K = CGAL::Exact_predicates_inexact_constructions_kernel;
    using PN = std::pair<K::Point_3, K::Vector_3>;
    const auto n = static_cast<std::size_t>(state.range(0));
    Outcome o;
    for (auto _ : state) {
        o = run_isolated(n, [&](const ks::PointCloud& pts, ks::IndexedMesh& mesh, Outcome& c) {
            std::vector<PN> pn(pts.points.size());
            for (std::size_t i = 0; i < pn.size(); ++i)
                pn[i] = {K::Point_3(pts.points[i].x(), pts.points[i].y(), pts.points[i].z()),
                         K::Vector_3(pts.normals[i].x(), pts.normals[i].y(), pts.normals[i].z())};
            CGAL::Surface_mesh<K::Point_3> out;
            const double spacing = CGAL::compute_average_spacing<CGAL::Sequential_tag>(
                pn, 6, CGAL::parameters::point_map(CGAL::First_of_pair_property_map<PN>()));
            const bool ok = CGAL::poisson_surface_reconstruction_delaunay(
                pn.begin(), pn.end(), CGAL::First_of_pair_property_map<PN>(), CGAL::Second_of_pair_property_map<PN>(),
                out, spacing);
            c.ok = ok && out.number_of_faces() > 0 ? 1 : 0;
            if (!ok) set_note(c, "poisson_surface_reconstruction_delaunay returned false");
            else if (out.number_of_faces() == 0) set_note(c, "empty surface");
            mesh = ks::to_indexed_mesh(out);
        });
    }
    report(state, "CGAL Poisson", n, o);
}

void print_summary() {
    std::printf("\nBunny (%s) sampled with 0.1 %% noise, 3 holes, 10 %% outliers; each run in its own process.\n",
                kBunny.c_str());
    {
        std::ifstream la("/proc/loadavg");
        std::string l;
        std::getline(la, l);
        std::printf("Load average at the end: %s (2 cores shared: wall times grow with the load, CPU times much less)\n",
                    l.c_str());
        std::printf("Allocator: %s\n", ks::bench::allocator_description());
    }
    auto cell = [](const Outcome* o, double v, const char* fmt) {
        char buf[64];
        if (!o) return std::string("-");
        if (v < 0) return std::string("n/a");
        std::snprintf(buf, sizeof buf, fmt, v);
        return std::string(buf);
    };
    for (std::size_t n : {std::size_t{100000}, std::size_t{2000000}, std::size_t{10000000}}) {
        const auto& R = results();
        const auto pi = R.find(key("PU+graph-cut", n)), ci = R.find(key("CGAL Poisson", n));
        const Outcome* pu = pi == R.end() ? nullptr : &pi->second;
        const Outcome* po = ci == R.end() ? nullptr : &ci->second;
        if (!pu && !po) continue;
        std::printf("\n%zu points            %16s %16s   %s\n", n, "PU+graph-cut", "CGAL Poisson", "Poisson / PU");
        auto row = [&](const char* name, double a, double b, const char* fmt, bool ratio) {
            std::printf("  %-22s %16s %16s", name, cell(pu, a, fmt).c_str(),
                        ((po && po->timed_out && b > 0 ? "> " : "") + cell(po, b, fmt)).c_str());
            if (ratio && pu && po && a > 0 && b > 0) std::printf("   %s%.2fx", po->timed_out ? "> " : "", b / a);
            std::printf("\n");
        };
        const bool pok = pu && pu->ok, cok = po && po->ok;
        row("wall time (s)", pu ? pu->wall_s : -1, po ? po->wall_s : -1, "%.2f", true);
        row("CPU time (s)", pu ? pu->cpu_s : -1, po ? po->cpu_s : -1, "%.2f", true);
        row("peak RSS (MB)", pu ? pu->peak_rss_mb : -1, po ? po->peak_rss_mb : -1, "%.0f", true);
        row("  of which input (MB)", pu ? pu->input_rss_mb : -1, po ? po->input_rss_mb : -1, "%.0f", false);
        row("components", pok ? pu->components : -1, cok ? po->components : -1, "%.0f", false);
        row("closed & manifold", pok ? pu->closed_manifold : -1, cok ? po->closed_manifold : -1, "%.0f", false);
        row("genus (sum)", pok ? pu->genus : -1, cok ? po->genus : -1, "%.0f", false);
        row("mean dist to truth (%)", pok ? pu->mean : -1, cok ? po->mean : -1, "%.4f", true);
        row("Hausdorff to truth (%)", pok ? pu->hausdorff : -1, cok ? po->hausdorff : -1, "%.3f", true);
        row("truth to result (%)", pok ? pu->mean_back : -1, cok ? po->mean_back : -1, "%.4f", true);
        row("area / true area", pok ? pu->area_ratio : -1, cok ? po->area_ratio : -1, "%.3f", false);
        if (pu && pu->note[0]) std::printf("  PU+graph-cut: %s\n", pu->note.data());
        if (po && po->note[0]) std::printf("  CGAL Poisson: %s\n", po->note.data());
        if (pu && pu->n_stages > 0) {
            std::printf("  PU+graph-cut stages (wall s / peak resident MB during the stage):");
            for (int i = 0; i < pu->n_stages; ++i)
                std::printf(" %s %.2f / %.0f", pu->stage[std::size_t(i)].data(), pu->stage_s[std::size_t(i)],
                            pu->stage_peak_mb[std::size_t(i)]);
            std::printf("\n");
        }
    }
}

}  // namespace

// args: points, max_level
BENCHMARK(BM_PUGraphcut)->Args({100000, 8})->Unit(benchmark::kSecond)->UseManualTime()->Iterations(1);
BENCHMARK(BM_CGALPoisson)->Args({100000, 0})->Unit(benchmark::kSecond)->UseManualTime()->Iterations(1);
BENCHMARK(BM_PUGraphcut)->Args({2000000, 9})->Unit(benchmark::kSecond)->UseManualTime()->Iterations(1);
BENCHMARK(BM_CGALPoisson)->Args({2000000, 0})->Unit(benchmark::kSecond)->UseManualTime()->Iterations(1);
// 10M: bunny00 sampled densely (the merged bunny scans hold 327K points); Poisson, which
// did not finish 2M within 900 s and 8.9 GB, is not run.
BENCHMARK(BM_PUGraphcut)->Args({10000000, 10})->Unit(benchmark::kSecond)->UseManualTime()->Iterations(1);

int main(int argc, char** argv) {
    // glibc's allocator keeping freed memory, as the kintsugi CLI runs (KINTSUGI_DEFAULT_MALLOC=1:
    // the library's default, as a program that does not call it gets).
    ks::use_kept_heap_malloc(argv);
    return ks::bench::run(argc, argv, [](const ks::bench::RatioReporter&) { print_summary(); });
}
