// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file pu_triangulation.ipp
/// @brief Step 4 of reconstruct_pu_graphcut: CGAL's regular triangulation of the
/// supports. Included by pu_graphcut_steps.hpp, or, with KINTSUGI_SEPARATE_STAGES, by
/// the one file of the program that compiles it (kintsugi/core/stages.hpp).

#include <kintsugi/core/memory.hpp>
#include <kintsugi/reconstruct/detail/pu_graphcut_steps.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Hidden_point_memory_policy.h>
#include <CGAL/Regular_triangulation_3.h>
#include <CGAL/Regular_triangulation_cell_base_3.h>
#include <CGAL/Regular_triangulation_vertex_base_3.h>
#include <CGAL/Spatial_sort_traits_adapter_3.h>
#include <CGAL/Triangulation_data_structure_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>
#include <CGAL/property_map.h>
#include <CGAL/spatial_sort.h>

#include <array>
#include <cstdint>
#include <limits>

namespace kintsugi::detail {

/// Regular triangulation of weighted sites (centre, weight = radius²) with CGAL.
/// Sites with radius 0 are plain points. Reports progress in [p0, p1].
KINTSUGI_STAGE PUTetMesh regular_tet_mesh(const std::vector<Vec3>& centers, const std::vector<Scalar>& radii,
                                          Progress& progress, double p0, double p1) {
    using K = CGAL::Exact_predicates_inexact_constructions_kernel;
    using Vb = CGAL::Triangulation_vertex_base_with_info_3<Index, K, CGAL::Regular_triangulation_vertex_base_3<K>>;
    // Hidden points are discarded, so the cells need no container for them: an empty
    // std::array instead of the default std::list makes a cell 72 bytes instead of 96
    // (72 MB less at the stage's peak for the 3M cells of the 2M bench input).
    using Cb = CGAL::Regular_triangulation_cell_base_3<K, CGAL::Triangulation_cell_base_3<K>,
                                                       CGAL::Discard_hidden_points, std::array<K::Weighted_point_3, 0>>;
    using Tds = CGAL::Triangulation_data_structure_3<Vb, Cb>;
    using RT = CGAL::Regular_triangulation_3<K, Tds>;
    using WP = K::Weighted_point_3;

    const std::size_t n = centers.size();
    // Hilbert order once, then insertion in chunks so that cancellation is checked.
    std::vector<K::Point_3> pts(n);
    for (std::size_t i = 0; i < n; ++i) pts[i] = K::Point_3(centers[i].x(), centers[i].y(), centers[i].z());
    std::vector<Index> order(n);
    std::iota(order.begin(), order.end(), Index{0});
    using Pmap = CGAL::Pointer_property_map<K::Point_3>::const_type;
    CGAL::spatial_sort(order.begin(), order.end(),
                       CGAL::Spatial_sort_traits_adapter_3<K, Pmap>(CGAL::make_property_map(std::as_const(pts))));
    RT rt;
    // Insertion in chunks of 2^15 sites, each in CGAL's own order for a range
    // (Regular_triangulation_3::insert_with_info, sequential: a spatial sort of the
    // chunk, then locate + insert from the previous vertex's cell), written out here so
    // that progress is reported and the stop token polled every 1024 insertions. The
    // triangulation depends on this order where sites are cospherical (octree cell
    // centres are), so it is the order of a plain rt.insert(chunk) and the chunks
    // stay 2^15: the output is the same as with one insert call per chunk.
    const std::size_t chunk = 1 << 15;
    std::vector<WP> wps;
    std::vector<K::Point_3> bare;
    std::vector<std::size_t> idx;
    for (std::size_t b = 0; b < n; b += chunk) {
        const std::size_t m = std::min(n, b + chunk) - b;
        wps.clear();
        bare.clear();
        for (std::size_t j = b; j < b + m; ++j) {
            const Index i = order[j];
            wps.emplace_back(pts[i], radii[i] * radii[i]);
            bare.push_back(pts[i]);
        }
        idx.resize(m);
        std::iota(idx.begin(), idx.end(), std::size_t{0});
        CGAL::spatial_sort(idx.begin(), idx.end(),
                           CGAL::Spatial_sort_traits_adapter_3<K, Pmap>(CGAL::make_property_map(std::as_const(bare))));
        typename RT::Cell_handle hint;
        for (std::size_t k = 0; k < m; ++k) {
            if ((k & 1023) == 0)
                progress.update(p0 + (p1 - p0) * 0.85 * static_cast<double>(b + k) / static_cast<double>(n));
            const WP& p = wps[idx[k]];
            typename RT::Locate_type lt;
            int li = 0, lj = 0;
            const typename RT::Cell_handle c = rt.locate(p, lt, li, lj, hint);
            const typename RT::Vertex_handle v = rt.insert(p, lt, c, li, lj);
            if (v != typename RT::Vertex_handle()) {
                v->info() = order[b + idx[k]];
                hint = v->cell();
            } else {
                hint = c;
            }
        }
    }
    progress.check();

    PUTetMesh out;
    // Vertices numbered by increasing site index (deterministic, independent of CGAL's storage).
    std::vector<Index> alive;
    alive.reserve(rt.number_of_vertices());
    for (auto v : rt.finite_vertex_handles()) alive.push_back(v->info());
    std::sort(alive.begin(), alive.end());
    std::vector<Index> vertex_of(n, std::numeric_limits<Index>::max());
    for (Index k = 0; k < alive.size(); ++k) vertex_of[alive[k]] = k;
    out.site = alive;
    out.vertices.resize(alive.size());
    for (Index k = 0; k < alive.size(); ++k) out.vertices[k] = centers[alive[k]];
    progress.update(p0 + (p1 - p0) * 0.9);
    // The tets in 32 bits (PUTetMesh), the edges gathered with 32-bit ends: 2M bench input
    // (3M tets, 4.3M edges), 48 MB less while the cells are alive and 170 MB less while
    // the edges are gathered. (The graph cut takes at most 2^32 - 1 nodes.)
    if (alive.size() >= std::numeric_limits<std::uint32_t>::max() - 2)  // + source and sink
        throw invalid_input("kintsugi::reconstruct_pu_graphcut: " + std::to_string(alive.size()) +
                            " supports to triangulate; at most 4,294,967,292 are supported (raise epsilon or "
                            "lower max_level)");
    // A vertex's edge ends are counted in 32 bits below (at most 3 per tet).
    if (rt.number_of_finite_cells() >= std::numeric_limits<std::uint32_t>::max() / 3)
        throw invalid_input("kintsugi::reconstruct_pu_graphcut: the supports' triangulation has " +
                            std::to_string(rt.number_of_finite_cells()) +
                            " tetrahedra; at most 1,431,655,764 are supported (raise epsilon or lower max_level)");
    reserve_huge(out.tets, rt.number_of_finite_cells());
    for (auto c : rt.finite_cell_handles())
        out.tets.push_back({static_cast<std::uint32_t>(vertex_of[c->vertex(0)->info()]),
                            static_cast<std::uint32_t>(vertex_of[c->vertex(1)->info()]),
                            static_cast<std::uint32_t>(vertex_of[c->vertex(2)->info()]),
                            static_cast<std::uint32_t>(vertex_of[c->vertex(3)->info()])});
    rt.clear();
    std::vector<Index>().swap(vertex_of);
    // Edges from the tets' vertex pairs, gathered per smaller vertex (a counting sort),
    // then sorted and made unique per vertex: the same sorted list as CGAL's finite-edge
    // iterator gives, which circulates around each edge from every cell to report it once
    // (6.2 of 11.3 s for 945K sites on a sphere's shell, this way 0.8 s).
    {
        constexpr std::array<std::array<int, 2>, 6> pair{{{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};
        const std::size_t nv = alive.size();
        // The counting and the filling in `parts` ranges of tets, each with its own counts
        // (which become its write offsets within each vertex's slot), so that a thread
        // that is free takes a range: the other side of the stage (step 8's data, the
        // site values) often still holds the second core, and then the ranges run one
        // after the other at no extra cost. The lists are sorted below, so the result
        // does not depend on the ranges or the threads.
        constexpr std::size_t parts = 4;
        const std::size_t nt = out.tets.size();
        auto part_begin = [&](std::size_t c) { return nt * c / parts; };
        std::vector<std::vector<std::uint32_t>> count(parts);
        parallel_for(0, parts, [&](std::size_t c) {
            count[c].assign(nv, 0);
            for (std::size_t i = part_begin(c); i < part_begin(c + 1); ++i) {
                const auto& t = out.tets[i];
                for (const auto& e : pair) ++count[c][std::min(t[std::size_t(e[0])], t[std::size_t(e[1])])];
            }
        }, 1);
        std::vector<std::size_t> start(nv + 1, 0);
        for (std::size_t v = 0; v < nv; ++v) {
            std::uint32_t off = 0;  // at most 3 nt < 2^32 (checked above)
            for (std::size_t c = 0; c < parts; ++c) {
                const std::uint32_t k = count[c][v];
                count[c][v] = off;
                off += k;
            }
            start[v + 1] = start[v] + off;
        }
        std::vector<std::uint32_t> other = huge_vector<std::uint32_t>(start[nv]);
        parallel_for(0, parts, [&](std::size_t c) {
            auto& at = count[c];
            for (std::size_t i = part_begin(c); i < part_begin(c + 1); ++i) {
                const auto& t = out.tets[i];
                for (const auto& e : pair) {
                    const std::uint32_t a = t[std::size_t(e[0])], b = t[std::size_t(e[1])];
                    const std::uint32_t m = std::min(a, b);
                    other[start[m] + at[m]++] = std::max(a, b);
                }
            }
        }, 1);
        std::vector<std::vector<std::uint32_t>>().swap(count);
        std::vector<std::size_t> kept(nv);
        parallel_for(0, nv, [&](std::size_t v) {
            const auto b = other.begin() + static_cast<std::ptrdiff_t>(start[v]);
            const auto e = other.begin() + static_cast<std::ptrdiff_t>(start[v + 1]);
            std::sort(b, e);
            kept[v] = static_cast<std::size_t>(std::unique(b, e) - b);
        }, 1024);
        reserve_huge(out.edges, std::accumulate(kept.begin(), kept.end(), std::size_t{0}));
        for (Index v = 0; v < nv; ++v)
            for (std::size_t j = 0; j < kept[v]; ++j) out.edges.push_back({v, Index{other[start[v] + j]}});
    }
    progress.update(p1);
    return out;
}

}  // namespace kintsugi::detail
