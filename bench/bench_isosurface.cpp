// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// extract_isosurface beside CGAL's surface mesher (make_surface_mesh, Boissonnat-Oudot
// Delaunay refinement with the field as oracle) on the same analytic fields: time,
// field evaluations and quality (closed, manifold, genus, smallest angles, distance of
// the vertices and of points on the triangles to the zero set).
//
// A dual-contouring prototype (surface nets, below) on the same cube set shows what
// the other family of polygonisers would give.
//
// Run: bench_isosurface --benchmark_counters_tabular=true
// Figures and the polygoniser comparison: docs/methods/isosurface.md.

#include "common.hpp"

#include "../tests/field/iso_fields.hpp"

#include <kintsugi/adapters/cgal.hpp>
#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/field/isosurface.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include <CGAL/Complex_2_in_triangulation_3.h>
#include <CGAL/Implicit_surface_3.h>
#include <CGAL/Surface_mesh_default_criteria_3.h>
#include <CGAL/Surface_mesh_default_triangulation_3.h>
#include <CGAL/IO/facets_in_complex_2_to_triangle_mesh.h>
#include <CGAL/make_surface_mesh.h>
#include <CGAL/Surface_mesh.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <string>
#include <unordered_map>
#include <unordered_set>

namespace ks = kintsugi;
using kintsugi_test::Genus3Field;
using kintsugi_test::SphereField;
using kintsugi_test::TorusField;

namespace {

std::atomic<std::size_t> g_calls{0};

template <class F>
struct Counted {
    const F* f;
    double operator()(const ks::Vec3& x) const {
        g_calls.fetch_add(1, std::memory_order_relaxed);
        return (*f)(x);
    }
};

/// Quality counters of a mesh against the field it should follow.
template <class F>
void quality(benchmark::State& state, const F& f, const ks::IndexedMesh& m) {
    const auto rep = ks::topology_report(m);
    const double diag = f.box().diagonal();
    double min_angle = 180, sum_min = 0, dv = 0, df = 0;
    std::size_t below10 = 0;
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> u(0, 1);
    for (const auto& t : m.faces) {
        double tri_min = 180;
        for (int k = 0; k < 3; ++k) {
            const ks::Vec3 a = m.vertices[t[(k + 1) % 3]] - m.vertices[t[k]], b = m.vertices[t[(k + 2) % 3]] - m.vertices[t[k]];
            const double ang = std::atan2(a.cross(b).norm(), a.dot(b)) * 180 / std::numbers::pi;
            tri_min = std::min(tri_min, ang);
        }
        min_angle = std::min(min_angle, tri_min);
        sum_min += tri_min;
        below10 += tri_min < 10;
        double a = u(rng), b = u(rng);
        if (a + b > 1) {
            a = 1 - a;
            b = 1 - b;
        }
        const ks::Vec3 p = m.vertices[t[0]] + a * (m.vertices[t[1]] - m.vertices[t[0]]) + b * (m.vertices[t[2]] - m.vertices[t[0]]);
        df = std::max(df, std::abs(f(p)));
    }
    for (const auto& v : m.vertices) dv = std::max(dv, std::abs(f(v)));
    const double nf = static_cast<double>(std::max<std::size_t>(m.faces.size(), 1));
    state.counters["V"] = static_cast<double>(m.vertices.size());
    state.counters["closed"] = rep.closed;
    state.counters["manifold"] = rep.manifold;
    state.counters["genus"] = static_cast<double>(rep.genus);
    state.counters["comps"] = static_cast<double>(rep.components);
    state.counters["min_angle"] = min_angle;
    state.counters["mean_min_angle"] = sum_min / nf;
    state.counters["pct_below_10deg"] = 100.0 * static_cast<double>(below10) / nf;
    state.counters["maxd_vert"] = dv / diag;
    state.counters["maxd_face"] = df / diag;
}

template <class F>
void BM_extract_isosurface(benchmark::State& state, F f, int cells, bool linear) {
    const auto grid = ks::IsoGrid::fit(f.box(), cells);
    const auto region = ks::IsoRegion::narrow_band(grid, kintsugi_test::surface_samples(f, 6), grid.cell_size);
    ks::IsosurfaceParams p;
    if (linear) p.root.max_iterations = 0;
    ks::IndexedMesh m;
    ks::IsosurfaceResult r;
    for (auto _ : state) {
        g_calls = 0;
        r = ks::extract_isosurface(Counted<F>{&f}, region, m, p);
    }
    state.counters["evals"] = static_cast<double>(g_calls.load());
    state.counters["cubes"] = static_cast<double>(r.cells);
    quality(state, f, m);
}

/// CGAL's surface mesher: angle bound 30° (its default), radius and distance bounds
/// from the cube side h of the kintsugi run it is compared with (radius h, distance h/10).
template <class F>
void BM_CGAL_surface_mesher(benchmark::State& state, F f, int cells, ks::Vec3 inside_point) {
    using Tr = CGAL::Surface_mesh_default_triangulation_3;
    using C2t3 = CGAL::Complex_2_in_triangulation_3<Tr>;
    using GT = Tr::Geom_traits;
    using FT = GT::FT;
    using Point = GT::Point_3;
    using Function = std::function<FT(Point)>;
    using Surface = CGAL::Implicit_surface_3<GT, Function>;
    const auto grid = ks::IsoGrid::fit(f.box(), cells);
    const double h = grid.cell_size;
    const auto b = f.box();
    double R2 = 0;
    for (int c = 0; c < 8; ++c) {
        const ks::Vec3 corner((c & 1) ? b.max.x() : b.min.x(), (c & 2) ? b.max.y() : b.min.y(), (c & 4) ? b.max.z() : b.min.z());
        R2 = std::max(R2, (corner - inside_point).squaredNorm());
    }
    ks::IndexedMesh m;
    for (auto _ : state) {
        g_calls = 0;
        Tr tr;
        C2t3 c2t3(tr);
        const Counted<F> cf{&f};
        Function fun = [&cf](Point p) { return FT(cf(ks::Vec3(p.x(), p.y(), p.z()))); };
        Surface surface(fun, GT::Sphere_3(Point(inside_point.x(), inside_point.y(), inside_point.z()), 1.1 * R2), 1e-6);
        CGAL::Surface_mesh_default_criteria_3<Tr> criteria(30., h, h / 10);
        CGAL::make_surface_mesh(c2t3, surface, criteria, CGAL::Manifold_tag());
        CGAL::Surface_mesh<Point> sm;
        CGAL::facets_in_complex_2_to_triangle_mesh(c2t3, sm);
        m = ks::to_indexed_mesh(sm);
    }
    state.counters["evals"] = static_cast<double>(g_calls.load());
    quality(state, f, m);
}

/// Prototype used only to choose the polygoniser (not in the library): dual contouring
/// in its surface-nets form on the same sparse, surface-following cube set. One
/// vertex per crossed cube (mean of the linear edge crossings, then two Newton steps
/// onto the zero set with a central-difference gradient), one quad per crossed lattice
/// edge joining the 4 cubes around it, split along its shorter diagonal.
template <class F>
ks::IndexedMesh dual_contour(const F& f, const ks::IsoRegion& region) {
    const ks::IsoGrid& g = region.grid;
    const std::int64_t nx = g.cells[0], ny = g.cells[1];
    auto vkey = [&](std::int64_t i, std::int64_t j, std::int64_t k) { return std::uint64_t((k * (ny + 1) + j) * (nx + 1) + i); };
    auto ckey = [&](std::int64_t i, std::int64_t j, std::int64_t k) { return std::uint64_t((k * ny + j) * nx + i); };
    std::unordered_map<std::uint64_t, double> val;
    auto value = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
        const auto key = vkey(i, j, k);
        auto it = val.find(key);
        if (it == val.end()) it = val.emplace(key, f(g.vertex(i, j, k))).first;
        return it->second;
    };
    // visit(p, e, axis, fp, fe) for each of the 12 edges (p -> e along axis) of cube q
    // whose ends have different signs
    auto for_each_crossed_edge = [&](const std::array<std::int64_t, 3>& q, auto&& visit) {
        for (int axis = 0; axis < 3; ++axis)
            for (int a = 0; a < 2; ++a)
                for (int b = 0; b < 2; ++b) {
                    std::array<std::int64_t, 3> p = q;
                    p[(axis + 1) % 3] += a;
                    p[(axis + 2) % 3] += b;
                    std::array<std::int64_t, 3> e = p;
                    e[axis] += 1;
                    const double fp = value(p[0], p[1], p[2]), fe = value(e[0], e[1], e[2]);
                    if ((fp < 0) != (fe < 0)) visit(p, e, axis, fp, fe);
                }
    };
    std::unordered_set<std::uint64_t> active;
    std::vector<std::array<std::int64_t, 3>> wave, next;
    for (const auto& c : region.cells)
        if (active.insert(ckey(c[0], c[1], c[2])).second) wave.push_back({c[0], c[1], c[2]});
    std::vector<std::array<std::int64_t, 4>> crossed;  // lattice vertex + axis
    std::unordered_set<std::uint64_t> crossed_seen;
    while (!wave.empty()) {
        next.clear();
        for (const auto& q : wave)
            for_each_crossed_edge(q, [&](const std::array<std::int64_t, 3>& p, const std::array<std::int64_t, 3>&,
                                         int axis, double, double) {
                if (!crossed_seen.insert(vkey(p[0], p[1], p[2]) * 3 + axis).second) return;
                crossed.push_back({p[0], p[1], p[2], axis});
                for (int du = 0; du < 2; ++du)
                    for (int dv = 0; dv < 2; ++dv) {
                        std::array<std::int64_t, 3> m = p;
                        m[(axis + 1) % 3] -= du;
                        m[(axis + 2) % 3] -= dv;
                        bool ok = true;
                        for (int k = 0; k < 3; ++k) ok = ok && m[k] >= 0 && m[k] < g.cells[k];
                        if (ok && active.insert(ckey(m[0], m[1], m[2])).second) next.push_back(m);
                    }
            });
        wave.swap(next);
    }
    ks::IndexedMesh mesh;
    std::unordered_map<std::uint64_t, ks::Index> vertex_of;
    auto cube_vertex = [&](const std::array<std::int64_t, 3>& q) -> ks::Index {
        const auto [it, fresh] = vertex_of.try_emplace(ckey(q[0], q[1], q[2]), mesh.vertices.size());
        if (!fresh) return it->second;
        ks::Vec3 sum = ks::Vec3::Zero();
        int n = 0;
        for_each_crossed_edge(q, [&](const std::array<std::int64_t, 3>& p, const std::array<std::int64_t, 3>& e, int,
                                     double fa, double fb) {
            const double t = fa / (fa - fb);
            sum += g.vertex(p[0], p[1], p[2]) + t * (g.vertex(e[0], e[1], e[2]) - g.vertex(p[0], p[1], p[2]));
            ++n;
        });
        ks::Vec3 x = sum / n;
        const double h = 1e-6 * g.cell_size;
        for (int it2 = 0; it2 < 2; ++it2) {
            const double fx = f(x);
            ks::Vec3 gr;
            for (int k = 0; k < 3; ++k) {
                ks::Vec3 d = ks::Vec3::Zero();
                d[k] = h;
                gr[k] = (f(x + d) - f(x - d)) / (2 * h);
            }
            if (gr.squaredNorm() > 0) x -= fx * gr / gr.squaredNorm();
        }
        mesh.vertices.push_back(x);
        return it->second;
    };
    for (const auto& c : crossed) {
        const int axis = static_cast<int>(c[3]);
        std::array<ks::Index, 4> quad{};
        bool ok = true;
        const int order[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
        for (int r = 0; r < 4 && ok; ++r) {
            std::array<std::int64_t, 3> m{c[0], c[1], c[2]};
            m[(axis + 1) % 3] -= order[r][0];
            m[(axis + 2) % 3] -= order[r][1];
            for (int k = 0; k < 3; ++k) ok = ok && m[k] >= 0 && m[k] < g.cells[k];
            if (ok) quad[r] = cube_vertex(m);
        }
        if (!ok) continue;  // the border of the grid: left open
        if (!(value(c[0], c[1], c[2]) < 0)) std::swap(quad[1], quad[3]);
        const auto& V = mesh.vertices;
        if ((V[quad[0]] - V[quad[2]]).squaredNorm() <= (V[quad[1]] - V[quad[3]]).squaredNorm()) {
            mesh.faces.push_back({quad[0], quad[1], quad[2]});
            mesh.faces.push_back({quad[0], quad[2], quad[3]});
        } else {
            mesh.faces.push_back({quad[0], quad[1], quad[3]});
            mesh.faces.push_back({quad[1], quad[2], quad[3]});
        }
    }
    return mesh;
}

template <class F>
void BM_dual_contouring_prototype(benchmark::State& state, F f, int cells) {
    const auto grid = ks::IsoGrid::fit(f.box(), cells);
    const auto region = ks::IsoRegion::narrow_band(grid, kintsugi_test::surface_samples(f, 6), grid.cell_size);
    ks::IndexedMesh m;
    for (auto _ : state) {
        g_calls = 0;
        m = dual_contour(Counted<F>{&f}, region);
    }
    state.counters["evals"] = static_cast<double>(g_calls.load());
    quality(state, f, m);
}

}  // namespace

BENCHMARK_CAPTURE(BM_extract_isosurface, sphere_64, SphereField{}, 64, false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_extract_isosurface, sphere_64_linear, SphereField{}, 64, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_CGAL_surface_mesher, sphere_64, SphereField{}, 64, ks::Vec3(0, 0, 0))->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK_CAPTURE(BM_extract_isosurface, torus_64, TorusField{}, 64, false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_extract_isosurface, torus_64_linear, TorusField{}, 64, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_CGAL_surface_mesher, torus_64, TorusField{}, 64, ks::Vec3(1, 0, 0))->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK_CAPTURE(BM_extract_isosurface, genus3_160, Genus3Field{}, 160, false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_extract_isosurface, genus3_160_linear, Genus3Field{}, 160, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_CGAL_surface_mesher, genus3_160, Genus3Field{}, 160, ks::Vec3(0, 1, 0))->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK_CAPTURE(BM_dual_contouring_prototype, sphere_64, SphereField{}, 64)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_dual_contouring_prototype, torus_64, TorusField{}, 64)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_dual_contouring_prototype, genus3_160, Genus3Field{}, 160)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_extract_isosurface, sphere_32, SphereField{}, 32, false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_extract_isosurface, sphere_128, SphereField{}, 128, false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_extract_isosurface, sphere_256, SphereField{}, 256, false)->Unit(benchmark::kMillisecond);

int main(int argc, char** argv) {
    return ks::bench::run(argc, argv, [](const ks::bench::RatioReporter& r) {
        std::printf("\nSame run, real time (ratio > 1: kintsugi faster):\n");
        for (const char* in : {"sphere_64", "torus_64", "genus3_160"})
            r.print_ratio(std::string("BM_extract_isosurface/") + in, std::string("BM_CGAL_surface_mesher/") + in);
    });
}
