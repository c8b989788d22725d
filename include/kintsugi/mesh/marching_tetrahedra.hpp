// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file marching_tetrahedra.hpp
/// @brief The surface between inside and outside vertices of a tetrahedral mesh
/// (marching tetrahedra over a labelling), closed, outward oriented and manifold.
///
/// Every tet edge whose two ends carry different labels gets one output vertex,
/// shared by all tets around the edge; every tet with mixed labels gets one
/// triangle (1 or 3 inside vertices) or two (2 inside vertices). Where the tet
/// mesh's own boundary has inside vertices, the inside part of the boundary
/// triangles is added as a cap, so the output is always closed.
///
/// Why the output is a closed 2-manifold whatever the labelling: the surface is the
/// zero set of the piecewise linear function that is +1 at inside and −1 at outside
/// vertices (moved along the edges, which does not change its combinatorics), and 0
/// is a regular value of it because no vertex has the value 0. Inside regions that
/// touch only at a vertex or an edge of the tet mesh therefore never share an
/// output vertex: output vertices live strictly inside mixed edges. Each output
/// vertex is kept a fraction `min_edge_fraction` away from both ends of its edge, so
/// no two output vertices coincide and no triangle is degenerate (a triangle's
/// three vertices lie on three distinct edges of one non-degenerate tet, or on a
/// boundary triangle, and are never collinear).
///
/// Used by the PU + graph-cut reconstruction (kintsugi/reconstruct/pu_graphcut.hpp);
/// its per-tet case table also serves extract_isosurface (kintsugi/field/isosurface.hpp).

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <tuple>
#include <unordered_map>
#include <utility>
#include <vector>

namespace kintsugi {

/// A tetrahedron as four vertex indices.
using Tet = std::array<Index, 4>;

/// Parameters of marching_tetrahedra.
struct MarchingTetrahedraParams {
    /// Output vertices stay at least this fraction of their edge's length away from
    /// both ends (no coincident vertices, no degenerate triangles). In (0, 0.5).
    Scalar min_edge_fraction = 0.01;
    /// On an edge where f has the same sign at both ends (the field failed there),
    /// the vertex goes this fraction of the edge away from the end with the smaller
    /// |f| (Nagai et al. put it on that end; a small offset keeps vertices distinct).
    /// In [min_edge_fraction, 0.5].
    Scalar same_sign_fraction = 0.1;
    /// Set when every tet is positively oriented (orient3d(v0, v1, v2, v3) > 0, as
    /// CGAL's triangulations give them): skips the orientation test per tet.
    bool tets_positively_oriented = false;
    RunControl control{};
};

/// Result of marching_tetrahedra.
struct MarchingTetrahedraResult {
    Status status = Status::ok;
    /// The surface: closed, consistently oriented with normals pointing from the
    /// inside vertices to the outside ones, 2-manifold, no degenerate triangles.
    IndexedMesh mesh;
    /// Per output vertex, the tet-mesh edge (a, b) it lies on, with a inside and b
    /// outside; a == b for a cap vertex placed on an inside vertex of the boundary.
    std::vector<std::array<Index, 2>> vertex_edges;
    /// Per output vertex, 1 when f has the same (non-zero) sign at both ends of its
    /// edge (the vertex was placed by the same-sign rule), else 0.
    std::vector<std::uint8_t> same_sign;
    std::size_t same_sign_vertices = 0;  ///< number of 1s in same_sign
    std::size_t cap_faces = 0;           ///< triangles on the tet mesh's boundary
    std::vector<StageTiming> timings;
};

namespace detail {

struct EdgeKeyHash {
    std::size_t operator()(const std::pair<Index, Index>& k) const noexcept {
        std::uint64_t h = static_cast<std::uint64_t>(k.first) * 0x9E3779B97F4A7C15ULL;
        h ^= static_cast<std::uint64_t>(k.second) + 0x7F4A7C159E3779B9ULL + (h << 6) + (h >> 2);
        return static_cast<std::size_t>(h ^ (h >> 31));
    }
};

inline int permutation_parity(const std::array<int, 4>& p) {
    int inv = 0;
    for (int i = 0; i < 4; ++i)
        for (int j = i + 1; j < 4; ++j)
            if (p[i] > p[j]) ++inv;
    return inv & 1;
}

/// Even permutation of (0,1,2,3) starting with `first` (and `second` when >= 0).
inline std::array<int, 4> even_permutation(int first, int second = -1) {
    std::array<int, 4> p{};
    int k = 0;
    p[k++] = first;
    if (second >= 0) p[k++] = second;
    for (int v = 0; v < 4; ++v)
        if (v != first && v != second) p[k++] = v;
    if (permutation_parity(p) != 0) std::swap(p[2], p[3]);
    return p;
}

/// The surface triangles of one tet with `nin` (1, 2 or 3) inside vertices, V in
/// positive order (orient3d(V0, V1, V2, V3) > 0), facing from inside to outside.
/// edge_vertex(a, b) gives the output vertex on tet edge (a, b) (called in a fixed
/// order: the caller's numbering depends on it); add_face(a, b, c) takes a triangle;
/// sq(u, w) is the squared distance of two output vertices (a quad is split along its
/// shorter diagonal). Shared by marching_tetrahedra and extract_isosurface.
template <class IsIn, class EdgeVertex, class AddFace, class Sq>
void mt_tet_faces(const std::array<Index, 4>& V, int nin, IsIn&& is_in, EdgeVertex&& edge_vertex, AddFace&& add_face,
                  Sq&& sq) {
    if (nin == 1 || nin == 3) {
        int iso = 0;
        for (int l = 0; l < 4; ++l)
            if (is_in(V[l]) == (nin == 1)) iso = l;
        const auto p = even_permutation(iso);
        const Index q1 = edge_vertex(V[p[0]], V[p[1]]);
        const Index q2 = edge_vertex(V[p[0]], V[p[2]]);
        const Index q3 = edge_vertex(V[p[0]], V[p[3]]);
        // (q1, q2, q3) faces away from V(p[0]).
        if (nin == 1) add_face(q1, q2, q3);
        else add_face(q1, q3, q2);
    } else {
        int a = -1, b = -1;
        for (int l = 0; l < 4; ++l)
            if (is_in(V[l])) (a < 0 ? a : b) = l;
        const auto p = even_permutation(a, b);
        // With (i, j, k, l) even and i, j inside: the outward cycle is (ik, il, jl, jk).
        const Index q0 = edge_vertex(V[p[0]], V[p[2]]);
        const Index q1 = edge_vertex(V[p[0]], V[p[3]]);
        const Index q2 = edge_vertex(V[p[1]], V[p[3]]);
        const Index q3 = edge_vertex(V[p[1]], V[p[2]]);
        if (sq(q0, q2) <= sq(q1, q3)) {
            add_face(q0, q1, q2);
            add_face(q0, q2, q3);
        } else {
            add_face(q0, q1, q3);
            add_face(q1, q2, q3);
        }
    }
}

inline MarchingTetrahedraResult marching_tetrahedra_impl(const std::vector<Vec3>& vertices,
                                                        const std::vector<Tet>& tets,
                                                        const std::vector<std::uint8_t>& inside,
                                                        const std::vector<Scalar>& f,
                                                        const MarchingTetrahedraParams& params, Progress& progress) {
    MarchingTetrahedraResult out;
    const Scalar dmin = params.min_edge_fraction;
    const Scalar dsame = params.same_sign_fraction;
    auto is_in = [&](Index v) { return inside[v] != 0; };

    std::unordered_map<std::pair<Index, Index>, Index, EdgeKeyHash> vertex_of;
    vertex_of.reserve(tets.size());

    // Output vertex on the mixed edge (a, b), or on vertex a when a == b (caps).
    auto edge_vertex = [&](Index a, Index b) -> Index {
        const std::pair<Index, Index> key = a == b ? std::pair{a, a} : std::pair{std::min(a, b), std::max(a, b)};
        const auto [it, fresh] = vertex_of.try_emplace(key, out.mesh.vertices.size());
        if (!fresh) return it->second;
        Index vin = a, vout = b;
        if (a != b && !is_in(a)) std::swap(vin, vout);
        out.vertex_edges.push_back({vin, vout});
        if (a == b) {
            out.mesh.vertices.push_back(vertices[a]);
            out.same_sign.push_back(0);
            return it->second;
        }
        // Parametrise from the smaller index so the position does not depend on the visiting order.
        const Index lo = key.first, hi = key.second;
        Scalar t = 0.5;
        std::uint8_t same = 0;
        if (!f.empty()) {
            const Scalar flo = f[lo], fhi = f[hi];
            if (flo * fhi < 0 || flo == 0 || fhi == 0) {
                t = flo == fhi ? 0.5 : flo / (flo - fhi);
            } else {
                same = 1;
                t = std::abs(flo) <= std::abs(fhi) ? dsame : 1 - dsame;
            }
        }
        t = std::clamp(t, dmin, 1 - dmin);
        out.mesh.vertices.push_back(vertices[lo] + t * (vertices[hi] - vertices[lo]));
        out.same_sign.push_back(same);
        out.same_sign_vertices += same;
        return it->second;
    };
    auto add_face = [&](Index a, Index b, Index c) { out.mesh.faces.push_back({a, b, c}); };
    auto sq = [&](Index a, Index b) { return (out.mesh.vertices[a] - out.mesh.vertices[b]).squaredNorm(); };

    // Boundary faces with an inside vertex: faces of tets with an inside vertex that
    // no other such tet shares (a face with an inside vertex is shared only by tets
    // that have that vertex).
    struct FaceRec {
        std::array<Index, 3> key;
        Index tet_local;  // 4 x tet + the tet's local vertex opposite the face
    };
    std::vector<FaceRec> faces;

    // Local order making tet t positive: (0, 1, 2, 3), or (0, 1, 3, 2) when flipped[t].
    std::vector<std::uint8_t> flipped(params.tets_positively_oriented ? 0 : tets.size(), 0);
    auto orient = [&](std::size_t t) {
        return !flipped.empty() && flipped[t] ? std::array<int, 4>{0, 1, 3, 2} : std::array<int, 4>{0, 1, 2, 3};
    };
    const std::size_t nt = tets.size();
    for (std::size_t t = 0; t < nt; ++t) {
        if ((t & 0xFFFF) == 0) progress.update(0.5 * static_cast<double>(t) / static_cast<double>(nt));
        const Tet& T = tets[t];
        const int nin = is_in(T[0]) + is_in(T[1]) + is_in(T[2]) + is_in(T[3]);
        if (nin == 0) continue;
        if (!params.tets_positively_oriented) {
            const Vec3& p0 = vertices[T[0]];
            const Scalar det = (vertices[T[1]] - p0).cross(vertices[T[2]] - p0).dot(vertices[T[3]] - p0);
            flipped[t] = det < 0;
        }
        const std::array<int, 4> o = orient(t);
        for (int l = 0; l < 4; ++l) {
            std::array<Index, 3> k{};
            int m = 0;
            bool any_in = false;
            for (int j = 0; j < 4; ++j)
                if (j != l) {
                    k[m++] = T[j];
                    any_in = any_in || is_in(T[j]);
                }
            if (!any_in) continue;
            std::sort(k.begin(), k.end());
            faces.push_back({k, 4 * t + static_cast<Index>(l)});
        }
        if (nin == 4) continue;
        // vertex ids in positive order
        mt_tet_faces({T[o[0]], T[o[1]], T[o[2]], T[o[3]]}, nin, is_in, edge_vertex, add_face, sq);
    }
    progress.update(0.5);

    // Caps on the boundary of the tet mesh.
    // (Compared as tuples of their fields: std::array's == and != call memcmp, which made
    // this sort 40 % of the stage.)
    auto fields = [](const FaceRec& r) { return std::tie(r.key[0], r.key[1], r.key[2]); };
    sort_maybe_parallel(faces, [](const FaceRec& x, const FaceRec& y) {
        return std::tie(x.key[0], x.key[1], x.key[2], x.tet_local) < std::tie(y.key[0], y.key[1], y.key[2], y.tet_local);
    });
    for (std::size_t i = 0; i < faces.size();) {
        std::size_t j = i + 1;
        while (j < faces.size() && fields(faces[j]) == fields(faces[i])) ++j;
        if (j - i == 1) {
            const std::size_t tet = faces[i].tet_local / 4;
            const int local = static_cast<int>(faces[i].tet_local % 4);
            const Tet& T = tets[tet];
            const std::array<int, 4> o = orient(tet);
            int opp = 0;  // position of the opposite vertex in the positive order
            for (int l = 0; l < 4; ++l)
                if (o[l] == local) opp = l;
            const auto p = even_permutation(opp);
            // (V(p1), V(p2), V(p3)) faces away from V(p0): outward of the tet mesh.
            const std::array<Index, 3> tri{T[o[p[1]]], T[o[p[2]]], T[o[p[3]]]};
            std::vector<Index> poly;
            for (int c = 0; c < 3; ++c) {
                const Index u = tri[c], w = tri[(c + 1) % 3];
                if (is_in(u)) poly.push_back(edge_vertex(u, u));
                if (is_in(u) != is_in(w)) poly.push_back(edge_vertex(u, w));
            }
            if (poly.size() == 3) {
                add_face(poly[0], poly[1], poly[2]);
                ++out.cap_faces;
            } else if (poly.size() == 4) {
                if (sq(poly[0], poly[2]) <= sq(poly[1], poly[3])) {
                    add_face(poly[0], poly[1], poly[2]);
                    add_face(poly[0], poly[2], poly[3]);
                } else {
                    add_face(poly[0], poly[1], poly[3]);
                    add_face(poly[1], poly[2], poly[3]);
                }
                out.cap_faces += 2;
            }
        }
        i = j;
    }
    return out;
}

inline void marching_tetrahedra_validate(const std::vector<Vec3>& vertices, const std::vector<Tet>& tets,
                                         const std::vector<std::uint8_t>& inside, const std::vector<Scalar>& f,
                                         const MarchingTetrahedraParams& params) {
    const std::string fn = "kintsugi::marching_tetrahedra: ";
    const std::size_t n = vertices.size();
    if (inside.size() != n)
        throw invalid_input(fn + "inside has " + std::to_string(inside.size()) + " labels for " + std::to_string(n) +
                            " vertices; give one label per vertex");
    if (!f.empty() && f.size() != n)
        throw invalid_input(fn + "f has " + std::to_string(f.size()) + " values for " + std::to_string(n) +
                            " vertices; give one value per vertex or none");
    if (!(params.min_edge_fraction > 0 && params.min_edge_fraction < 0.5))
        throw invalid_input(fn + "min_edge_fraction must lie in (0, 0.5)");
    if (!(params.same_sign_fraction >= params.min_edge_fraction && params.same_sign_fraction <= 0.5))
        throw invalid_input(fn + "same_sign_fraction must lie in [min_edge_fraction, 0.5]");
    detail::check_finite_points(vertices, fn + "vertex ", "");
    for (std::size_t i = 0; i < f.size(); ++i)
        if (!std::isfinite(f[i]))
            throw invalid_input(fn + "f[" + std::to_string(i) + "] is NaN or infinite; give finite values");
    for (std::size_t t = 0; t < tets.size(); ++t) {
        const Tet& T = tets[t];
        for (int j = 0; j < 4; ++j)
            if (T[j] >= n)
                throw invalid_input(fn + "tet " + std::to_string(t) + " refers to vertex " + std::to_string(T[j]) +
                                    " >= " + std::to_string(n) + "; vertex indices must be in [0, vertices.size())");
        if (params.tets_positively_oriented) continue;  // the caller's (exact) promise
        const Vec3& p0 = vertices[T[0]];
        const Scalar det = (vertices[T[1]] - p0).cross(vertices[T[2]] - p0).dot(vertices[T[3]] - p0);
        if (det == 0)
            throw invalid_input(fn + "tet " + std::to_string(t) + " is degenerate (zero volume); remove flat tets");
    }
}

}  // namespace detail

/// @brief Extracts the closed surface separating inside from outside vertices of a
/// tetrahedral mesh.
///
/// Marching tetrahedra over a binary labelling, with the vertex placement of
/// Nagai, Ohtake, Suzuki, "Outlier robust implicit surface reconstruction using
/// graph-cut" (IPSJ Journal 2011, §2.3): on a mixed edge the vertex lies where the
/// linear interpolation of f is zero when f changes sign, else near the end with the
/// smaller |f| (see MarchingTetrahedraParams::same_sign_fraction). Without f the
/// vertex is the edge's midpoint.
///
/// Output guarantee: a closed, 2-manifold triangle mesh (one or more components),
/// consistently oriented with normals pointing from inside to outside vertices, no
/// degenerate triangles and no two vertices at the same place. Inside vertices on the
/// boundary of the tet mesh are closed over by caps on the boundary triangles.
///
/// @param vertices tet-mesh vertex positions (any unit).
/// @param tets     tetrahedra as 4 vertex indices; a conforming mesh (two tets share
///                 a whole face or nothing), either orientation unless
///                 params.tets_positively_oriented.
/// @param inside   one label per vertex: non-zero = inside.
/// @param f        empty, or one finite value per vertex (e.g. an implicit function).
/// @param params   placement fractions, orientation promise, cancellation.
/// @pre the tet mesh is conforming (the manifold guarantee relies on it).
/// @throws invalid_input on size mismatches, indices out of range, NaN/Inf
///         coordinates or values, zero-volume tets, fractions out of range.
/// @return the surface and per-vertex provenance. Status::cancelled: stopped
///         through params.control; the mesh is empty.
[[nodiscard]] inline MarchingTetrahedraResult marching_tetrahedra(const std::vector<Vec3>& vertices,
                                                                 const std::vector<Tet>& tets,
                                                                 const std::vector<std::uint8_t>& inside,
                                                                 const std::vector<Scalar>& f = {},
                                                                 const MarchingTetrahedraParams& params = {}) {
    detail::marching_tetrahedra_validate(vertices, tets, inside, f, params);
    return detail::run_cancellable<MarchingTetrahedraResult>(params.control, [&](detail::Progress& progress) {
        progress.stage("marching_tetrahedra", 0.0, 1.0);
        MarchingTetrahedraResult out = detail::marching_tetrahedra_impl(vertices, tets, inside, f, params, progress);
        out.timings = progress.finish();
        return out;
    });
}

}  // namespace kintsugi
