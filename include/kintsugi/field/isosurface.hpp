// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file isosurface.hpp
/// @brief `extract_isosurface`: the zero set of any ScalarField as a triangle mesh,
/// evaluating the field only near the surface.
///
/// @code
/// #include <kintsugi/field/isosurface.hpp>
/// auto sphere = [](const kintsugi::Vec3& x) { return x.norm() - 1; };   // < 0 inside
/// const auto grid = kintsugi::IsoGrid::fit(box, 128);                   // 128 cubes on the longest side
/// kintsugi::IndexedMesh mesh;                                          // or CGAL::Surface_mesh, ...
/// auto r = kintsugi::extract_isosurface(sphere, kintsugi::IsoRegion::narrow_band(grid, samples, radius),
///                                       mesh);
/// // r.field_evaluations, r.cells, r.timings
/// @endcode
///
/// **Method** (chosen by measurement, docs/methods/isosurface.md): marching tetrahedra
/// (Doi and Koide, IEICE 1991) on the Kuhn (Freudenthal) split of a uniform grid of
/// cubes into 6 tetrahedra around each cube's main diagonal, visited sparsely by
/// surface continuation (Bloomenthal, "Polygonization of implicit surfaces", CAGD
/// 1988): the caller's cubes seed the search, and every cube around a crossed lattice
/// edge joins it, so the surface is followed through the grid however small the seed.
/// Each output vertex is the root of the field on its edge (find_edge_root, Illinois
/// refinement on the field itself), not a linear interpolation.
///
/// **Output guarantee.** The mesh is the zero set of a piecewise-linear function that is
/// never 0 at a lattice vertex (f == 0 counts as outside), so it is a 2-manifold with
/// consistently outward triangles (from f < 0 to f > 0) and no degenerate triangle;
/// every component found is closed unless it reaches the border of the grid, where it
/// is cut open. NaN (outside a field's domain) counts as outside: the surface closes
/// along the border of the domain.

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/field/edge_root.hpp>
#include <kintsugi/mesh/marching_tetrahedra.hpp>
#include <kintsugi/spatial/octree.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

namespace kintsugi {

/// A uniform grid of cubes: the resolution of extract_isosurface.
struct IsoGrid {
    Vec3 origin = Vec3::Zero();        ///< minimum corner (caller's units)
    Scalar cell_size = 0;              ///< cube side (caller's units), > 0
    std::array<int, 3> cells{0, 0, 0}; ///< cubes per axis, each in [1, 2^20]

    /// The grid over `box` enlarged by `margin` cubes on every side, with
    /// `cells_longest_side` cubes along the box's longest side (>= 1).
    /// @throws invalid_input for an empty or non-finite box or a count out of range.
    [[nodiscard]] static IsoGrid fit(const BoundingBox& box, int cells_longest_side, int margin = 1) {
        const std::string fn = "kintsugi::IsoGrid::fit: ";
        if (box.empty() || !box.min.allFinite() || !box.max.allFinite())
            throw invalid_input(fn + "the box is empty or not finite; give the bounding box of the surface");
        if (cells_longest_side < 1 || cells_longest_side > (1 << 20) - 2 * std::max(margin, 0) || margin < 0)
            throw invalid_input(fn + "cells_longest_side = " + std::to_string(cells_longest_side) + ", margin = " +
                                std::to_string(margin) + ": need cells in [1, 2^20] and margin >= 0");
        const Scalar longest = box.extent().maxCoeff();
        IsoGrid g;
        g.cell_size = longest > 0 ? longest / cells_longest_side : Scalar(1);
        for (int k = 0; k < 3; ++k)
            g.cells[k] = std::max(1, static_cast<int>(std::ceil(box.extent()[k] / g.cell_size - Scalar(1e-9)))) +
                         2 * margin;
        g.origin = box.center() - Scalar(0.5) * g.cell_size * Vec3(g.cells[0], g.cells[1], g.cells[2]);
        return g;
    }
    /// Position of lattice vertex (i, j, k).
    [[nodiscard]] Vec3 vertex(std::int64_t i, std::int64_t j, std::int64_t k) const {
        return origin + cell_size * Vec3(static_cast<Scalar>(i), static_cast<Scalar>(j), static_cast<Scalar>(k));
    }
};

/// Where extract_isosurface looks: cubes of a grid (the seeds of the search). Build
/// it with one of the factories (full, narrow_band, from_boxes, from_octree) or fill
/// `cells` yourself.
struct IsoRegion {
    IsoGrid grid;
    /// Seed cubes as (i, j, k) in [0, cells): any order, repeats allowed.
    std::vector<std::array<int, 3>> cells;

    /// Every cube of the grid (evaluates the whole volume; for small grids).
    [[nodiscard]] static IsoRegion full(const IsoGrid& grid) {
        IsoRegion r{grid, {}};
        detail_check(grid, "kintsugi::IsoRegion::full");
        for (int k = 0; k < grid.cells[2]; ++k)
            for (int j = 0; j < grid.cells[1]; ++j)
                for (int i = 0; i < grid.cells[0]; ++i) r.cells.push_back({i, j, k});
        return r;
    }
    /// The narrow band: cubes that meet a ball of `radius` around a sample point
    /// (points on or near the surface; samples outside the grid are skipped).
    /// radius >= 0 (0: the cube holding each point).
    template <PointSet P>
    [[nodiscard]] static IsoRegion narrow_band(const IsoGrid& grid, const P& points, Scalar radius) {
        std::vector<std::pair<Vec3, Vec3>> boxes;
        const std::size_t n = num_points(points);
        boxes.reserve(n);
        if (!(radius >= 0) || !std::isfinite(radius))
            throw invalid_input("kintsugi::IsoRegion::narrow_band: radius = " + std::to_string(radius) +
                                " must be finite and >= 0 (e.g. one cube side)");
        for (std::size_t i = 0; i < n; ++i) {
            const Vec3 p = point_at(points, i);
            if (!p.allFinite())
                throw invalid_input("kintsugi::IsoRegion::narrow_band: point " + std::to_string(i) +
                                    " has a NaN or infinite coordinate; remove it first");
            boxes.emplace_back(p - Vec3::Constant(radius), p + Vec3::Constant(radius));
        }
        return from_boxes(grid, boxes, "kintsugi::IsoRegion::narrow_band");
    }
    /// The cubes that meet any of the boxes [lo, hi] (e.g. octree leaves: the leaves
    /// holding points are a narrow band of the scanned surface). Parts outside the
    /// grid are skipped.
    [[nodiscard]] static IsoRegion from_boxes(const IsoGrid& grid, const std::vector<std::pair<Vec3, Vec3>>& boxes,
                                              const char* fn = "kintsugi::IsoRegion::from_boxes") {
        detail_check(grid, fn);
        IsoRegion r{grid, {}};
        for (std::size_t b = 0; b < boxes.size(); ++b) {
            const auto& [lo, hi] = boxes[b];
            if (!lo.allFinite() || !hi.allFinite() || (lo.array() > hi.array()).any())
                throw invalid_input(std::string(fn) + ": box " + std::to_string(b) +
                                    " is not finite or has lo > hi; give finite boxes");
            std::array<int, 3> a{}, z{};
            bool empty = false;
            for (int k = 0; k < 3; ++k) {
                const Scalar u0 = (lo[k] - grid.origin[k]) / grid.cell_size, u1 = (hi[k] - grid.origin[k]) / grid.cell_size;
                if (u1 < 0 || u0 > grid.cells[k]) empty = true;
                a[k] = static_cast<int>(std::clamp<Scalar>(std::floor(u0), 0, grid.cells[k] - 1));
                z[k] = static_cast<int>(std::clamp<Scalar>(std::floor(u1), 0, grid.cells[k] - 1));
            }
            if (empty) continue;
            for (int k = a[2]; k <= z[2]; ++k)
                for (int j = a[1]; j <= z[1]; ++j)
                    for (int i = a[0]; i <= z[0]; ++i) r.cells.push_back({i, j, k});
        }
        return r;
    }

    /// The leaves of an octree that hold points, on the grid of its finest level
    /// (2^max_level cubes per side of its cube, in the octree's frame): for an octree
    /// built on scan points, a band one finest cell wide around the scanned surface.
    /// @throws invalid_input for an empty octree.
    [[nodiscard]] static IsoRegion from_octree(const Octree& octree) {
        if (octree.size() == 0)
            throw invalid_input("kintsugi::IsoRegion::from_octree: the octree is empty; build it on points first");
        IsoGrid grid;
        const int n = 1 << octree.max_level();
        grid.origin = octree.cube_min();
        grid.cell_size = octree.cube_side() / n;
        grid.cells = {n, n, n};
        std::vector<std::pair<Vec3, Vec3>> boxes;
        const Vec3 inset = Vec3::Constant(grid.cell_size / 4);  // whole cubes only
        for (Index c = 0; c < octree.size(); ++c)
            if (!octree.cell_points(c).empty()) boxes.emplace_back(octree.cell_min(c) + inset, octree.cell_max(c) - inset);
        return from_boxes(grid, boxes, "kintsugi::IsoRegion::from_octree");
    }

    /// Throws invalid_input when the grid is unusable.
    static void detail_check(const IsoGrid& g, const std::string& fn) {
        if (!g.origin.allFinite() || !(g.cell_size > 0) || !std::isfinite(g.cell_size))
            throw invalid_input(fn + ": the grid needs a finite origin and a positive finite cell_size");
        for (int k = 0; k < 3; ++k)
            if (g.cells[k] < 1 || g.cells[k] > (1 << 20))
                throw invalid_input(fn + ": the grid has " + std::to_string(g.cells[k]) + " cubes along axis " +
                                    std::to_string(k) + "; need [1, 2^20]");
    }
};

/// Parameters of extract_isosurface (aggregate; field order is API, append only).
struct IsosurfaceParams {
    /// The root search on each crossed edge. samples = 1: the bracket is the edge's
    /// ends (the lattice already shows the crossing); more samples look for an earlier
    /// crossing on the edge. max_iterations = 0 gives linear interpolation of the end
    /// values (fewer evaluations, vertices off the zero set by O(h²·curvature)).
    EdgeRootParams root{.samples = 1, .max_iterations = 30, .tolerance = 1e-7};
    /// Output vertices stay at least this fraction of their edge away from both ends
    /// (no coincident vertices, no degenerate triangle), in (0, 0.5). Moves a vertex
    /// off the zero set by at most this fraction of a cube side.
    Scalar min_edge_fraction = 1e-3;
    /// Progress callback and cancellation.
    RunControl control{};
};

/// Result of extract_isosurface.
struct IsosurfaceResult {
    Status status = Status::ok;
    std::size_t field_evaluations = 0;   ///< all calls of the field (lattice + roots)
    std::size_t lattice_evaluations = 0; ///< at lattice vertices
    std::size_t root_evaluations = 0;    ///< inside edges, by the root search
    std::size_t seed_cells = 0;          ///< distinct cubes of the region
    std::size_t cells = 0;               ///< cubes visited (seeds + the ones the surface led to)
    std::size_t crossed_cells = 0;       ///< cubes holding part of the surface
    std::size_t vertices = 0;            ///< output vertices (= crossed lattice edges)
    std::size_t faces = 0;               ///< output triangles
    std::vector<StageTiming> timings;    ///< "isosurface_cells", "isosurface_vertices", "isosurface_faces"
};

namespace detail {

/// The Kuhn split of a cube (corner c has offset (c & 1, c >> 1 & 1, c >> 2 & 1)):
/// 6 tets (0, a, a|b, 7) around the main diagonal, in positive order.
inline const std::array<std::array<int, 4>, 6>& kuhn_tets() {
    static const std::array<std::array<int, 4>, 6> tets = [] {
        std::array<std::array<int, 4>, 6> t{};
        const int axes[6][2] = {{1, 2}, {1, 4}, {2, 1}, {2, 4}, {4, 1}, {4, 2}};
        auto pos = [](int c) { return Vec3(c & 1, (c >> 1) & 1, (c >> 2) & 1); };
        for (int i = 0; i < 6; ++i) {
            t[i] = {0, axes[i][0], axes[i][0] | axes[i][1], 7};
            const Scalar det = (pos(t[i][1]) - pos(0)).cross(pos(t[i][2]) - pos(0)).dot(pos(7) - pos(0));
            if (det < 0) std::swap(t[i][2], t[i][3]);
        }
        return t;
    }();
    return tets;
}

/// The 19 edges of the Kuhn split of a cube: corner pairs (a, b) with a ⊂ b as bit sets.
inline const std::array<std::array<int, 2>, 19>& kuhn_edges() {
    static const std::array<std::array<int, 2>, 19> edges = [] {
        std::array<std::array<int, 2>, 19> e{};
        int n = 0;
        for (int a = 0; a < 8; ++a)
            for (int b = 0; b < 8; ++b)
                if (a != b && (a & b) == a) e[n++] = {a, b};
        return e;
    }();
    return edges;
}

struct IsoLattice {
    std::int64_t nx, ny, nz;  ///< cubes per axis
    [[nodiscard]] std::uint64_t cell_key(std::int64_t i, std::int64_t j, std::int64_t k) const {
        return static_cast<std::uint64_t>((k * ny + j) * nx + i);
    }
    [[nodiscard]] std::array<std::int64_t, 3> cell_ijk(std::uint64_t c) const {
        const auto s = static_cast<std::int64_t>(c);
        return {s % nx, (s / nx) % ny, s / (nx * ny)};
    }
    [[nodiscard]] std::uint64_t vertex_key(std::int64_t i, std::int64_t j, std::int64_t k) const {
        return static_cast<std::uint64_t>((k * (ny + 1) + j) * (nx + 1) + i);
    }
    [[nodiscard]] std::array<std::int64_t, 3> vertex_ijk(std::uint64_t v) const {
        const auto s = static_cast<std::int64_t>(v);
        return {s % (nx + 1), (s / (nx + 1)) % (ny + 1), s / ((nx + 1) * (ny + 1))};
    }
    /// Key of corner c of cube (i, j, k).
    [[nodiscard]] std::uint64_t corner(const std::array<std::int64_t, 3>& q, int c) const {
        return vertex_key(q[0] + (c & 1), q[1] + ((c >> 1) & 1), q[2] + ((c >> 2) & 1));
    }
};

}  // namespace detail

/// @brief Extracts the zero set of `field` as a triangle mesh, following the surface
/// from the cubes of `region` (see the file comment for the method and guarantee).
///
/// @tparam F a ScalarField (kintsugi's sign: < 0 inside, > 0 outside, NaN outside its
///         domain); called concurrently, so f(x) must be thread-safe.
/// @tparam M a TopologyMutableMesh (IndexedMesh, CGAL::Surface_mesh, ...); cleared
///         and filled on success, untouched on cancellation or error.
/// @param field  the field.
/// @param region the grid (the resolution: a surface detail smaller than a cube may
///        be missed) and the seed cubes; each component of the zero set that crosses
///        a lattice edge of a seed cube is extracted whole (within the grid).
/// @param out    the output mesh.
/// @param params root search, vertex clamp, RunControl.
/// @throws invalid_input for a grid with a non-positive or non-finite cell size or a
///         cube count outside [1, 2^20], a seed cube outside the grid, an empty region,
///         root parameters out of range (samples < 1, max_iterations < 0, tolerance <=
///         0) or min_edge_fraction outside (0, 0.5). `out` untouched.
/// @return counts (field evaluations, cubes) and timings. Status::cancelled: stopped
///         through params.control; `out` untouched.
///
/// Cost: field evaluations ≈ 8 per seed cube + (1 + roots) per crossed edge, so it
/// grows with the surface's area in cubes, not with the grid's volume (measured in
/// docs/methods/isosurface.md). Deterministic whatever the thread count.
template <ScalarField F, TopologyMutableMesh M>
IsosurfaceResult extract_isosurface(const F& field, const IsoRegion& region, M& out,
                                    const IsosurfaceParams& params = {}) {
    const std::string fn = "kintsugi::extract_isosurface";
    IsoRegion::detail_check(region.grid, fn);
    if (region.cells.empty())
        throw invalid_input(fn + ": the region has no cube; give seed cubes near the surface "
                                 "(IsoRegion::narrow_band, from_boxes or full)");
    for (std::size_t c = 0; c < region.cells.size(); ++c)
        for (int k = 0; k < 3; ++k)
            if (region.cells[c][k] < 0 || region.cells[c][k] >= region.grid.cells[k])
                throw invalid_input(fn + ": region cube " + std::to_string(c) + " = (" +
                                    std::to_string(region.cells[c][0]) + ", " + std::to_string(region.cells[c][1]) +
                                    ", " + std::to_string(region.cells[c][2]) + ") lies outside the grid of " +
                                    std::to_string(region.grid.cells[0]) + " x " + std::to_string(region.grid.cells[1]) +
                                    " x " + std::to_string(region.grid.cells[2]) + " cubes");
    if (params.root.samples < 1 || params.root.max_iterations < 0 || !(params.root.tolerance > 0))
        throw invalid_input(fn + ": root.samples must be >= 1, root.max_iterations >= 0 and root.tolerance > 0");
    if (!(params.min_edge_fraction > 0 && params.min_edge_fraction < 0.5))
        throw invalid_input(fn + ": min_edge_fraction must lie in (0, 0.5), e.g. 1e-3");

    const IsoGrid& grid = region.grid;
    const detail::IsoLattice L{grid.cells[0], grid.cells[1], grid.cells[2]};
    const auto& tets = detail::kuhn_tets();
    const auto& edges = detail::kuhn_edges();
    return detail::run_cancellable<IsosurfaceResult>(params.control, [&](detail::Progress& progress) {
        IsosurfaceResult res;
        // Stage 1: the cubes, by waves from the seeds; every cube around a crossed
        // lattice edge joins the next wave.
        progress.stage("isosurface_cells", 0.0, 0.5);
        std::vector<std::uint64_t> wave;
        wave.reserve(region.cells.size());
        for (const auto& c : region.cells) wave.push_back(L.cell_key(c[0], c[1], c[2]));
        std::sort(wave.begin(), wave.end());
        wave.erase(std::unique(wave.begin(), wave.end()), wave.end());
        res.seed_cells = wave.size();
        std::unordered_set<std::uint64_t> active(wave.begin(), wave.end());
        std::unordered_map<std::uint64_t, Scalar> value;
        value.reserve(wave.size() * 2);
        std::vector<std::uint64_t> need, next;
        std::vector<Scalar> vals;
        auto inside = [&](std::uint64_t v) { return value.find(v)->second < 0; };  // NaN: outside
        std::size_t waves = 0;
        while (!wave.empty()) {
            progress.update(1.0 - 1.0 / (1.0 + 0.02 * static_cast<double>(++waves)));
            need.clear();
            for (const std::uint64_t c : wave) {
                const auto q = L.cell_ijk(c);
                for (int k = 0; k < 8; ++k) {
                    const std::uint64_t v = L.corner(q, k);
                    if (!value.count(v)) need.push_back(v);
                }
            }
            std::sort(need.begin(), need.end());
            need.erase(std::unique(need.begin(), need.end()), need.end());
            vals.resize(need.size());
            parallel_for(0, need.size(), [&](std::size_t i) {
                const auto p = L.vertex_ijk(need[i]);
                vals[i] = static_cast<Scalar>(field(grid.vertex(p[0], p[1], p[2])));
            }, 256);
            res.lattice_evaluations += need.size();
            for (std::size_t i = 0; i < need.size(); ++i) value.emplace(need[i], vals[i]);
            progress.check();
            next.clear();
            for (const std::uint64_t c : wave) {
                const auto q = L.cell_ijk(c);
                for (const auto& e : edges) {
                    if (inside(L.corner(q, e[0])) == inside(L.corner(q, e[1]))) continue;
                    // the cubes holding this edge: offset -1 or 0 on the axes it does not span
                    const int span = e[0] ^ e[1];
                    for (int o = 0; o < 8; ++o) {
                        if (o & span) continue;
                        std::array<std::int64_t, 3> m{};
                        bool ok = true;
                        for (int k = 0; k < 3; ++k) {
                            m[k] = q[k] + ((e[0] >> k) & 1) - ((o >> k) & 1);
                            ok = ok && m[k] >= 0 && m[k] < grid.cells[k];
                        }
                        if (!ok) continue;
                        const std::uint64_t key = L.cell_key(m[0], m[1], m[2]);
                        if (active.insert(key).second) next.push_back(key);
                    }
                }
            }
            std::sort(next.begin(), next.end());
            wave.swap(next);
        }
        std::vector<std::uint64_t> cells(active.begin(), active.end());
        std::sort(cells.begin(), cells.end());
        res.cells = cells.size();

        // Stage 2: one output vertex per crossed edge (numbered in cube order), placed
        // at the root of the field on the edge.
        progress.stage("isosurface_vertices", 0.5, 0.9);
        IndexedMesh mesh;
        std::unordered_map<std::uint64_t, Index> vertex_of;  // lattice vertex key * 8 + direction
        std::vector<std::array<std::uint64_t, 2>> vertex_edge;  // (inside end, outside end)
        auto edge_key = [&](std::uint64_t a, std::uint64_t b) {
            if (a > b) std::swap(a, b);
            const auto pa = L.vertex_ijk(a), pb = L.vertex_ijk(b);
            const auto dir = static_cast<std::uint64_t>((pb[0] - pa[0]) | ((pb[1] - pa[1]) << 1) | ((pb[2] - pa[2]) << 2));
            return a * 8 + dir;
        };
        auto for_each_crossed_tet = [&](auto&& visit) {
            for (std::size_t n = 0; n < cells.size(); ++n) {
                if ((n & 0x3FFF) == 0) progress.check();
                const auto q = L.cell_ijk(cells[n]);
                std::array<std::uint64_t, 8> cv{};
                int nin_cube = 0;
                for (int k = 0; k < 8; ++k) {
                    cv[k] = L.corner(q, k);
                    nin_cube += inside(cv[k]);
                }
                if (nin_cube == 0 || nin_cube == 8) continue;
                for (const auto& t : tets) {
                    const std::array<Index, 4> V{cv[t[0]], cv[t[1]], cv[t[2]], cv[t[3]]};
                    const int nin = inside(V[0]) + inside(V[1]) + inside(V[2]) + inside(V[3]);
                    if (nin == 0 || nin == 4) continue;
                    visit(V, nin);
                }
                ++res.crossed_cells;
            }
        };
        auto new_vertex = [&](Index a, Index b) -> Index {
            const auto [it, fresh] = vertex_of.try_emplace(edge_key(a, b), vertex_edge.size());
            if (fresh) vertex_edge.push_back(inside(a) ? std::array<std::uint64_t, 2>{a, b} : std::array<std::uint64_t, 2>{b, a});
            return it->second;
        };
        for_each_crossed_tet([&](const std::array<Index, 4>& V, int nin) {
            detail::mt_tet_faces(V, nin, inside, new_vertex, [](Index, Index, Index) {},
                                 [](Index, Index) { return Scalar(0); });
        });
        const std::size_t nv = vertex_edge.size();
        mesh.vertices.resize(nv);
        std::vector<std::uint32_t> evals(nv, 0);
        const std::size_t block = 4096;
        for (std::size_t b0 = 0; b0 < nv; b0 += 16 * block) {
            progress.update(static_cast<double>(b0) / static_cast<double>(nv));
            parallel_for(b0, std::min(nv, b0 + 16 * block), [&](std::size_t i) {
                const std::uint64_t a = vertex_edge[i][0], b = vertex_edge[i][1];
                const auto ia = L.vertex_ijk(a), ib = L.vertex_ijk(b);
                const Vec3 pa = grid.vertex(ia[0], ia[1], ia[2]);
                const Vec3 d = grid.vertex(ib[0], ib[1], ib[2]) - pa;
                const Scalar fa = value.find(a)->second, fb = value.find(b)->second;
                std::uint32_t count = 0;
                // NaN counts as outside, as the mirror of the inside end's value: the
                // search then closes in on the border of the field's domain.
                const auto root = find_edge_root([&](Scalar t) {
                    Scalar v = 0;
                    if (t <= 0) v = fa;
                    else if (t >= 1) v = fb;
                    else {
                        ++count;
                        v = static_cast<Scalar>(field(Vec3(pa + t * d)));
                    }
                    return std::isnan(v) ? -fa : v;
                }, params.root);
                // a root always exists: fa < 0 <= fb (or NaN, mapped to 0)
                const Scalar t = std::clamp(root.value_or(Scalar(0.5)), params.min_edge_fraction,
                                            1 - params.min_edge_fraction);
                mesh.vertices[i] = pa + t * d;
                evals[i] = count;
            }, 256);
        }
        for (const auto c : evals) res.root_evaluations += c;

        // Stage 3: the triangles, in cube order.
        progress.stage("isosurface_faces", 0.9, 1.0);
        res.crossed_cells = 0;
        auto find_vertex = [&](Index a, Index b) { return vertex_of.find(edge_key(a, b))->second; };
        auto sq = [&](Index u, Index w) { return (mesh.vertices[u] - mesh.vertices[w]).squaredNorm(); };
        for_each_crossed_tet([&](const std::array<Index, 4>& V, int nin) {
            detail::mt_tet_faces(V, nin, inside, find_vertex,
                                 [&](Index a, Index b, Index c) { mesh.faces.push_back({a, b, c}); }, sq);
        });
        res.vertices = mesh.vertices.size();
        res.faces = mesh.faces.size();
        res.field_evaluations = res.lattice_evaluations + res.root_evaluations;
        progress.check();
        assign_mesh(out, mesh);
        res.timings = progress.finish();
        res.status = Status::ok;
        return res;
    });
}

}  // namespace kintsugi
