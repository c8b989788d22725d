// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Mesh editing: 1M seeded random split / collapse / flip with a normal and a scalar
// per vertex, on kintsugi::HalfedgeMesh and on CGAL::Surface_mesh with its Euler
// operations (the choice of structure, docs/methods/mesh_editing.md). Start: an
// icosphere with 81,920 faces. Counters: heap bytes per live face after the run (glibc
// mallinfo2, in-use plus mmapped blocks: the structure with its attributes) and the edits done.
// Hole fill: time against the hole's length (about 100, 1K and 10K boundary edges), a slot
// two cells wide cut from a flat grid, kintsugi::fill_hole beside CGAL's
// triangulate_refine_and_fair_hole (docs/methods/mesh_editing.md).
#include "common.hpp"

#include "../tests/mesh/edit_fixtures.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/mesh/halfedge_mesh.hpp>
#include <kintsugi/mesh/holes.hpp>

#define CGAL_EIGEN3_ENABLED 1
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/boost/graph/Euler_operations.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/helpers.h>

#include <malloc.h>

#include <random>

namespace ks = kintsugi;

namespace {

constexpr std::size_t kOps = 1'000'000;

// Heap in use: small blocks plus the mmapped large ones (big vectors).
double heap_bytes() {
    const auto mi = mallinfo2();
    return static_cast<double>(mi.uordblks + mi.hblkhd);
}

const ks::IndexedMesh& start_mesh() {
    static const ks::IndexedMesh m = kintsugi_test::icosphere(6);
    return m;
}

double param(std::mt19937_64& rng) { return 0.2 + 0.6 * static_cast<double>(rng() % 1000) / 1000.0; }

void BM_kintsugi_edit_1M(benchmark::State& state) {
    for (auto _ : state) {
        state.PauseTiming();
        (void)start_mesh();
        const double h0 = heap_bytes();
        auto hm = ks::HalfedgeMesh::from_mesh(start_mesh());
        const auto s = hm.add_scalar("f");
        hm.enable_normals();
        for (ks::Index v = 0; v < hm.vertex_capacity(); ++v) {
            hm.scalar(s, v) = hm.position(v).x();
            hm.normal(v) = hm.position(v);
        }
        std::mt19937_64 rng(1);
        std::size_t done = 0;
        state.ResumeTiming();
        for (std::size_t i = 0; i < kOps; ++i) {
            ks::Index h = 0;
            do {
                h = static_cast<ks::Index>(rng() % hm.halfedge_capacity());
            } while (hm.is_removed_face(ks::HalfedgeMesh::face(h)));
            const auto op = rng() % 3;
            const double t = param(rng);
            if (op == 0) {
                hm.split(h, t);
                ++done;
            } else if (op == 1) {
                done += hm.collapse(h, t) != ks::HalfedgeMesh::invalid;
            } else {
                done += hm.flip(h);
            }
        }
        state.PauseTiming();
        state.counters["bytes_per_face"] = (heap_bytes() - h0) / static_cast<double>(hm.num_faces());
        state.counters["edits"] = static_cast<double>(done);
        state.counters["faces"] = static_cast<double>(hm.num_faces());
        if (!hm.validate().empty()) state.SkipWithError("invalid mesh after the edits");
        state.ResumeTiming();
    }
}
BENCHMARK(BM_kintsugi_edit_1M)->Unit(benchmark::kMillisecond)->Iterations(1);

void BM_cgal_edit_1M(benchmark::State& state) {
    using K = CGAL::Simple_cartesian<double>;
    using SM = CGAL::Surface_mesh<K::Point_3>;
    using VI = SM::Vertex_index;
    using HI = SM::Halfedge_index;
    for (auto _ : state) {
        state.PauseTiming();
        (void)start_mesh();
        const double h0 = heap_bytes();
        SM sm;
        ks::assign_mesh(sm, start_mesh());
        auto fmap = sm.add_property_map<VI, double>("v:f", 0).first;
        auto nmap = sm.add_property_map<VI, K::Vector_3>("v:n", K::Vector_3(0, 0, 0)).first;
        for (VI v : sm.vertices()) {
            fmap[v] = sm.point(v).x();
            nmap[v] = sm.point(v) - CGAL::ORIGIN;
        }
        auto interpolate = [&](VI dst, VI a, VI b, double t) {
            sm.point(dst) = CGAL::ORIGIN + ((1 - t) * (sm.point(a) - CGAL::ORIGIN) + t * (sm.point(b) - CGAL::ORIGIN));
            fmap[dst] = (1 - t) * fmap[a] + t * fmap[b];
            const K::Vector_3 n = (1 - t) * nmap[a] + t * nmap[b];
            nmap[dst] = n / std::sqrt(n.squared_length());
        };
        std::mt19937_64 rng(1);
        std::size_t done = 0;
        state.ResumeTiming();
        for (std::size_t i = 0; i < kOps; ++i) {
            HI h;
            do {
                h = HI(static_cast<SM::size_type>(rng() % sm.num_halfedges()));
            } while (sm.is_removed(h));
            const auto op = rng() % 3;
            const double t = param(rng);
            const VI a = sm.source(h), b = sm.target(h);
            if (op == 0) {
                const HI hn = CGAL::Euler::split_edge(h, sm);  // a -> m, then h: m -> b
                CGAL::Euler::split_face(hn, sm.next(h), sm);
                const HI o = sm.opposite(h), on = sm.opposite(hn);
                if (!sm.is_border(o)) CGAL::Euler::split_face(o, sm.next(on), sm);
                interpolate(sm.target(hn), a, b, t);
                ++done;
            } else if (op == 1) {
                const auto e = sm.edge(h);
                if (CGAL::Euler::does_satisfy_link_condition(e, sm)) {
                    const VI kept = CGAL::Euler::collapse_edge(e, sm);
                    interpolate(kept, a, b, t);
                    ++done;
                }
            } else {
                const VI c = sm.target(sm.next(h)), d = sm.target(sm.next(sm.opposite(h)));
                if (c != d && !CGAL::halfedge(c, d, sm).second) {
                    CGAL::Euler::flip_edge(h, sm);
                    ++done;
                }
            }
        }
        state.PauseTiming();
        state.counters["bytes_per_face"] = (heap_bytes() - h0) / static_cast<double>(sm.number_of_faces());
        state.counters["edits"] = static_cast<double>(done);
        state.counters["faces"] = static_cast<double>(sm.number_of_faces());
        if (!sm.is_valid(false) || !CGAL::is_triangle_mesh(sm)) state.SkipWithError("invalid mesh after the edits");
        state.ResumeTiming();
    }
}
BENCHMARK(BM_cgal_edit_1M)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace

int main(int argc, char** argv) {
    return ks::bench::run(argc, argv, [](const ks::bench::RatioReporter& r) {
        r.print_cpu_ratio("BM_kintsugi_edit_1M", "BM_cgal_edit_1M");
    });
}

namespace {

// (L + 2) x 8 cells of 0.1 in the plane z = 0 minus the slot of L x 2 cells at cells
// [1, L+1) x [3, 5): one hole with 2L + 4 boundary edges, next to the outer border.
ks::IndexedMesh slot_mesh(int L) {
    const int nx = L + 2, ny = 8;
    ks::IndexedMesh m;
    for (int j = 0; j <= ny; ++j)
        for (int i = 0; i <= nx; ++i) m.vertices.emplace_back(0.1 * i, 0.1 * j, 0.0);
    auto id = [nx](int i, int j) { return static_cast<ks::Index>(j * (nx + 1) + i); };
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
            if (i >= 1 && i < L + 1 && j >= 3 && j < 5) continue;
            m.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            m.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    return m;
}

void BM_kintsugi_fill_slot(benchmark::State& state) {
    const ks::IndexedMesh in = slot_mesh(static_cast<int>(state.range(0)));
    const auto loops = ks::find_boundary_loops(in);
    const auto hole = loops.loops.at(loops.holes().at(0)).vertices;
    std::size_t added = 0;
    for (auto _ : state) {
        state.PauseTiming();
        ks::IndexedMesh m = in;
        state.ResumeTiming();
        added = ks::fill_hole(m, hole).new_vertices;
    }
    state.counters["boundary_edges"] = static_cast<double>(hole.size());
    state.counters["new_vertices"] = static_cast<double>(added);
}
BENCHMARK(BM_kintsugi_fill_slot)->Arg(48)->Arg(498)->Arg(4998)->Unit(benchmark::kMillisecond)->Iterations(1);

void BM_cgal_fill_slot(benchmark::State& state) {
    using SM = CGAL::Surface_mesh<CGAL::Simple_cartesian<double>::Point_3>;
    SM in;
    ks::assign_mesh(in, slot_mesh(static_cast<int>(state.range(0))));
    // The hole: the border cycle that does not contain vertex 0 (a corner of the outer border).
    SM::Halfedge_index start;
    std::size_t edges = 0;
    for (auto h : in.halfedges()) {
        if (!in.is_border(h)) continue;
        bool outer = false;
        std::size_t n = 0;
        for (auto g : CGAL::halfedges_around_face(h, in)) {
            outer = outer || in.source(g) == SM::Vertex_index(0);
            ++n;
        }
        if (!outer) {
            start = h;
            edges = n;
            break;
        }
    }
    std::size_t added = 0;
    for (auto _ : state) {
        state.PauseTiming();
        SM m = in;
        std::vector<SM::Face_index> pf;
        std::vector<SM::Vertex_index> pv;
        state.ResumeTiming();
        CGAL::Polygon_mesh_processing::triangulate_refine_and_fair_hole(m, start, std::back_inserter(pf),
                                                                        std::back_inserter(pv));
        added = pv.size();
    }
    state.counters["boundary_edges"] = static_cast<double>(edges);
    state.counters["new_vertices"] = static_cast<double>(added);
}
BENCHMARK(BM_cgal_fill_slot)->Arg(48)->Arg(498)->Arg(4998)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace
