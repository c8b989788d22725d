// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file example_completion.hpp
/// @brief Example-based surface completion: holes are filled with geometry that
/// resembles the rest of the object, by minimising one global energy of local-shape
/// similarity (Kawai, Sato, Yokoya 2009). Measurements and departures from the paper:
/// docs/methods/example_completion.md.
///
/// @code
/// kintsugi::IndexedMesh mesh = kintsugi::read_mesh("scan.ply");
/// auto r = kintsugi::complete_holes_example_based(mesh, {.max_hole_size = 0.1});
/// // r.filled_holes, r.new_vertices, r.energy[level][iteration], r.timings
/// @endcode

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/disjoint_sets.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/stages.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/halfedge_mesh.hpp>
#include <kintsugi/mesh/holes.hpp>
#include <kintsugi/spatial/jet_fit.hpp>
#include <kintsugi/spatial/kd_tree.hpp>

#include <Eigen/Cholesky>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

/// One level of the coarse-to-fine schedule (Table 1 of the paper); lengths are in
/// units of l_ave, the mean edge length of the data region.
struct CompletionLevel {
    Scalar a_radius = 9;      ///< radius of the sphere A whose shape is compared (SSD), > 0
    Scalar split_above = 4;   ///< patch edges longer than this are split, > merge_below
    Scalar merge_below = 1.5; ///< patch edges shorter than this are collapsed, >= 0
    /// Fraction of the fixed vertices of Ω' (around the hole) left out of the energy,
    /// in [0, 1): the coarse levels look at fewer of them.
    Scalar thin_fraction = Scalar(8) / 9;
};

/// How the hole is first closed before the energy minimisation.
enum class InitialPatch {
    thin_plate,  ///< fill_holes (minimum-area triangulation, refinement, biharmonic fairing)
    fan,         ///< the paper's fan from the boundary's centroid
};

/// Parameters of complete_holes_example_based (aggregate; field order is API, append only).
struct CompletionParams {
    /// Holes filled: every boundary loop that is not the outer border and whose extent
    /// (bounding-box diagonal) is at most this fraction of the mesh's diagonal, (0, inf),
    /// default 0.25. Ignored when `holes` is given.
    Scalar max_hole_size = 0.25;
    /// Holes with more boundary edges than this are left open; 0 = no limit (default).
    std::size_t max_hole_edges = 0;
    /// Explicit holes (boundary loops, as find_boundary_loops gives them); when not
    /// empty, detection is skipped and exactly these are filled.
    std::vector<std::vector<Index>> holes = {};
    /// The outer-border rule of find_boundary_loops (HoleParams::outer_border_extent,
    /// default 0.75): the outer border of an open scan is never filled.
    Scalar outer_border_extent = Scalar(0.75);
    /// Initial patch, default thin_plate (closer to the truth before and after the
    /// minimisation; docs/methods/example_completion.md).
    InitialPatch initial = InitialPatch::thin_plate;
    /// s of the weights w = 1/s^m inside the hole (m = links to the hole boundary),
    /// > 1, default 2 (the paper's models I and II): larger trusts the rim more.
    Scalar s = 2;
    /// Candidates whose SSD is computed: the top_percent % of the data vertices by
    /// curvature likeness K (eq. 9), in (0, 100], default 10 (the paper's n).
    Scalar top_percent = 10;
    /// The coarse-to-fine schedule, default Table 1: A = 9, 7, 5; split 4, 2, 1.3;
    /// merge 1.5, 0.8, 0.4; thinned 8/9, 3/4, 0.
    std::vector<CompletionLevel> levels = {{9, 4, 1.5, Scalar(8) / 9}, {7, 2, 0.8, Scalar(0.75)}, {5, 1.3, 0.4, 0}};
    /// Radius of the range B of the quadric fits that give the frames (eq. 3-7), in
    /// l_ave, > 0, default 12 (the paper used 8 to 26 by model).
    Scalar b_radius = 12;
    /// Most iterations per level, >= 1 (default 8): a level also ends when the energy
    /// falls by less than `tolerance` (relative) or an iteration would raise it.
    std::size_t max_iterations = 8;
    /// Relative energy decrease below which a level has converged, >= 0, default 0.01.
    Scalar tolerance = Scalar(0.01);
    /// Data vertices examined as candidates p̂ (an even random subset when the data
    /// region is larger), >= 1, default 3000: bounds the search's cost on big meshes.
    std::size_t max_candidates = 3000;
    /// Vertices of A used to rank candidates before the exact SSD of the best three,
    /// >= 4, default 24.
    std::size_t search_samples = 24;
    /// Seed of the candidate subset and of the thinning (results depend on it only).
    std::uint64_t seed = 0;
    RunControl control{};
    /// Blend each hole's result with the thin-plate fairing of the same patch, default
    /// true: the patch's offset from that smooth surface is scaled by the hole's example
    /// weight λ = max(0, 1 - R_e / R_q), the share of the data's departure from a smooth
    /// surface that the copied shapes explain. R_e: mean squared distance of the data
    /// vertices within A of the hole to the shapes they matched (SSD, eq. 2, data only);
    /// R_q: to a quadric fitted over the same A. λ ≈ 1 where the surroundings repeat
    /// elsewhere on the object (the relief is copied), 0 where the best matches explain
    /// them worse than a quadric (a smooth surface: the smooth fill predicts better;
    /// docs/methods/example_completion.md). false: the minimiser's result, unblended.
    bool blend_with_smooth = true;
    /// Explosion guard: most patch vertices a hole may hold, as a multiple of the vertices
    /// of a flat disk with the hole's perimeter meshed at l_ave plus the loop's vertices,
    /// > 0, default 16 (the finest level, edges 0.4 to 1.3 l_ave, needs about 1.2 of that
    /// disk on a round hole). A hole that needs more, whose patch leaves its reach (the
    /// loop's box grown by its diagonal, mesh/holes.hpp) or whose energy is not finite is
    /// reverted to its thin-plate fill (CompletionResult::hole_status).
    Scalar max_patch_growth = 16;
};

/// What became of a filled hole (CompletionResult::hole_status).
enum class HoleStatus : std::uint8_t {
    completed,              ///< filled by the minimisation (and the blend)
    reverted_left_reach,    ///< a patch vertex left the hole's reach or was not finite
    reverted_vertex_bound,  ///< the remesh needed more vertices than max_patch_growth allows
    reverted_energy,        ///< the energy E became NaN or infinite
};

/// Name of a HoleStatus ("completed", "left_reach", "vertex_bound", "energy").
[[nodiscard]] inline const char* to_string(HoleStatus s) {
    switch (s) {
        case HoleStatus::completed: return "completed";
        case HoleStatus::reverted_left_reach: return "left_reach";
        case HoleStatus::reverted_vertex_bound: return "vertex_bound";
        case HoleStatus::reverted_energy: return "energy";
    }
    return "unknown";
}

/// Result of complete_holes_example_based.
struct CompletionResult {
    Status status = Status::ok;
    std::size_t filled_holes = 0;       ///< holes closed
    std::vector<std::vector<Index>> unfilled_holes;  ///< selected loops that could not be closed
    std::size_t new_vertices = 0;       ///< appended after the existing vertices
    std::size_t new_faces = 0;          ///< appended after the existing faces
    /// Energy E (eq. 1, squared length units) per level: first after the initial
    /// search, then after every accepted iteration (non-increasing within a level).
    std::vector<std::vector<Scalar>> energy;
    Scalar mean_edge_length = 0;        ///< l_ave of the data region
    std::vector<StageTiming> timings;   ///< detect, initial patch, level 1..n, write
    /// Per filled hole (in the order of the selected loops), the weight λ in [0, 1] of the
    /// example-based offset in the blend (CompletionParams::blend_with_smooth; 1 when off
    /// or when the hole's surroundings gave no evidence; 0 for a reverted hole).
    std::vector<Scalar> example_weight;
    /// Per filled hole (same order): completed, or why the explosion guard reverted it to
    /// its thin-plate fill (the patch fill_holes gives, its vertices never moved; the
    /// other holes are then minimised again without it, and the energy history is that
    /// of the last run). A reverted hole is still closed.
    std::vector<HoleStatus> hole_status;
};

namespace detail::completion {

/// Bounds on the points one vertex reads, where the data is far denser than l_ave (a fan of
/// thousands of thin faces around one vertex: a 5,000-segment bicone's apex ring held 5,000
/// vertices within A, and its first evaluation alone ran past 20 s). Beyond them an even
/// subset is read: by distance for the SSD's samples, in the search's order for the frame
/// fits. Scanned meshes stay below (CGAL's elephant-with-holes: 789 samples within A and 1,693
/// within B at most; bun_zipper: 498 and 1,087), so their results do not change.
inline constexpr std::size_t max_ssd_samples = 1024;
inline constexpr std::size_t max_fit_points = 4096;
/// Fixed vertices of Ω' whose sphere A holds more than this many times the vertices a mesh
/// of equilateral triangles at l_ave holds there are thinned to that share (at random, by
/// vertex), so that their number, too, follows the surface's area rather than its density.
/// The scanned meshes above read at most 2.7 times at the first level.
inline constexpr Scalar dense_ratio = 4;
/// Vertices within a sphere of radius a (in l_ave) of a plane meshed by equilateral
/// triangles of side l_ave: π a² times 2 / √3 per unit area.
inline Scalar uniform_vertices_within(Scalar a) { return Scalar(3.14159265358979323846) * a * a * Scalar(1.1547005383792515); }

/// Index of the k-th of `limit` entries spread evenly over n (n >= limit; k itself when n == limit).
inline std::size_t spread(std::size_t k, std::size_t n, std::size_t limit) { return k * n / limit; }

/// Orthonormal frame at a vertex: origin o, principal directions x (k1), y (k2), normal z.
struct LocalFrame {
    Vec3 o = Vec3::Zero(), x = Vec3::UnitX(), y = Vec3::UnitY(), z = Vec3::UnitZ();
    Scalar k1 = 0, k2 = 0;
    [[nodiscard]] Vec3 local(const Vec3& p) const {
        const Vec3 d = p - o;
        return {d.dot(x), d.dot(y), d.dot(z)};
    }
    [[nodiscard]] Vec3 local_dir(const Vec3& d) const { return {d.dot(x), d.dot(y), d.dot(z)}; }
};

/// Frame by the quadric fit of the points within B (PCA frame, z = quadric, normal and
/// principal directions at the vertex), oriented along `ref`. Flat or degenerate: any
/// orthonormal x, y around the fit's (or ref's) normal.
inline LocalFrame fit_frame(const Vec3& p, const Vec3& ref, const KdTree& tree, Scalar rb2,
                            std::vector<Neighbor>& nb) {
    tree.radius_search_squared(p, rb2, nb, false);
    LocalFrame f;
    f.o = p;
    JetFit j;
    const std::size_t n = std::min(nb.size(), max_fit_points);  // an even subset beyond the bound
    if (n >= 8)
        j = detail::fit_jet(
            [&](std::size_t k) -> const Vec3& {
                return tree.point(nb[spread(k, nb.size(), n)].index);
            },
            n, p, 2, true);
    if (j.valid && j.d1.allFinite() && j.d2.allFinite()) {
        orient_jet(j, ref);
        f.z = j.normal;
        f.x = j.d1;
        f.y = f.z.cross(f.x).normalized();
        f.k1 = j.k1;
        f.k2 = j.k2;
        return f;
    }
    f.z = ref.norm() > 0 ? Vec3(ref.normalized()) : Vec3::UnitZ();
    const Vec3 a = std::abs(f.z.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
    f.x = (a - a.dot(f.z) * f.z).normalized();
    f.y = f.z.cross(f.x);
    return f;
}

/// The data surface around a candidate, as heights over its frame's (x, y) plane on a
/// square grid of half-width `r` cells (NaN where no data triangle projects).
struct HeightMaps {
    int r = 0, g = 0;           ///< half-width in cells, side g = 2 r + 1
    Scalar cell = 1, inv_cell = 1;
    std::vector<float> h;       ///< g * g per candidate

    [[nodiscard]] const float* map(std::size_t c) const { return h.data() + c * static_cast<std::size_t>(g * g); }

    /// Bilinear height at (u, v); false outside the grid or where no data is near.
    bool sample(const float* H, Scalar u, Scalar v, Scalar& out) const {
        const Scalar gu = u * inv_cell + r, gv = v * inv_cell + r;
        if (!(gu >= 0 && gv >= 0 && gu <= g - 1 && gv <= g - 1)) return false;
        const int i = std::min(static_cast<int>(gu), g - 2), j = std::min(static_cast<int>(gv), g - 2);
        const Scalar fu = gu - i, fv = gv - j;
        const float c[4] = {H[i * g + j], H[(i + 1) * g + j], H[i * g + j + 1], H[(i + 1) * g + j + 1]};
        const Scalar w[4] = {(1 - fu) * (1 - fv), fu * (1 - fv), (1 - fu) * fv, fu * fv};
        Scalar s = 0, ws = 0;
        for (int k = 0; k < 4; ++k)
            if (!std::isnan(c[k])) {
                s += w[k] * c[k];
                ws += w[k];
            }
        if (!(ws > 1e-6)) return false;
        out = s / ws;
        return true;
    }

    /// Where the line q + t d (candidate-local, |d| = 1) meets the height field: Newton
    /// steps on t; false when it leaves the grid, finds no data or |t| > tmax.
    bool intersect(const float* H, const Vec3& q, const Vec3& d, Scalar tmax, Scalar& t, int iterations = 5) const {
        t = 0;
        for (int it = 0; it < iterations; ++it) {
            const Vec3 x = q + t * d;
            Scalar h0 = 0, h1 = 0;
            if (!sample(H, x.x(), x.y(), h0)) return false;
            Scalar slope = d.z();
            if (iterations > 2 && sample(H, x.x() + cell * d.x(), x.y() + cell * d.y(), h1)) slope -= (h1 - h0) * inv_cell;
            if (std::abs(slope) < Scalar(0.2)) slope = slope < 0 ? Scalar(-0.2) : Scalar(0.2);
            const Scalar step = (x.z() - h0) / slope;
            t -= step;
            if (!(std::abs(t) <= tmax)) return false;
            if (std::abs(step) < Scalar(1e-4) * cell) break;
        }
        return true;
    }
};

/// A vertex of A in the frame of the sphere's centre: position and normal direction.
struct Sample {
    Vec3 q, d;
};

/// SSD (eq. 2) of samples against height map H with the frame mirrored by (sx, sy):
/// mean squared distance along each sample's normal line; a line that misses costs miss2.
/// Stops early (returning +inf) once the SSD is sure to exceed `bound`.
inline Scalar ssd(const HeightMaps& hm, const float* H, const Sample* s, std::size_t n, std::size_t stride, int variant,
                  Scalar tmax, Scalar miss2, Scalar bound = std::numeric_limits<Scalar>::infinity(), int iterations = 5) {
    const Scalar sx = (variant & 1) ? -1 : 1, sy = (variant & 2) ? -1 : 1;
    const std::size_t total = n == 0 ? 0 : (n - 1) / stride + 1;
    const Scalar limit = bound * static_cast<Scalar>(total);
    Scalar sum = 0;
    for (std::size_t k = 0; k < n; k += stride) {
        const Vec3 q(sx * s[k].q.x(), sy * s[k].q.y(), s[k].q.z());
        const Vec3 d(sx * s[k].d.x(), sy * s[k].d.y(), s[k].d.z());
        Scalar t = 0;
        sum += hm.intersect(H, q, d, tmax, t, iterations) ? t * t : miss2;
        if (sum > limit) return std::numeric_limits<Scalar>::infinity();
    }
    return total ? sum / static_cast<Scalar>(total) : miss2;
}

/// A correspondence p -> p̂: candidate index (in the level's pool) and mirror variant.
struct Match {
    std::uint32_t cand = std::numeric_limits<std::uint32_t>::max();
    std::uint8_t variant = 0;
    [[nodiscard]] bool valid() const { return cand != std::numeric_limits<std::uint32_t>::max(); }
};

/// Deterministic uniform number in [0, 1) from a vertex, a level and the seed.
inline Scalar hash01(std::uint64_t v, std::uint64_t level, std::uint64_t seed) {
    std::uint64_t x = v * 0x9E3779B97F4A7C15ULL ^ (level + 1) * 0xC2B2AE3D27D4EB4FULL ^ seed * 0x165667B19E3779F9ULL;
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdULL;
    x ^= x >> 33;
    x *= 0xc4ceb9fe1a85ec53ULL;
    x ^= x >> 33;
    return static_cast<Scalar>(x >> 11) * Scalar(1.0 / 9007199254740992.0);
}

/// Whether moving the removed end of the collapse of h to `p` keeps every other face
/// around both ends from turning over.
inline bool collapse_keeps_orientation(const HalfedgeMesh& m, Index h, const Vec3& p) {
    const Index a = m.source(h), b = m.target(h);
    std::vector<Index> out;
    for (const Index v : {a, b}) {
        m.outgoing_halfedges(v, out);
        for (const Index e : out) {
            const Index f = HalfedgeMesh::face(e);
            if (f == HalfedgeMesh::face(h) || (m.twin(h) != HalfedgeMesh::invalid && f == HalfedgeMesh::face(m.twin(h))))
                continue;
            const Index u = m.target(e), w = m.opposite(e);
            if (u == a || u == b || w == a || w == b) continue;
            const Vec3 n0 = (m.position(u) - m.position(v)).cross(m.position(w) - m.position(v));
            const Vec3 n1 = (m.position(u) - p).cross(m.position(w) - p);
            if (!(n0.dot(n1) > 0.2 * n0.norm() * n1.norm())) return false;
        }
    }
    return true;
}

/// Test hook, null by default: called after every update step (eq. 16) with the working
/// mesh and the per-vertex patch flags, so that the tests can make a patch explode.
inline thread_local void (*test_after_update)(HalfedgeMesh&, const std::vector<std::uint8_t>&) = nullptr;

/// The working state: the mesh with its patch, which vertices are new (Ω).
struct State {
    HalfedgeMesh hm;
    std::vector<std::uint8_t> omega;  ///< per vertex slot: 1 = patch vertex (moves)
    std::vector<Match> match;         ///< per vertex slot
    std::size_t nv0 = 0, nf0 = 0;     ///< data vertices and faces (never edited)
    std::vector<std::uint8_t> fixed_face;  ///< per face: 1 = a reverted hole's patch (never edited)

    void grow() {
        omega.resize(hm.vertex_capacity(), 0);
        match.resize(hm.vertex_capacity());
    }
    [[nodiscard]] bool patch_face(Index f) const {
        return f >= nf0 && !hm.is_removed_face(f) && !(f < fixed_face.size() && fixed_face[f]);
    }
    [[nodiscard]] bool patch_interior(Index h) const {
        const Index g = hm.twin(h);
        return g != HalfedgeMesh::invalid && patch_face(HalfedgeMesh::face(h)) && patch_face(HalfedgeMesh::face(g));
    }
    [[nodiscard]] Scalar length(Index h) const { return (hm.position(hm.target(h)) - hm.position(hm.source(h))).norm(); }

    void flip_to_delaunay() {
        for (int sweep = 0; sweep < 20; ++sweep) {
            bool any = false;
            for (Index h = 3 * nf0; h < hm.halfedge_capacity(); ++h) {
                if (hm.is_removed_face(HalfedgeMesh::face(h)) || !patch_interior(h) || hm.twin(h) < h) continue;
                if (!is_locally_delaunay(hm, h) && hm.flip(h)) any = true;
            }
            if (!any) return;
        }
    }

    /// Step (iii): split patch edges longer than hi, collapse those between two patch
    /// vertices shorter than lo (a data vertex never moves), Delaunay flips in between.
    /// Splitting stops once there are more than max_patch patch vertices (the guard then
    /// reverts the hole that holds too many).
    void remesh(Scalar hi, Scalar lo, std::size_t max_patch = std::numeric_limits<std::size_t>::max()) {
        std::size_t n = 0;
        for (Index v = nv0; v < hm.vertex_capacity(); ++v) n += !hm.is_removed_vertex(v) && omega[v];
        for (int pass = 0; pass < 6; ++pass) {
            bool any = false;
            const Index end = hm.halfedge_capacity();
            for (Index h = 3 * nf0; h < end; ++h) {
                if (hm.is_removed_face(HalfedgeMesh::face(h)) || !patch_interior(h) || hm.twin(h) < h) continue;
                if (length(h) <= hi) continue;
                if (n > max_patch) return;
                const Index m = hm.split(h, 0.5);
                ++n;
                grow();
                omega[m] = 1;
                match[m] = Match{};
                any = true;
            }
            if (!any) break;
            flip_to_delaunay();
        }
        flip_to_delaunay();
        for (int pass = 0; pass < 4; ++pass) {
            bool any = false;
            for (Index h = 3 * nf0; h < hm.halfedge_capacity(); ++h) {
                if (hm.is_removed_face(HalfedgeMesh::face(h)) || !patch_interior(h)) continue;
                const Index a = hm.source(h), b = hm.target(h);
                // Only two patch vertices merge (at the midpoint): the rim keeps its ring of
                // new vertices, so a small hole is never emptied by a coarse level.
                if (!omega[a] || !omega[b] || hm.twin(h) < h) continue;
                if (length(h) >= lo) continue;
                const Scalar t = Scalar(0.5);
                const Vec3 p = hm.position(a) + t * (hm.position(b) - hm.position(a));
                if (!hm.can_collapse(h) || !collapse_keeps_orientation(hm, h, p)) continue;
                hm.collapse(h, t);
                any = true;
            }
            if (!any) break;
            flip_to_delaunay();
        }
    }
};


/// The completion of complete_holes_example_based on its working copy `work` (the input's
/// vertices and faces): no user type appears below the conversion, so a program compiles this
/// body once whatever mesh types it completes. Appends the patch to new_pos / new_faces; a
/// cancelled run returns Status::cancelled with both left to be discarded.
/// Defined in detail/complete_indexed.ipp (kintsugi/core/stages.hpp).
KINTSUGI_STAGE CompletionResult complete_indexed(IndexedMesh& work, const CompletionParams& params, const std::string& fn,
                                                 std::vector<Vec3>& new_pos, std::vector<Face>& new_faces);

}  // namespace detail::completion

/// @brief Fills holes of a triangle mesh with geometry that resembles the rest of the
/// object (Kawai, Sato, Yokoya, "3D surface completion by minimizing energy based on
/// similarity of local shape", TVRSJ 2009; docs/methods/example_completion.md).
///
/// The selected holes are closed by an initial patch (thin-plate fill or the paper's
/// fan); then, per level of a coarse-to-fine schedule, three steps repeat until the
/// energy E (eq. 1) converges: (i) each vertex p of Ω' (the patch and the vertices
/// within A of it) finds the data vertex p̂ whose surface, aligned by the two quadric
/// frames (eq. 3-7, mirrored frames too), is closest to p's neighbourhood A along the
/// normal lines (SSD, eq. 2), testing the top_percent % of candidates by curvature
/// likeness (eq. 9); (ii) every patch vertex moves at once along its normal to the
/// weighted mean of where its normal line meets the surfaces its neighbours matched
/// (eq. 16), weights 1 outside and 1/s^m inside the hole; (iii) patch edges are split or
/// collapsed to keep the level's density. An iteration that would raise E is undone and
/// ends the level, so E never rises within a level. Last, per hole, the patch's offset
/// from the thin-plate fairing of the same patch is kept in the share λ that the copied
/// shapes explain of the surroundings better than a quadric (blend_with_smooth).
///
/// @tparam M a TopologyMutableMesh (IndexedMesh, CGAL::Surface_mesh, ...). The existing
///         vertices and faces are untouched; new ones are appended. An IndexedMesh with
///         normals receives normals for the new vertices.
/// @param mesh   an oriented 2-manifold with boundary
/// @param params hole selection, schedule, cancellation (CompletionParams)
/// @throws invalid_input (mesh untouched) naming the element when the mesh is empty,
///         not an oriented manifold (including a boundary that touches itself: a
///         non-manifold vertex), has NaN/Inf coordinates, a given hole is not a
///         boundary loop, or a parameter is out of range.
/// @return Status::ok (closed holes counted, loops that could not be triangulated in
///         unfilled_holes); Status::cancelled: the mesh is untouched.
template <TopologyMutableMesh M>
CompletionResult complete_holes_example_based(M& mesh, const CompletionParams& params = {}) {
    using namespace detail::completion;
    const std::string fn = "kintsugi::complete_holes_example_based: ";
    auto bad = [&](const std::string& what) { throw invalid_input(fn + what); };
    if (!(params.max_hole_size > 0)) bad("max_hole_size must be > 0 (fraction of the diagonal, default 0.25)");
    if (!(params.outer_border_extent >= 0)) bad("outer_border_extent must be >= 0 (default 0.75)");
    if (!(params.s > 1) || !std::isfinite(params.s)) bad("s = " + std::to_string(params.s) + " must be finite and > 1 (default 2)");
    if (!(params.top_percent > 0 && params.top_percent <= 100))
        bad("top_percent = " + std::to_string(params.top_percent) + " must lie in (0, 100] (default 10)");
    if (params.levels.empty()) bad("levels is empty; give at least one level (default: Table 1's three)");
    for (std::size_t i = 0; i < params.levels.size(); ++i) {
        const auto& L = params.levels[i];
        const std::string w = "level " + std::to_string(i + 1) + ": ";
        if (!(L.a_radius > 0) || !std::isfinite(L.a_radius)) bad(w + "a_radius must be finite and > 0");
        if (!(L.merge_below >= 0) || !(L.split_above > 2 * L.merge_below) || !std::isfinite(L.split_above))
            bad(w + "need 0 <= merge_below and split_above > 2 merge_below (finite), else splits and merges undo each other");
        if (!(L.thin_fraction >= 0 && L.thin_fraction < 1)) bad(w + "thin_fraction must lie in [0, 1)");
    }
    if (!(params.b_radius > 0) || !std::isfinite(params.b_radius)) bad("b_radius must be finite and > 0 (default 12)");
    if (params.max_iterations < 1) bad("max_iterations must be >= 1 (default 8)");
    if (!(params.tolerance >= 0)) bad("tolerance must be >= 0 (default 0.01)");
    if (params.max_candidates < 1) bad("max_candidates must be >= 1 (default 3000)");
    if (params.search_samples < 4) bad("search_samples must be >= 4 (default 24)");
    if (!(params.max_patch_growth > 0) || !std::isfinite(params.max_patch_growth))
        bad("max_patch_growth must be finite and > 0 (default 16)");

    const std::size_t nv0 = kintsugi::num_vertices(mesh), nf0 = kintsugi::num_faces(mesh);
    if (nv0 == 0 || nf0 == 0) bad("the mesh is empty (" + std::to_string(nv0) + " vertices, " + std::to_string(nf0) + " faces); pass a triangle mesh");
    IndexedMesh work;
    work.vertices.resize(nv0);
    work.faces.resize(nf0);
    for (Index v = 0; v < nv0; ++v) work.vertices[v] = vertex_position(mesh, v);
    for (Index f = 0; f < nf0; ++f) work.faces[f] = face_at(mesh, f);
    {
        // Shapes are copied from the data's faces: with none of positive area (every vertex at
        // one point, or all of them on a line) there is nothing to copy and no scale to fill at.
        bool area = false;
        for (Index f = 0; f < nf0 && !area; ++f) {
            const Face& t = work.faces[f];
            area = (work.vertices[t[1]] - work.vertices[t[0]]).cross(work.vertices[t[2]] - work.vertices[t[0]]).norm() > 0;
        }
        if (!area)
            bad("every face of the mesh has zero area (its vertices coincide or lie on one line); there is no surface "
                "to copy from");
    }
    try {
        (void)HalfedgeMesh::from_faces(work.vertices, work.faces);
    } catch (const invalid_input& e) {
        throw invalid_input(fn + e.what() + " (a boundary that touches itself is a non-manifold vertex)");
    }

    std::vector<Vec3> new_pos;    // the patch, appended at the end
    std::vector<Face> new_faces;
    CompletionResult out = detail::completion::complete_indexed(work, params, fn, new_pos, new_faces);
    if (out.status == Status::cancelled) return out;
    detail::append_patch(mesh, new_pos, new_faces);
    out.new_vertices = new_pos.size();
    out.new_faces = new_faces.size();
    return out;
}

}  // namespace kintsugi

#ifndef KINTSUGI_SEPARATE_STAGES
#include <kintsugi/complete/detail/complete_indexed.ipp>
#endif
