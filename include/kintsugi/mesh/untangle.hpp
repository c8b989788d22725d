// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file untangle.hpp
/// @brief Faces folded over by noise along the surface, unfolded by moving their corners
/// within the tangent plane (a stage of smooth_feature_bilateral, FeatureBilateralParams::untangle).
///
/// ## Why
/// Noise in random directions moves vertices along the surface as well as across it. Moved
/// along the surface past a neighbour's edge, a vertex folds a face over: at 0.3-0.8|e| in random
/// directions 1-20 % of the faces point against their surroundings (0-4 % at the same σ along
/// the normals). Filters that update vertices along face normals (the bilateral filters' vertex
/// stage, as in Sun et al. 2007) cannot undo a fold made along the surface, and the folded faces
/// dominate the result's normal error: the shark at 0.7|e| in random directions 11.9° with the
/// filters, 2.8° with the folds undone first (docs/methods/feature_bilateral.md, "Noise in random
/// directions").
///
/// ## Method
/// - **Reference normals:** the area-weighted vertex normals of a copy smoothed by
///   `reference_pairs` (10) Taubin λ|μ pairs, which unfolds it.
/// - **Gate:** for each vertex with three or more neighbours, the offset d from it to the mean of
///   its neighbours, split along its reference normal (h = |n·d|) and across it (t = |d − (n·d)n|).
///   Noise along the normals raises the medians' ratio t/h little above the mesh's own
///   irregularity; noise in random directions raises t with the tangential two thirds of its
///   variance. The stage runs when median t / median h exceeds `ratio_gate` (1.2): along the
///   normals at 0.3-0.8|e| ten shapes read 0.12-0.92, in random directions 1.64-2.45.
/// - **Impulsive noise** (remove_impulses' gate on the heights above the neighbours) is left to the
///   impulse removal: its unmoved majority reads a high ratio on irregular meshes.
/// - **Coarse meshes** are left as they are: above a median angle of `coarse_angle` (12°)
///   between the reference's neighbouring faces a move within the tangent plane leaves the surface.
/// - **Folded faces:** those whose normal points against the sum of their corners' reference
///   normals, leaving out faces whose corners' reference normals differ by more than 60° (the
///   smoothed field across a sharp crease, where a clean face can point against it).
/// - **Unfolding:** the corners of the folded faces, and only they, move `relax_steps` (3) times
///   by `step` (0.5) of the offset to their neighbours' mean, within the plane of their
///   reference normal (simultaneous updates: the result is the same whatever the thread count).
/// Cost: the Taubin pairs and a few passes over the vertices, O(n).
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/mesh/impulses.hpp>
#include <kintsugi/mesh/taubin.hpp>
#include <kintsugi/mesh/topology.hpp>

#include <limits>
#include <vector>

namespace kintsugi {

/// What the untangling stage found and did.
struct UntangleReport {
    /// median tangential / median normal offset of a vertex from its neighbours' mean (see the
    /// file comment); 0 when no vertex has three neighbours.
    Scalar ratio = 0;
    /// The ratio passed the gate, so folded faces were looked for.
    bool tangential_noise = false;
    /// The vertices' heights above their neighbours are heavy-tailed (remove_impulses' gate):
    /// impulsive noise, whose unmoved majority makes the ratio read high on irregular meshes;
    /// left to the impulse removal, nothing moved here.
    bool impulsive = false;
    /// Median angle between neighbouring faces of the smoothed reference, in radians; above
    /// detail::untangle::coarse_angle the mesh is too coarse for moves within the tangent plane.
    Scalar reference_angle = 0;
    /// Faces found folded over (0 when the gate did not pass).
    std::size_t folded_faces = 0;
    /// Vertices moved (the corners of the folded faces).
    std::size_t moved_vertices = 0;
};

namespace detail::untangle {

inline constexpr std::size_t reference_pairs = 10;
/// Set between the ratios of noise along the normals (at most 0.92 at 0.3-0.8|e|: armadillo at
/// 0.3|e|) and in random directions (at least 1.64: the Block at 0.3|e|), ten shapes, seed 11.
inline constexpr Scalar ratio_gate = 1.2;
inline constexpr std::size_t relax_steps = 3;
inline constexpr Scalar step = 0.5;
/// Above this median angle between the reference's neighbouring faces (12°, in radians) the stage
/// does nothing: moves within a vertex's tangent plane leave a coarse curved surface by about
/// the angle times the move (CGAL's eight.off, 634 faces, median 16°: 0.5-1.5° worse at
/// 0.5-0.8|e| in random directions); the elephant (4.5K faces, 10-11°) gains.
inline constexpr Scalar coarse_angle = 0.20943951023931953;  // 12°
/// Faces whose corners' reference normals differ by more than 60° are not tested (cos 60°).
inline constexpr Scalar crease_cos = 0.5;

/// Unfolds `p` (positions; a local frame, see core/frame.hpp) in place over `faces` and `topo`.
inline UntangleReport run(std::vector<Vec3>& p, const std::vector<Face>& faces, const MeshTopology& topo) {
    const std::size_t nv = p.size();
    UntangleReport rep;
    std::vector<Vec3> s = p;
    {
        RunControl none;
        Progress quiet(none);
        (void)taubin_smooth(s, topo, {}, TaubinParams{.iterations = reference_pairs}, quiet);
    }
    std::vector<Vec3> n(nv, Vec3::Zero()), fn(faces.size());
    for (std::size_t i = 0; i < faces.size(); ++i) {
        const Face& f = faces[i];
        const Vec3 a = (s[f[1]] - s[f[0]]).cross(s[f[2]] - s[f[0]]);
        for (Index c : f) n[c] += a;
        const Scalar l = a.norm();
        fn[i] = l > 0 ? Vec3(a / l) : Vec3::Zero();
    }
    rep.reference_angle = median_dihedral_angle(fn, topo);
    for (Vec3& x : n) {
        const Scalar l = x.norm();
        x = l > 0 ? Vec3(x / l) : Vec3::Zero();
    }
    std::vector<Scalar> t, h;
    for (std::size_t v = 0; v < nv; ++v) {
        if (topo.vertex_neighbors(static_cast<Index>(v)).size() < 3 || n[v].squaredNorm() == 0) continue;
        const Vec3 d = umbrella(p, topo, static_cast<Index>(v));
        const Scalar dn = n[v].dot(d);
        h.push_back(std::abs(dn));
        t.push_back((d - dn * n[v]).norm());
    }
    if (h.empty()) return rep;
    const Scalar mt = upper_median(std::move(t)), mh = upper_median(std::move(h));
    rep.ratio = mh > 0 ? mt / mh : (mt > 0 ? std::numeric_limits<Scalar>::infinity() : 0);
    rep.tangential_noise = rep.ratio > ratio_gate;
    if (!rep.tangential_noise || rep.reference_angle > coarse_angle) return rep;
    {  // impulsive noise: remove_impulses' gate on the heights (fertility + 10 % impulses reads 2.45)
        ImpulseResult gate;
        (void)impulses::gate_heights(p, faces, topo, mean_edge_length(p, topo, false), ImpulseParams{}, gate);
        rep.impulsive = gate.impulsive;
        if (rep.impulsive) return rep;
    }
    std::vector<unsigned char> move(nv, 0);
    for (const Face& f : faces) {
        const Vec3 &a = n[f[0]], &b = n[f[1]], &c = n[f[2]];
        if (a.dot(b) < crease_cos || b.dot(c) < crease_cos || a.dot(c) < crease_cos) continue;
        const Vec3 area = (p[f[1]] - p[f[0]]).cross(p[f[2]] - p[f[0]]);
        if (area.dot(a + b + c) < 0) {
            ++rep.folded_faces;
            for (Index v : f) move[v] = 1;
        }
    }
    std::vector<Index> active;
    for (std::size_t v = 0; v < nv; ++v)
        if (move[v] && !topo.vertex_neighbors(static_cast<Index>(v)).empty()) active.push_back(static_cast<Index>(v));
    rep.moved_vertices = active.size();
    std::vector<Vec3> next(active.size());
    for (std::size_t it = 0; it < relax_steps; ++it) {
        for (std::size_t i = 0; i < active.size(); ++i) {
            const Index v = active[i];
            const Vec3 d = umbrella(p, topo, v);
            next[i] = p[v] + step * (d - n[v].dot(d) * n[v]);
        }
        for (std::size_t i = 0; i < active.size(); ++i) p[active[i]] = next[i];
    }
    return rep;
}

}  // namespace detail::untangle
}  // namespace kintsugi
