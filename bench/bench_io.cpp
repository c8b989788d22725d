// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Reading a 1M-point binary PLY: kintsugi's reader against CGAL's plain readers, in the
// same run, on the same file.
//
// Input: the 9 Stanford bunny range scans of ../shared/data (327k points with normals)
// merged and repeated with a small deterministic jitter (sigma 0.1 mm) up to 1,000,000
// points, written as binary little-endian PLY with float32 x y z nx ny nz (24 MB) into a
// temporary directory. Without ../shared/data a synthetic sphere of 1M points is used
// (said on stdout). A second file adds the scans' faces (range-grid triangles, 1.98M) to
// time a mesh read.
//
// Peers: CGAL::IO::read_PLY into std::vector<Point_3> (positions only), the same with a
// normal map (positions + normals, what kintsugi reads), and CGAL::IO::read_point_set
// into a CGAL::Point_set_3 (all properties). The ratios are printed at the end.
//
// Measured 2026-11-23 on the 2-core build machine (shared, load average ~9, so real time
// is ~3.5x CPU time), RelWithDebInfo, real data, time per read real / CPU:
//   kintsugi::read_point_cloud (points + normals)    236 /   68 ms
//   CGAL::IO::read_PLY, points only                  956 /  269 ms   (4.0x slower)
//   CGAL::IO::read_PLY, points + normals            1433 /  454 ms   (6.1x / 6.7x slower)
//   CGAL::IO::read_point_set (Point_set_3)          1197 /  347 ms   (5.1x slower)
//   kintsugi::read_mesh, 9 scans (327k V, 634k F)     46 /   15 ms
// perf: most of kintsugi's time is the kernel's first-touch page faults of the 24 MB
// file buffer and the 48 MB output vectors; the decoding loop itself is ~17 %.
#include <benchmark/benchmark.h>

#include "common.hpp"

#include <kintsugi/io/read.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/IO/read_ply_points.h>
#include <CGAL/Point_set_3.h>
#include <CGAL/Point_set_3/IO.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace fs = std::filesystem;
namespace ks = kintsugi;
using K = CGAL::Exact_predicates_inexact_constructions_kernel;

namespace {

constexpr std::size_t kPoints = 1'000'000;

struct Inputs {
    fs::path dir;
    fs::path points_ply;  // 1M points with normals, float32
    fs::path mesh_ply;    // the 9 scans as one mesh (points + faces), float32
    std::string source;
};

void write_float_ply(const fs::path& path, const std::vector<ks::Vec3>& p, const std::vector<ks::Vec3>& n,
                     const std::vector<ks::Face>& faces) {
    std::ofstream f(path, std::ios::binary);
    f << "ply\nformat binary_little_endian 1.0\nelement vertex " << p.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n";
    if (!faces.empty()) f << "element face " << faces.size() << "\nproperty list uchar int vertex_indices\n";
    f << "end_header\n";
    std::vector<char> buf;
    buf.reserve(p.size() * 24 + faces.size() * 13);
    auto put = [&](const auto v) {
        const char* b = reinterpret_cast<const char*>(&v);
        buf.insert(buf.end(), b, b + sizeof v);
    };
    for (std::size_t i = 0; i < p.size(); ++i) {
        for (int c = 0; c < 3; ++c) put(static_cast<float>(p[i][c]));
        for (int c = 0; c < 3; ++c) put(static_cast<float>(n[i][c]));
    }
    for (const ks::Face& t : faces) {
        put(static_cast<std::uint8_t>(3));
        for (const ks::Index v : t) put(static_cast<std::int32_t>(v));
    }
    f.write(buf.data(), static_cast<std::streamsize>(buf.size()));
}

Inputs& inputs() {
    static Inputs in = [] {
        Inputs r;
        std::random_device rd;
        r.dir = fs::temp_directory_path() / ("kintsugi_bench_io_" + std::to_string(rd()));
        fs::create_directories(r.dir);
        r.points_ply = r.dir / "points_1M.ply";
        r.mesh_ply = r.dir / "scans_mesh.ply";
        std::vector<ks::Vec3> base_p, base_n;
        std::vector<ks::Face> faces;
        const fs::path scans = fs::path(KINTSUGI_SHARED_DATA_DIR) / "stanford_bunny" / "scans";
        const char* names[] = {"bun000", "bun045", "bun090", "bun180", "bun270", "chin", "ear_back", "top2", "top3"};
        bool real = fs::is_directory(scans);
        if (real) {
            for (const char* name : names) {
                const ks::IndexedMesh m = ks::read_mesh(scans / (std::string(name) + ".ply"));
                const std::size_t offset = base_p.size();
                base_p.insert(base_p.end(), m.vertices.begin(), m.vertices.end());
                base_n.insert(base_n.end(), m.normals.begin(), m.normals.end());
                for (const ks::Face& t : m.faces) faces.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
            }
            r.source = "the 9 Stanford bunny scans of " + scans.string() + " (" + std::to_string(base_p.size()) +
                       " points), repeated with jitter";
        } else {
            std::mt19937_64 rng(7);
            std::normal_distribution<double> g(0, 1);
            for (std::size_t i = 0; i < kPoints; ++i) {
                const ks::Vec3 d = ks::Vec3(g(rng), g(rng), g(rng)).normalized();
                base_p.push_back(0.1 * d);
                base_n.push_back(d);
            }
            r.source = "SYNTHETIC sphere (shared data not found at " + scans.string() + ")";
        }
        std::mt19937_64 rng(42);
        std::normal_distribution<double> jitter(0, 1e-4);
        std::vector<ks::Vec3> p(kPoints), n(kPoints);
        for (std::size_t i = 0; i < kPoints; ++i) {
            const std::size_t j = i % base_p.size();
            p[i] = base_p[j] + (i < base_p.size() ? ks::Vec3::Zero() : ks::Vec3(jitter(rng), jitter(rng), jitter(rng)));
            n[i] = base_n[j];
        }
        write_float_ply(r.points_ply, p, n, {});
        if (real) write_float_ply(r.mesh_ply, base_p, base_n, faces);
        std::cout << "bench_io input: " << r.source << "\n  " << r.points_ply << " (" << fs::file_size(r.points_ply)
                  << " bytes, " << kPoints << " points, float32 x y z nx ny nz)\n";
        if (real)
            std::cout << "  " << r.mesh_ply << " (" << fs::file_size(r.mesh_ply) << " bytes, " << base_p.size()
                      << " vertices, " << faces.size() << " faces)\n";
        return r;
    }();
    return in;
}

void BM_kintsugi_read_point_cloud(benchmark::State& state) {
    const fs::path f = inputs().points_ply;
    for (auto _ : state) {
        ks::PointCloud c = ks::read_point_cloud(f);
        if (c.points.size() != kPoints || c.normals.size() != kPoints) state.SkipWithError("wrong count");
        benchmark::DoNotOptimize(c.points.data());
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kPoints));
}

void BM_cgal_read_PLY_points(benchmark::State& state) {
    const std::string f = inputs().points_ply.string();
    for (auto _ : state) {
        std::vector<K::Point_3> pts;
        if (!CGAL::IO::read_PLY(f, std::back_inserter(pts)) || pts.size() != kPoints) state.SkipWithError("CGAL failed");
        benchmark::DoNotOptimize(pts.data());
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kPoints));
}

void BM_cgal_read_PLY_points_normals(benchmark::State& state) {
    using PN = std::pair<K::Point_3, K::Vector_3>;
    const std::string f = inputs().points_ply.string();
    for (auto _ : state) {
        std::vector<PN> pts;
        if (!CGAL::IO::read_PLY(f, std::back_inserter(pts),
                                CGAL::parameters::point_map(CGAL::First_of_pair_property_map<PN>())
                                    .normal_map(CGAL::Second_of_pair_property_map<PN>())) ||
            pts.size() != kPoints)
            state.SkipWithError("CGAL failed");
        benchmark::DoNotOptimize(pts.data());
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kPoints));
}

void BM_cgal_read_point_set(benchmark::State& state) {
    const std::string f = inputs().points_ply.string();
    for (auto _ : state) {
        CGAL::Point_set_3<K::Point_3, K::Vector_3> ps;
        if (!CGAL::IO::read_point_set(f, ps) || ps.size() != kPoints) state.SkipWithError("CGAL failed");
        benchmark::DoNotOptimize(&ps);
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kPoints));
}

void BM_kintsugi_read_mesh_scans(benchmark::State& state) {
    const fs::path f = inputs().mesh_ply;
    if (f.empty() || !fs::exists(f)) {
        state.SkipWithError("no shared data: mesh benchmark skipped");
        return;
    }
    for (auto _ : state) {
        ks::IndexedMesh m = ks::read_mesh(f);
        benchmark::DoNotOptimize(m.faces.data());
    }
}

BENCHMARK(BM_kintsugi_read_point_cloud)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_cgal_read_PLY_points)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_cgal_read_PLY_points_normals)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_cgal_read_point_set)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_kintsugi_read_mesh_scans)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace

int main(int argc, char** argv) {
    inputs();
    const int rc = ks::bench::run(argc, argv, [](const ks::bench::RatioReporter& r) {
        const double kr = r.real("BM_kintsugi_read_point_cloud"), kc = r.cpu("BM_kintsugi_read_point_cloud");
        std::cout << "\nRead 1M-point binary PLY, time per read (real / CPU):\n";
        for (const char* peer : {"BM_cgal_read_PLY_points", "BM_cgal_read_PLY_points_normals", "BM_cgal_read_point_set"}) {
            const double cr = r.real(peer), cc = r.cpu(peer);
            if (kr > 0 && cr > 0)
                std::printf("  kintsugi %.0f / %.0f ms vs %s %.0f / %.0f ms: kintsugi is %.1fx (real) / %.1fx (CPU) faster\n",
                            kr, kc, peer, cr, cc, cr / kr, cc / kc);
        }
    });
    std::error_code ec;
    fs::remove_all(inputs().dir, ec);
    return rc;
}
