// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file fair.hpp
/// @brief Thin-plate (biharmonic) fairing of a subset of a mesh's vertices: the chosen
/// vertices take the positions that minimise the squared umbrella Laplacian, the
/// others stay fixed, so the patch continues the position and the slope of the
/// surface around it. Used by the hole fill (mesh/holes.hpp) and the PU + graph-cut
/// reconstruction (its unsupported vertices).
///
/// @code
/// std::vector<std::uint8_t> free(mesh.vertices.size(), 0);
/// for (auto v : patch) free[v] = 1;                  // these vertices move
/// auto r = kintsugi::fair_biharmonic(mesh, free);   // r.moved_vertices
/// @endcode

#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/mesh/vertex_subset.hpp>

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseLU>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

namespace detail {

/// Default of FairParams::delta and FillParams::fair_delta (the same pull).
inline constexpr Scalar default_fair_delta = 1e-8;

/// Throws invalid_input unless the pull `delta` (the parameter `name` of `fn`) is finite
/// and >= 0.
inline void check_fair_delta(Scalar delta, const std::string& fn, const char* name) {
    if (!(delta >= 0) || !std::isfinite(delta))
        throw invalid_input(fn + name + " = " + std::to_string(delta) + " must be finite and >= 0 (default 1e-8)");
}

}  // namespace detail

/// Parameters of fair_biharmonic.
struct FairParams {
    /// Weight of the pull of each free vertex to its start position, finite and >= 0
    /// (default 1e-8; 0 = no pull). Tiny, it only keeps a component with no fixed vertex
    /// where it is (the system would be singular there).
    Scalar delta = detail::default_fair_delta;
    /// Progress callback and stop token (default: none); a cancelled run leaves the mesh untouched.
    RunControl control{};
};

/// Result of fair_biharmonic: moved_vertices = the free vertices that have a neighbour
/// (the unknowns of the system), 0 when the factorisation failed (nothing moved).
using FairResult = VertexSubsetResult;

namespace detail {

/// The sparse system of a fairing: one unknown per free vertex with a neighbour, three
/// right-hand sides (x, y, z). A fairing adds its entries, then solve() writes the
/// solution into the free vertices.
struct FairSystem {
    MovableVertices unknowns;
    std::vector<std::uint8_t> rows;  ///< the unknowns and their neighbours (one-rings that involve an unknown)
    std::vector<Eigen::Triplet<Scalar>> entries;
    Eigen::Matrix<Scalar, Eigen::Dynamic, 3> rhs;

    FairSystem(const MeshTopology& topo, std::size_t n, const std::vector<std::uint8_t>& free)
        : unknowns(movable_vertices(topo, n, free)), rows(rows_near(topo, unknowns.vertices, n)),
          rhs(Eigen::Matrix<Scalar, Eigen::Dynamic, 3>::Zero(static_cast<Eigen::Index>(unknowns.vertices.size()), 3)) {}

    [[nodiscard]] std::size_t size() const { return unknowns.vertices.size(); }
    /// Column of vertex v, MovableVertices::none when v is fixed.
    [[nodiscard]] Index column(Index v) const { return unknowns.column[v]; }
    void add(std::size_t r, std::size_t c, Scalar a) { entries.emplace_back(static_cast<int>(r), static_cast<int>(c), a); }

    /// Factorises with Solver and writes the solution into x; returns the number of
    /// vertices moved, 0 (x unchanged) when the factorisation or the solve fails.
    template <class Solver>
    std::size_t solve(std::vector<Vec3>& x) const {
        const auto m = static_cast<Eigen::Index>(size());
        Eigen::SparseMatrix<Scalar> A(m, m);
        A.setFromTriplets(entries.begin(), entries.end());
        A.makeCompressed();
        Solver solver;
        solver.compute(A);
        if (solver.info() != Eigen::Success) return 0;
        const Eigen::Matrix<Scalar, Eigen::Dynamic, 3> sol = solver.solve(rhs);
        if (solver.info() != Eigen::Success || !sol.allFinite()) return 0;
        for (Eigen::Index k = 0; k < m; ++k) x[unknowns.vertices[static_cast<std::size_t>(k)]] = sol.row(k).transpose();
        return size();
    }
};

/// The vertices with free[v] != 0 take the positions that minimise Σ_i |L x_i|² (L the
/// uniform umbrella operator, mean of the one ring minus the vertex; the sum over every
/// vertex whose umbrella involves a free vertex) plus delta Σ_free |x_v - x_v⁰|², the
/// other vertices fixed. Solved with Eigen's SimplicialLDLT. Returns the number of
/// free vertices moved (0 when the factorisation fails; then x is unchanged).
inline std::size_t biharmonic_fill(std::vector<Vec3>& x, const MeshTopology& topo,
                                   const std::vector<std::uint8_t>& free, Scalar delta = default_fair_delta) {
    FairSystem sys(topo, x.size(), free);
    if (sys.size() == 0) return 0;
    std::vector<std::pair<Index, Scalar>> a;  // free part of the row: (column, coefficient)
    for (Index i = 0; i < x.size(); ++i) {
        if (!sys.rows[i]) continue;
        const auto nb = topo.vertex_neighbors(i);
        if (nb.empty()) continue;
        const Scalar c = Scalar(1) / static_cast<Scalar>(nb.size());
        a.clear();
        Vec3 b = Vec3::Zero();
        auto add = [&](Index v, Scalar coef) {
            if (sys.column(v) != MovableVertices::none) a.emplace_back(sys.column(v), coef);
            else b += coef * x[v];
        };
        add(i, -1);
        for (const Index u : nb) add(u, c);
        for (const auto& [p, ap] : a) {
            for (const auto& [q, aq] : a) sys.add(p, q, ap * aq);
            sys.rhs.row(static_cast<Eigen::Index>(p)) -= ap * b.transpose();
        }
    }
    for (std::size_t k = 0; k < sys.size(); ++k) {
        sys.add(k, k, delta);
        sys.rhs.row(static_cast<Eigen::Index>(k)) += delta * x[sys.unknowns.vertices[k]].transpose();
    }
    return sys.solve<Eigen::SimplicialLDLT<Eigen::SparseMatrix<Scalar>>>(x);
}

/// The vertices with free[v] != 0 solve the discrete bi-Laplace equation (L L x)_v = 0,
/// the others fixed (Liepa 2003; CGAL's fair with continuity 1). L is the cotangent
/// Laplacian over the barycentric vertex area, (L x)_i = Σ_j w_ij (x_j - x_i) / A_i,
/// w_ij = (cot α + cot β) / 2 measured on the positions before the solve and clamped to
/// [0.01, 100] (flat or needle triangles). Unlike biharmonic_fill (uniform weights,
/// Σ |L x|² minimised over every row, so L x = 0 is also asked on the fixed vertices
/// next to the patch), only the free vertices' equations are imposed: the fixed ring
/// carries the surrounding curvature into the patch. Measured on the hole fill
/// (docs/methods/mesh_editing.md): sphere cap max 3.9 % -> 2.0 %. Non-symmetric:
/// Eigen's SparseLU. Returns the number of free vertices moved (0 when the solve fails;
/// then x is unchanged).
inline std::size_t bilaplacian_fill(std::vector<Vec3>& x, const MeshTopology& topo,
                                    const std::vector<std::uint8_t>& free) {
    const std::size_t n = x.size();
    FairSystem sys(topo, n, free);
    if (sys.size() == 0) return 0;
    // Cotangent weight of each edge (i, j): half the sum of the cotangents opposite it.
    auto cot_weight = [&](Index i, Index j) -> Scalar {
        const auto e = topo.find_edge(i, j);
        Scalar w = 0;
        if (e)
            for (const Index f : topo.edge_faces(*e)) {
                const Face& t = topo.faces()[f];
                const Index o = t[0] != i && t[0] != j ? t[0] : (t[1] != i && t[1] != j ? t[1] : t[2]);
                const Vec3 a = x[i] - x[o], b = x[j] - x[o];
                w += a.dot(b) / std::max(a.cross(b).norm(), std::numeric_limits<Scalar>::min()) / 2;
            }
        constexpr Scalar w_min = Scalar(0.01);
        return std::clamp(w, w_min, 1 / w_min);
    };
    // L as sparse rows over all vertices (only the needed rows filled).
    std::vector<std::vector<std::pair<Index, Scalar>>> L(n);
    for (Index i = 0; i < n; ++i) {
        if (!sys.rows[i]) continue;
        const auto nb = topo.vertex_neighbors(i);
        if (nb.empty()) continue;
        Scalar sum = 0;
        for (const Index u : nb) {
            const Scalar w = cot_weight(i, u);
            L[i].emplace_back(u, w);
            sum += w;
        }
        // Divided by the vertex's barycentric area (a third of its faces' areas), as
        // CGAL's Voronoi-area fairing weights; the weight sum where that area is 0.
        Scalar area = 0;
        for (const Index f : topo.vertex_faces(i)) {
            const Face& t = topo.faces()[f];
            area += (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]).norm() / 6;
        }
        const Scalar scale = area > 0 ? area : sum;
        for (auto& [u, w] : L[i]) w /= scale;
        Scalar diag = 0;
        for (const auto& [u, w] : L[i]) diag -= w;
        L[i].emplace_back(i, diag);
    }
    for (std::size_t r = 0; r < sys.size(); ++r)
        for (const auto& [i, a] : L[sys.unknowns.vertices[r]])
            for (const auto& [j, b] : L[i]) {
                if (sys.column(j) != MovableVertices::none) sys.add(r, sys.column(j), a * b);
                else sys.rhs.row(static_cast<Eigen::Index>(r)) -= a * b * x[j].transpose();
            }
    return sys.solve<Eigen::SparseLU<Eigen::SparseMatrix<Scalar>>>(x);
}

}  // namespace detail

/// @brief Thin-plate fairing of the chosen vertices: minimises Σ |L x|² with the uniform
/// umbrella Laplacian L, the other vertices fixed (the discrete biharmonic equation
/// L²x = 0 on the free vertices; Kobbelt, "Discrete fairing", 1997; as the fairing step
/// of Liepa, "Filling holes in meshes", 2003, with uniform weights).
///
/// @tparam M a MutableTriangleMesh (IndexedMesh, Eigen V/F view, CGAL::Surface_mesh...).
/// @param mesh   positions of the free vertices are written; connectivity is read once.
/// @param free   one flag per vertex, non-zero = the vertex moves.
/// @param params delta (>= 0), cancellation.
/// @pre finite coordinates; each free region should touch a fixed vertex (else it only
///      stays in place, held by delta).
/// @throws invalid_input for a free vector of the wrong length, delta < 0 or not finite,
///         a NaN/Inf coordinate or a face index out of range (mesh untouched).
/// @return Status::ok with moved_vertices, the number of vertices moved (0 if the system could not be
///         factorised: nothing moved); Status::cancelled: the mesh is untouched.
template <MutableTriangleMesh M>
FairResult fair_biharmonic(M& mesh, const std::vector<std::uint8_t>& free, const FairParams& params = {}) {
    const std::string fn = "kintsugi::fair_biharmonic: ";
    detail::check_vertex_flags(free, kintsugi::num_vertices(mesh), fn, "free", false);
    detail::check_fair_delta(params.delta, fn, "delta");
    std::vector<Vec3> x = detail::finite_vertex_positions(mesh, fn);
    FairResult out = detail::run_cancellable<FairResult>(params.control, [&](detail::Progress& progress) {
        FairResult r;
        progress.stage("topology", 0.0, 0.2);
        const MeshTopology topo(mesh);
        progress.stage("solve", 0.2, 1.0);
        r.moved_vertices = detail::biharmonic_fill(x, topo, free, params.delta);
        progress.check();
        r.timings = progress.finish();
        return r;
    });
    if (out.moved_vertices > 0) detail::write_flagged_positions(mesh, x, free);
    return out;
}

}  // namespace kintsugi
