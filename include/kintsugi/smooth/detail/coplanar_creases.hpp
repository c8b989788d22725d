// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file coplanar_creases.hpp
/// @brief Internal machinery of smooth/feature_bilateral.hpp: sharp edges of a
/// piecewise-planar part read from the faces that impulsive noise left exactly on their
/// planes ("Impulsive noise" in the file comment there). Not part of the API.
///
/// Under impulsive noise most vertices are not moved, so many faces still lie exactly
/// in the part's planes; the normal voting tensor, which averages the noisy normals,
/// misses such creases (Twelve0.5Impulsive: recall 0.02). Steps (thresholds in the
/// mean edge length |e|; measured in docs/methods/feature_bilateral.md):
///  1. A face is *anchored* when a face near it (sharing a vertex with a vertex
///     neighbour of one of its corners) that shares at most one vertex with it is
///     coplanar with it: normals within 0.1°, each centroid within 0.002|e| of the other's
///     plane. Partners sharing an edge are not taken: two neighbours moved by the same
///     amount on a regular grid are coplanar by accident. The tolerances are an order above
///     a file's rounding (Twelve0.5Impulsive's unmoved vertices: within 1e-4|e|) and below
///     what Gaussian noise reaches by accident: noise in random directions, whose component
///     along the normal is often near 0, anchored 1-3 % of the faces at 0.5° / 0.01|e|
///     (bunny00 at 0.1|e|: 1,391 of 75,408), so its vertices were held as if unmoved.
///  2. Each vertex collects the distinct planes of the anchored faces within 6 vertex
///     rings, at most 6, the nearest first (Jacobi passes over the edges, so the cost is
///     linear in the edges whatever the valences).
///  3. For each interior manifold edge whose nearest plane is within 3 rings, the pair
///     of its endpoints' planes that explains it best: at least the crease angle apart,
///     one of them among the nearest, their line within 1.2|e| of both endpoints. An
///     endpoint scores 0 when it lies on both planes (an unmoved crease vertex), rules
///     the pair out when it lies on one only (an unmoved vertex beside the crease), else
///     |d1 − d2| with its signed distances (a crease vertex moved along its normal stays
///     on the planes' bisector). With a pair, the edge is sharp when the pair's worse
///     endpoint scores below 0.35|e| and the edge runs along the line (its extent along
///     it at least half its length), and at least a quarter of its endpoints'
///     neighbours (at most 32 read per endpoint) lie on one of the two planes: on a
///     curved part a few faces are coplanar by accident (bunny00 with 10 % impulsive
///     noise: 2,418 anchored faces and 1,715 false creases without this test, 104 with
///     it), while at a real crease the unmoved neighbours (half or more) lie on the planes.
/// The sharp edges are the voting tensor's and these together: letting the stage also
/// veto the tensor's edges (where a pair exists but scores too high) or replace them
/// near anchored faces lost creases the stage cannot explain (curved creases, cylinder
/// facets that no coplanar partner anchors) and smoothed worse on generated impulsive
/// noise on the Block. With fewer than 1 % of the faces anchored (Gaussian noise, scans:
/// a few faces coplanar by accident) the stage costs one pass over the faces and changes
/// nothing.

#include <kintsugi/core/control.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/smooth/detail/feature_bilateral_impl.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace kintsugi::detail::fbs {

/// The stage's constants (see the file comment; chosen on Twelve0.5Impulsive, checked
/// on generated impulsive noise on the Block and SharpSphere).
struct CoplanarConstants {
    static constexpr Scalar normal_cos = 0.9999984769132877;  ///< cos 0.1°: coplanar faces' normals
    static constexpr Scalar coplanar_offset = 0.002;  ///< coplanar faces' centroid offsets, |e|
    static constexpr Scalar offset = 0.01;            ///< a vertex on a plane: offset tolerance τ, |e|
    static constexpr int rings = 6;                         ///< vertex rings planes travel
    static constexpr std::size_t planes_per_vertex = 6;
    static constexpr Scalar line_reach = 1.2;     ///< the planes' line to each endpoint, |e|
    static constexpr Scalar max_score = 0.35;     ///< worse endpoint score of a sharp edge, |e|
    static constexpr Scalar min_extent = 0.5;     ///< edge extent along the line, of its length
    /// Fewer anchored faces than this fraction of the faces: coplanar by accident, the stage
    /// stops (impulsive noise moving up to 3 vertices in 4 leaves 1.6 % or more; Gaussian
    /// noise leaves a few: 1,093 of 589,824 faces in bench_smooth's uniform-noise input).
    static constexpr Scalar min_anchored_fraction = 0.01;
    static constexpr Scalar min_support = 0.25;   ///< endpoints' neighbours on one of the planes
    static constexpr std::size_t support_samples = 32;  ///< neighbours read per endpoint at most
    static constexpr int near_ring = 3;           ///< edges whose nearest plane is this near are tested
    static constexpr std::size_t partner_tests = 512;  ///< faces one anchoring test visits at most
};

/// Per topology edge, whether the stage found it sharp.
struct CoplanarCreases {
    std::vector<unsigned char> sharp;
    /// Per vertex: a corner of two anchored faces or more, so not moved by the noise (empty
    /// when the stage stopped below min_anchored_fraction).
    std::vector<unsigned char> unmoved;
    std::size_t anchored_faces = 0;
    std::size_t sharp_edges = 0;
};

/// Sharp edges from exactly coplanar faces (see the file comment). `min_angle_cos`: the
/// cosine of the smallest angle between the two planes' normals at a crease.
inline CoplanarCreases coplanar_creases(const std::vector<Vec3>& V, const std::vector<Face>& F,
                                        const MeshTopology& topo, Scalar L, Scalar min_angle_cos,
                                        Progress& progress, double from, double to) {
    using C = CoplanarConstants;
    const std::size_t nv = V.size(), nf = F.size(), ne = topo.num_edges();
    CoplanarCreases out;
    out.sharp.assign(ne, 0);
    FaceGeometry geo;
    compute_face_geometry(V, F, geo);
    const Scalar tau = C::offset * L, tau_face = C::coplanar_offset * L;
    auto coplanar = [&](Index t, Index s) {
        const Vec3 &nt = geo.normal[t], &ns = geo.normal[s];
        if (!(nt.dot(ns) >= C::normal_cos)) return false;  // also rules out zero normals
        const Vec3 d = geo.centroid[s] - geo.centroid[t];
        return std::abs(nt.dot(d)) <= tau_face && std::abs(ns.dot(d)) <= tau_face;
    };

    // 1. Anchored faces.
    const double mid1 = from + 0.3 * (to - from);
    std::vector<unsigned char> anchored(nf, 0);
    blocked_for(progress, nf, from, mid1, [&](std::size_t t) {
        if (!(geo.area[t] > 0)) return;
        const Face& ft = F[t];
        std::size_t tests = 0;
        for (Index c : ft) {
            const auto ring = topo.vertex_neighbors(c);
            for (std::size_t k = 0; k <= ring.size(); ++k) {
                const Index w = k == 0 ? c : ring[k - 1];
                for (Index s : topo.vertex_faces(w)) {
                    if (++tests > C::partner_tests) return;
                    if (s == t || !coplanar(static_cast<Index>(t), s)) continue;  // its normal test first: cheap
                    int shared = 0;
                    for (Index x : F[s]) shared += x == ft[0] || x == ft[1] || x == ft[2];
                    if (shared <= 1) {
                        anchored[t] = 1;
                        return;
                    }
                }
            }
        }
    });
    for (unsigned char a : anchored) out.anchored_faces += a;
    if (static_cast<Scalar>(out.anchored_faces) < C::min_anchored_fraction * static_cast<Scalar>(nf)) {
        progress.update(to);
        return out;
    }
    // Unmoved vertices: corners of at least two anchored faces. A moved vertex can be the
    // corner of one (twelve.obj + 10 % impulsive noise: 3 of 38 single-face corners were moved
    // by about |e|, none of the 4,108 others).
    out.unmoved.assign(nv, 0);
    for (std::size_t t = 0; t < nf; ++t)
        if (anchored[t])
            for (Index v : F[t]) out.unmoved[v] = static_cast<unsigned char>(std::min(out.unmoved[v] + 1, 2));
    for (unsigned char& u : out.unmoved) u = u >= 2;

    // 2. Planes per vertex, nearest first: entries (face, ring), at most P per vertex.
    struct Entry {
        Index face;
        std::uint32_t ring;
    };
    constexpr std::size_t P = C::planes_per_vertex;
    constexpr Index none = std::numeric_limits<Index>::max();
    std::vector<Entry> cur(nv * P, Entry{none, 0}), next(nv * P, Entry{none, 0});
    // Sorted candidates -> the first P pairwise non-coplanar ones, written to dst.
    auto select = [&](std::vector<Entry>& cand, Entry* dst, std::size_t cap) {
        std::sort(cand.begin(), cand.end(), [](const Entry& x, const Entry& y) {
            return x.ring != y.ring ? x.ring < y.ring : x.face < y.face;
        });
        std::size_t n = 0;
        for (const Entry& e : cand) {
            bool dup = false;
            for (std::size_t k = 0; k < n && !dup; ++k) dup = dst[k].face == e.face || coplanar(dst[k].face, e.face);
            if (dup) continue;
            dst[n++] = e;
            if (n == cap) break;
        }
        for (std::size_t k = n; k < cap; ++k) dst[k] = Entry{none, 0};
        return n;
    };
    const double mid2 = mid1 + 0.4 * (to - from);
    blocked_for(progress, nv, mid1, mid1 + (mid2 - mid1) / (C::rings + 1), [&](std::size_t v) {
        thread_local std::vector<Entry> cand;
        cand.clear();
        for (Index t : topo.vertex_faces(v))
            if (anchored[t]) cand.push_back({t, 0});
        select(cand, &cur[v * P], P);
    });
    for (int r = 1; r <= C::rings; ++r) {
        const double a = mid1 + (mid2 - mid1) * r / (C::rings + 1), b = mid1 + (mid2 - mid1) * (r + 1) / (C::rings + 1);
        blocked_for(progress, nv, a, b, [&](std::size_t v) {
            thread_local std::vector<Entry> cand;
            cand.clear();
            for (std::size_t k = 0; k < P && cur[v * P + k].face != none; ++k) cand.push_back(cur[v * P + k]);
            for (Index w : topo.vertex_neighbors(v))
                for (std::size_t k = 0; k < P && cur[w * P + k].face != none; ++k)
                    cand.push_back({cur[w * P + k].face, cur[w * P + k].ring + 1});
            select(cand, &next[v * P], P);
        });
        cur.swap(next);
    }
    std::vector<Entry>().swap(next);

    // 3. The best pair of planes per edge.
    const auto& E = topo.edges();
    blocked_for(progress, ne, mid2, to, [&](std::size_t e) {
        const Index a = E[e][0], b = E[e][1];
        if (a == b || topo.edge_faces(e).size() != 2) return;
        thread_local std::vector<Entry> cand;
        cand.clear();
        for (Index v : {a, b})
            for (std::size_t k = 0; k < P && cur[v * P + k].face != none; ++k) cand.push_back(cur[v * P + k]);
        if (cand.empty()) return;
        Entry planes[2 * P];
        const std::size_t n = select(cand, planes, 2 * P);
        const std::uint32_t nearest = planes[0].ring;
        if (nearest > static_cast<std::uint32_t>(C::near_ring)) return;
        const Vec3 mid = (V[a] + V[b]) / 2;
        const Vec3 pa = V[a] - mid, pb = V[b] - mid;
        Scalar best = std::numeric_limits<Scalar>::infinity();
        Vec3 best_dir = Vec3::Zero();
        std::array<std::size_t, 2> best_pair{0, 0};
        for (std::size_t i = 0; i < n; ++i)
            for (std::size_t j = i + 1; j < n; ++j) {
                if (planes[i].ring != nearest && planes[j].ring != nearest) continue;
                const Vec3 &n1 = geo.normal[planes[i].face], &n2 = geo.normal[planes[j].face];
                const Scalar c = n1.dot(n2);
                if (c > min_angle_cos) continue;
                const Scalar o1 = n1.dot(geo.centroid[planes[i].face] - mid),
                             o2 = n2.dot(geo.centroid[planes[j].face] - mid);
                const Scalar det = 1 - c * c;
                if (!(det > 1e-12)) continue;
                const Vec3 x0 = ((o1 - o2 * c) / det) * n1 + ((o2 - o1 * c) / det) * n2;
                const Vec3 u = n1.cross(n2).normalized();
                Scalar score = 0;
                bool ok = true;
                for (const Vec3* p : {&pa, &pb}) {
                    const Vec3 r = *p - x0;
                    if ((r - r.dot(u) * u).norm() > C::line_reach * L) {
                        ok = false;
                        break;
                    }
                    const Scalar d1 = n1.dot(*p) - o1, d2 = n2.dot(*p) - o2;
                    const bool on1 = std::abs(d1) < tau, on2 = std::abs(d2) < tau;
                    if (on1 != on2) {
                        ok = false;
                        break;
                    }
                    if (!on1) score = std::max(score, std::abs(d1 - d2));
                }
                if (ok && score < best) {
                    best = score;
                    best_dir = u;
                    best_pair = {i, j};
                }
            }
        if (!(best < C::max_score * L && std::abs((pb - pa).dot(best_dir)) >= C::min_extent * (pb - pa).norm())) return;
        {  // support: the endpoints' neighbours on the two planes
            const Vec3 &n1 = geo.normal[planes[best_pair[0]].face], &n2 = geo.normal[planes[best_pair[1]].face];
            const Vec3 &q1 = geo.centroid[planes[best_pair[0]].face], &q2 = geo.centroid[planes[best_pair[1]].face];
            // At most support_samples neighbours per endpoint, evenly strided: a hub of a
            // fan would otherwise cost its valence once per spoke.
            std::size_t on = 0, all = 0;
            for (Index v : {a, b}) {
                const auto ring = topo.vertex_neighbors(v);
                const std::size_t step = std::max<std::size_t>(1, ring.size() / C::support_samples);
                for (std::size_t k = 0; k < ring.size(); k += step) {
                    const Index w = ring[k];
                    ++all;
                    on += std::abs(n1.dot(V[w] - q1)) < tau || std::abs(n2.dot(V[w] - q2)) < tau;
                }
            }
            if (static_cast<Scalar>(on) < C::min_support * static_cast<Scalar>(all)) return;
        }
        out.sharp[e] = 1;
    });
    for (unsigned char x : out.sharp) out.sharp_edges += x;
    progress.update(to);
    return out;
}

/// The voting tensor's sharp edges united with the stage's; counts the stage's figures
/// into `fd`.
inline void apply_coplanar(FeatureData& fd, const CoplanarCreases& cc, const MeshTopology& topo) {
    fd.anchored_faces = cc.anchored_faces;
    fd.coplanar_sharp_edges = cc.sharp_edges;
    if (cc.sharp_edges == 0) return;
    std::vector<unsigned char> sharp(cc.sharp);
    for (const auto& e : fd.sharp_edges)
        if (const auto id = topo.find_edge(e[0], e[1])) sharp[*id] = 1;
    fd.sharp_edges.clear();
    for (std::size_t e = 0; e < sharp.size(); ++e)
        if (sharp[e]) fd.sharp_edges.push_back(topo.edges()[e]);
}

}  // namespace kintsugi::detail::fbs
