// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file feature_bilateral.hpp
/// @brief Feature-aware mesh smoothing: sharp edges found with the normal voting
/// tensor, then four bilateral filters that keep edges sharp and make the edges
/// themselves straight.
///
/// Method: T. Shimizu, H. Date, S. Kanai, T. Kishinami, "メッシュモデルの形状特徴を認識した
/// メッシュスムージング手法" (a mesh smoothing method that recognises shape features),
/// Hokkaido University. Normal voting tensor after Y. Sun, D. L. Page, J. K. Paik,
/// A. Koschan, M. A. Abidi, "Triangle mesh-based edge detection and its application to
/// surface segmentation and adaptive surface smoothing", ICIP 2002. Bilateral filter on
/// meshes after T. R. Jones, F. Durand, M. Desbrun, SIGGRAPH 2003.
///
/// @code
/// kintsugi::IndexedMesh mesh = kintsugi::read_mesh("scan.ply");
/// auto r = kintsugi::smooth_feature_bilateral(mesh);          // d, face iterations from the noise
/// // r.noise.sigma: the noise level estimated on the input; r.lowpass_iterations: Taubin
/// // steps run first (strong noise); r.d, r.face_iterations: used; r.risk.taubin: Taubin's
/// // result kept instead of the filters' (lower estimated error: smooth organic shapes)
/// auto f = kintsugi::detect_sharp_features(mesh, {.edge_threshold = 0.102}); // scans
/// @endcode
///
/// ## Normal voting tensor and edge strength
/// For vertex i, T_i = Σ_t μ_t n_t n_tᵀ over the faces t whose centroid lies in the
/// axis-aligned cube of side `voting_cube`·|e| centred at p_i (|e| the mean edge length),
/// with μ_t = a_t · exp(−‖c_t − p_i‖ / h), h the cube's half side: area-weighted votes
/// decaying with distance, as in Sun et al. / Page et al. T_i is divided by its trace,
/// so its eigenvalues v1 ≥ v2 ≥ v3 ≥ 0 sum to 1; e1, e2, e3 are the eigenvectors.
///
/// The paper does not print its edge strength. We use Sun et al.'s eigenvalue
/// analysis (face: v1 ≫ v2 ≈ v3 ≈ 0; sharp edge: v1 ≈ v2 ≫ v3; corner: v1 ≈ v2 ≈ v3)
/// and take **s_i = v2 / v1** ∈ [0, 1]: 0 on a flat face, 1 on a symmetric sharp edge
/// whose two faces meet at a right angle and at a cube corner. For a symmetric edge
/// whose face normals make an angle φ, s = tan²(φ/2): the paper's threshold 0.251
/// selects edges sharper than about 53°, and 0.102 (its value for scans) about 35°.
/// e3 is the crease direction at an edge vertex. A mesh edge is sharp when one of its
/// vertices has s ≥ `edge_threshold` and |d_e · e3| ≥ `direction_threshold` (0.9).
///
/// ## The four filters (the paper's Table 1)
/// Each is O_r = (1/k_r) Σ_q I_q w_q f(X, σ1) g(Y, σ2), f and g Gaussian; in this order:
///  1. sharp-edge directions: r = e, q = sharp edges e* with midpoint in the cube of
///     side 2σ_mef around c_e; I = d_e* (sign aligned with d_e), w = l_e*,
///     X = ‖c_e − c_e*‖, σ_mef = a|e|/2; Y = ‖d_e − d_e*‖, σ_meg = 0.6; g = 0 when Y > 1.
///  2. sharp-edge vertices: r = i, q = e* (same cube size, around p_i);
///     I = Π_e* = c_e* + ((p_i − c_e*)·d'_e*) d'_e*, w = l_e*, X = ‖c_e* − p_i‖,
///     σ_ef = a|e|; Y = ‖Π_e* − p_i‖, σ_eg = b|e|.
///  3. face normals: r = t, q = t* with centroid in the cube of side 2σ_f around c_t;
///     I = n_t*, w = area a_t*, X = ‖c_t − c_t*‖, σ_mf = c|e|/2; Y = ‖n_t − n_t*‖,
///     σ_mg = 0.6; g = 0 when Y > 1.
///  4. vertices: r = i, q = t* (same cube, around p_i); I = Π_t = p_i − ((p_i − c_t)·n'_t) n'_t,
///     w = a_t*, X = ‖c_t − p_i‖, σ_f = c|e|; Y = ‖Π_t − p_i‖, σ_g = d|e|.
/// Filters 1–2 run `edge_iterations` times on the sharp-edge vertices, then filters 3–4
/// run `face_iterations` times. Within one face iteration filter 3 is applied
/// `normal_iterations` times (paper: once) and filter 4 `vertex_iterations` times.
/// Filter 4 moves the sharp-edge vertices too, as it moves every vertex (the paper
/// applies the face filters to the whole mesh); by default filters 1–2 then run
/// `edge_iterations` times more on them ("Edges that straighten" below).
/// With `features = false` no features are detected and filters 3–4 run alone. Every
/// pass reads the values of the previous one (Jacobi updates), so the result does not
/// depend on the thread count.
///
/// ## Departures from the paper
/// Each is measured on the guided-denoising pairs (Block0.4, SharpSphere0.3,
/// Twelve0.5Impulsive, noise 3-5 times the paper's); the figures, the values tried and
/// the cost are in docs/methods/feature_bilateral.md.
/// - Detection under heavy noise (SharpFeatureParams): the votes are taken on a
///   pre-smoothed copy (`presmooth_*`, `prefilter_*`), and a mesh edge is sharp when its
///   two faces' filtered normals are at least 2·atan(√edge_threshold) apart
///   (`crease_test`) instead of the direction test.
/// - Sharp edges bound the face filters (`separate_features`): in filters 3 and 4 a face
///   of the cube counts only when a walk over the cube's faces reaches it from r's own
///   faces without crossing a sharp edge.
/// - Face filter scales: c = 1, d = 0.14 (or from the noise, below), 3–10 filter-3 and two
///   filter-4 passes per face iteration, 1–8 face iterations, both from the noise (paper:
///   c = 2, d = 0.1, one, one, two).
/// - Filters 1–2 run again after the face filters (`edge_vertex_motion`, below).
/// - Creases under impulsive noise from the faces it left in their planes
///   (`coplanar_creases`, below).
///
/// ## Edges that straighten
/// Filter 4 sees the faces of both sides of a crease and moves its vertices across it
/// too, which undid most of what filters 1–2 did (the edge stage was worth 0.05° on
/// Block0.4). With EdgeVertexMotion::straighten (the default) filters 1–2 run again,
/// `edge_iterations` times, on the sharp edges after the face filters, so the edge
/// vertices end on their filtered edge lines. Measured on a noisy box (16 × 16 per side,
/// 0.5|e| along the normals) and Block0.4: the angle of the sharp edges to the true
/// creases falls from 4.43° / 9.65° (no edge stage) and 4.14° / 9.17° (filter 4 last)
/// to 3.56° / 8.20°, the mean normal error from 3.00° / 5.29° to 2.95° / 5.26°. Letting
/// filter 4 move them only along their edge line (the other reading) or not at all
/// kept their noise across the crease (Block0.4: 7.5° instead of 5.3°); see
/// docs/methods/feature_bilateral.md. FeatureBilateralParams::paper() gives the paper's
/// published parameters and detection, to measure these departures against.
///
/// ## Parameters from the data (the paper's future work)
/// When `d` or `face_iterations` is left unset (the default), the input's noise level
/// is estimated first (estimate_noise_level, mesh/noise_level.hpp: the median of
/// local quadric-fit residual variances, below 0.3|e| combined with umbrella-height
/// differences, which read less of a detailed mesh's shape; σ normal to the surface) and, with
/// r = σ/|e| (|e| the input's mean edge length, as for every scale here),
/// d = max(0.14, 0.5·(r − 0.05)) and face_iterations = min(8, 3 + round(20·max(0, r − 0.38))):
/// the measured defaults up to r ≈ 0.33 (noise of about 0.3|e|), a wider range and more
/// passes above, where a fixed d|e| below the noise left filter 4 moving nothing. Below
/// r = 0.15, face_iterations = clamp(round(r / 0.05), 1, 3): light noise needs fewer
/// passes, and three damaged clean meshes (clean fertility 7.6°, armadillo 13.1°; one
/// iteration: 4.7°, 9.2°) at the cost of 0.07° on the Block at 0.1|e|. The filter-3 passes
/// per face iteration follow the noise too: 3 up to r = 0.15, 10 from 0.2
/// (normal_iterations_from_noise).
/// Explicit values are used as given and skip the estimate; the estimate and the
/// values used are in the result (`noise`, `d`, `face_iterations`). Measurements in
/// docs/methods/feature_bilateral.md.
/// (With the automatic low-pass below, d comes from the noise after it, about 0.2 or less,
/// and the face iterations from the input's noise r0: clamp(round(1 + 7·r0), 1, 8), see
/// face_iterations_after_lowpass; the mapping above for the iterations and the strong-noise
/// rule act when the low-pass is off or given a step count.)
/// Strong noise (face_iterations unset and r ≥ 0.47, about 0.7|e| of Gaussian noise and
/// above): at least 20 filter-3 passes per face iteration (instead of 10), and the
/// detection's pre-smoothing with at least 6 passes (3) and c = 3 for its normal filter
/// (2); `strong_noise` and `normal_iterations` in the result say what was used. Measured
/// on the Block at 0.7|e|: 14.1° → 11.0°; the sharp edges' P/R 0.33/0.60 → 0.53/0.75.
///
/// ## Strong noise: a low-pass first
/// The filters above compare noisy normals and offsets with each other; from about 0.3|e|
/// of noise they keep noise clusters and the detection misses creases (Block at 0.7|e|:
/// 11.0°, and far behind Taubin smoothing on curved shapes). So when the noise is
/// estimated, Taubin λ|μ steps (λ = 0.5, μ = −0.5, one-ring umbrella: kintsugi::smooth_taubin's
/// operator; rim vertices moving along their normal only, those of non-manifold edges
/// fixed) run first, the noise
/// re-estimated after each, until it is at most `lowpass_noise`·|e| (0.2), at most 20
/// steps; d and the strong-noise rule are then set from the noise after the low-pass
/// (`noise_after_lowpass`, `lowpass_iterations` in the result), and |e| is the low-passed
/// mesh's; the face iterations and the filter-3 passes come from the input's noise
/// whenever the automatic low-pass is enabled, whether or not it runs a step (see
/// face_iterations_after_lowpass and normal_iterations_from_noise, whose r is σ over the
/// clean edge length, NoiseLevel::relative). Below 0.2|e| (clean meshes read 0–0.15) no
/// step runs.
/// Measured (normal error, defaults before → after; docs/methods/feature_bilateral.md):
/// Block at 0.5 / 0.7 / 0.8|e| 7.5 / 11.0 / 15.5° → 6.4 / 9.5 / 10.9°, SharpSphere 15.2 /
/// 25.9 / 32.7° → 9.7 / 11.9 / 13.1°, fertility 16.3 / 27.8 / 33.0° → 10.9 / 12.5 / 13.3°;
/// Block0.4 5.26° → 4.81°. The target 0.2 was chosen on the Block and fertility.
///
/// ## Straight creases under Gaussian noise (on by default)
/// The detection's pre-smoothing and prefilter use filter 3's range kernel, which admits
/// neighbours whose normals are up to 60° apart: once noise tilts the normals, a crease of
/// 53-65° is averaged away before the voting (Twelve's 63° creases: none found at any level of
/// Gaussian noise). With SharpFeatureParams::straight_creases (default on, off in paper()) a
/// second detection runs on the first one's neighbour sets with a narrow kernel (σ 0.3, cut
/// 0.85: normals within about 50°), and of its sharp edges those on straight runs (edges
/// continuing each other within 30°, 8 or more) whose two sides' input face normals are at
/// least 45° apart join the sharp edges (`features.straight_sharp_edges`; the narrow kernel alone
/// also reads noise folds of curved surfaces as creases, which zigzag or bend by less, and a
/// prism's 30° sides). Measured over the two noise tables (seed 11), defaults before → after:
/// Twelve 3.49 → 1.86° at 0.1|e| along the normals (P/R 0/0 → 1.0/1.0), 7.55 → 3.97° at
/// 0.3|e|, 7.53 → 4.30° at 0.5|e| in random directions; the Block at 0.7|e| 8.42 → 7.12°; the
/// 33 CAD cells −24.3° in sum (none worse by more than 0.01°), the 77 curved cells +0.09°
/// (none by more than 0.05°); held out (a box, prisms of 12 and 24 sides, an L-shaped bracket,
/// tori, spheres, bun_zipper_res2-4, the npm bunny; 143 cells): CAD −15.2°, curved +1.6° (one
/// cell flips the risk selection: bun_zipper_res2 at 0.8|e| random, +0.88°). Cost: a second
/// pre-smoothing on the first one's neighbour sets, and the voting tensor at the vertices of
/// its crease edges; the bench's 590K faces 3.55-3.60 → 4.63-4.66 s a call (its creases: 5 →
/// 3,840 sharp edges); later calls 4.7-4.9 s in the VM's faster phases since the passes' AVX
/// body and the exact-size lists, the first call in a process 5.0-5.5 s
/// (docs/methods/feature_bilateral.md, "Straight creases" and "Neighbourhoods and cost").
///
/// ## Impulsive noise: creases from the faces left in their planes
/// Impulsive noise moves a few vertices far and leaves the others exactly in place, so the
/// voting tensor (which averages the noisy normals) misses the creases of a CAD part:
/// Twelve0.5Impulsive's 63° creases had recall 0.019 and the smoothing reached 7.7°.
/// With SharpFeatureParams::coplanar_creases (default on, off in paper()), the faces
/// lying exactly in the plane of another face near them (*anchored* faces) give the
/// part's planes, and an edge is sharp when a pair of planes at least the crease angle
/// apart explains it: their line passes along the edge, its endpoints lie on both
/// planes or on their bisector (a crease vertex moved along its normal), and a quarter
/// of its endpoints' neighbours lie on one of them. These edges are added to the voting
/// tensor's. The corners of two anchored faces or more were not moved by the noise: with
/// `hold_unmoved` (default) they stay where they are through the low-pass and the filters.
/// The stage reads the input before the low-pass and stops when fewer than 1 % of the
/// faces are anchored (Gaussian noise, scans: a few by accident); the steps and constants
/// are in smooth/detail/coplanar_creases.hpp. Measured (docs/methods/feature_bilateral.md;
/// sharp-edge P/R, normal error with the defaults; voting tensor alone → with the stage
/// and the held vertices): Twelve0.5Impulsive (the pair it was tuned on) 1.0/0.019,
/// 7.67° → 0.856/0.819, 4.02°; held out, generated (10 % of the vertices moved along the
/// normals by Gaussian amounts of σ = |e|): Twelve 0.034/0.006, 7.57° → 0.816/0.971,
/// 1.11°; the Block 0.768/0.933, 3.71° → 0.761/0.968, 1.00°; SharpSphere 7.74° → 7.32°;
/// curved shapes are unchanged or slightly better (bunny00 4.77° → 4.74°, fertility
/// 9.65° → 9.49°). With the tighter anchoring of 2026-12-07 (0.1° / 0.002|e|; noise in
/// random directions anchored faces by accident): Twelve0.5Impulsive 0.907/0.833, 3.99°;
/// Twelve + 10 % 0.828/0.971, 1.10°; the Block 1.03°; SharpSphere 3.29° (with the impulse
/// removal; 3.19° before). Cost: one pass over the faces' neighbourhoods, and when the stage runs
/// seven Jacobi passes over the edges.
///
/// ## Impulsive noise on any shape: the moved vertices put back (on by default)
/// On curved shapes no face stays in a plane, and the filters keep an isolated spike's
/// faces as a feature (fertility with 10 % of its vertices moved by σ = |e|: 9.5°, the best
/// Taubin 5.8°). With `impulse_removal` (default; off in paper()) kintsugi::remove_impulses
/// (mesh/impulses.hpp) runs after the coplanar stage on the vertices it does not hold: when
/// the vertices' heights above the planes of their neighbours are heavy-tailed, those far
/// above are put onto a robust quadric of their unflagged two-ring, and the vertices left in
/// such a plane are held like the corners of anchored faces. Gaussian noise and scans do not
/// pass its gate (the run is then bit-identical), and above a fifth of the vertices flagged
/// it puts nothing back. The vertices are not held when the repaired mesh reads as Gaussian
/// noise (impulses on top of Gaussian noise; fbs::impulse_gaussian_after_repair). The noise is
/// estimated after it (`input_noise` is the input's: the repaired mesh's with the repair's
/// moves added in quadrature). Before everything else (with `impulse_removal`), a few vertices
/// far off the surface, which that gate does not see, are put back the same way (spikes: height
/// over 10 median edge lengths and 200 times the median height; `spike_vertices`): a spike kept
/// as a cone tip, and spread by the Taubin steps, dragged its neighbours by a quarter of its
/// height (the npm bunny with one vertex 50|e| off: 13.6|e|; at 10⁴|e| every scale, from the
/// mean edge length, was the spikes'); also a vertex moved nearly along the surface, every edge
/// at it over 10 median edge lengths and it off its neighbours' mean by over 0.8 of the shortest;
/// either way standing out from its ring by over 3 times the ring's radius, so that a coarse
/// corner beside fine faces is not one (docs/methods/feature_bilateral.md, "Spikes").
/// Noise-table impulsive cells: fertility 9.5° → 3.8°, armadillo 14.2° → 6.4°, the elephant
/// 16.9° → 6.7°, SharpSphere 7.3° → 3.2°; measured in docs/methods/feature_bilateral.md
/// ("Impulse removal").
///
/// ## Noise in random directions: folded faces unfolded first (on by default)
/// Noise that moves vertices along the surface folds faces over, and the vertex filter, which
/// moves vertices along face normals, cannot undo such a fold (the shark at 0.7|e| in random
/// directions: 11.9°, the best Taubin 4.7°). With `untangle` (default; off in paper()) the run
/// starts on a copy whose folded faces' corners were moved within their tangent plane
/// (mesh/untangle.hpp: only where the vertices' offsets from their neighbours read as tangential
/// noise, not impulsive, on a mesh that is not coarse), then writes the mesh once: the shark
/// 2.8°; noise along the normals and the noise table's 60 cells are unchanged bit for bit.
/// Measured in docs/methods/feature_bilateral.md ("Noise in random directions").
///
/// ## Risk selection: Taubin where it does better (on by default)
/// On smooth organic shapes the face filters lose to plain Taubin smoothing at its best step
/// count (fertility at 0.3|e| 8.9° against 5.7°). With `risk_selection` (the default) the run also scores
/// both results by an estimate of their squared error along the normals, from the noisy input
/// alone, and returns Taubin's when its estimate is below 0.75 times the filters'. Taubin's
/// step count is the one of least Stein's unbiased risk estimate (Stein 1981; mesh/taubin.hpp,
/// detail::taubin_risk_curves); the filters' risk is the same estimate with their divergence
/// measured by Monte-Carlo SURE (S. Ramani, T. Blu, M. Unser, "Monte-Carlo SURE: a black-box
/// optimization of regularization parameters for general denoising algorithms", IEEE TIP
/// 2008): one more run, with the values, sharp edges, mean edge length and filter-3 and filter-4
/// neighbour sets of the first (its discrete choices; detail::fbs::RunReuse), on the input moved by
/// ±0.1σ along the result's normals. Both estimates assume Gaussian-like noise: the selection
/// is skipped when vertices are held (impulsive noise, exact planes) and when the σ the Taubin
/// residual implies exceeds the estimate by 10 % (30 % where the input's estimated relative
/// noise, `noise.relative`, is at least 0.47: the estimate under-reads strong noise). Heights
/// can favour Taubin where its normals are far worse: on a prism whose vertices all lie on
/// creases between thin facets, small residual moves turn the faces (16 sides, caps wound
/// against the sides: 15-16° against the filters' 5.5°). Taubin's result is also kept, whatever
/// the height risks, on a mesh too coarse for the filters: when the median angle between
/// neighbouring faces of Taubin's result exceeds 1.25 d radians (10° at d = 0.14), filter 4
/// reads the surface's own bending as features and flattens it into facets (CGAL's eight.off,
/// 634 faces, at 0.5-0.8|e|: 24-27° against 10-13°; `risk.coarse`). Whenever
/// the heights or the coarseness choose Taubin, both mean squared face-normal errors are
/// estimated too, by the same Monte-Carlo SURE on the same probe (n̂·n_y less its covariance
/// with the input's face normals n_y; detail::fbs::normal_risk_difference), and Taubin's result
/// is not returned when its estimate exceeds the filters' by more than 0.03 rad² at more than
/// 2.5 standard errors (`risk.normal_veto`; generated prisms of 8-40 sides with their caps
/// wound against their sides: 60 of the 74 cells where Taubin had been chosen, 7.7-20.9° →
/// 2.0-7.6°, one wrongly by 0.5°; consistently oriented: 4 of 53, 13-16° → 4.5-10°, and 21 of
/// 120 cells still return Taubin's result where the filters' is better; no organic shape
/// measured reaches the bound; not applied where `noise.relative` ≥ 0.47 and the filters' height
/// risk reads zero or below). Where the filters are kept on a mesh whose faces meet at a median
/// angle over 0.6 d, their risk is estimated again with the sharp edges detected anew on each of
/// up to 16 probes (the frozen edges hide the noise-driven creases the detection reads in a
/// coarse surface's bending), and Taubin's result returned below half of it (`risk.recheck`;
/// coarse tori: 14-22° → 5-8°). The cost is a second run of the filters
/// without the detection or the face filters' neighbour searches, up to 200 Taubin steps, and
/// Taubin's result at the chosen count (twice, with the probe, when it is chosen): about 1.3×
/// the time of the filters alone on 590K faces (later calls 2.98-3.38 s against 2.28-2.39 s).
/// Past the recheck's gate, up to 16 more runs with the detection (probes × vertices ≤ 2^15,
/// about the cost of one run on 32K vertices). Measured in docs/methods/feature_bilateral.md
/// ("Risk selection", "Coarse meshes", "Faceted shapes", "Detection recheck").
///
/// ## Neighbourhoods and cost
/// Cube neighbourhoods come from a uniform grid over an internal copy of the mesh
/// renumbered along a Morton curve; neighbour sets are gathered once per stage and
/// their weights recomputed each pass. Memory and time are linear in the faces, and
/// the cost of each element is bounded (repeated faces, fans, long polygons). Every
/// output element is computed from the previous pass's values in a fixed neighbour
/// order (Jacobi updates), so the result does not depend on the thread count.
///
/// ## Boundaries, non-manifold input, degenerate faces
/// Boundary edges are never sharp unless `boundary_edges_sharp`. Boundary vertices are
/// filtered like the others: filter 4 moves a vertex only along filtered face normals,
/// so boundaries do not shrink; the low-pass moves them along their normal only, for the
/// same reason. Non-manifold edges and vertices are accepted (the
/// neighbourhoods are spatial cubes, not one-rings); a non-manifold edge may be sharp.
/// Degenerate faces get a zero normal and zero weight; a vertex with no usable
/// neighbour keeps its position. Vertices used by no face are never moved.

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>
#include <kintsugi/core/random.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/mesh/impulses.hpp>
#include <kintsugi/mesh/noise_level.hpp>
#include <kintsugi/mesh/taubin.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/mesh/untangle.hpp>
#include <kintsugi/smooth/detail/coplanar_creases.hpp>
#include <kintsugi/smooth/detail/feature_bilateral_impl.hpp>
#include <kintsugi/smooth/sharp_feature_params.hpp>
#include <kintsugi/spatial/morton.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

/// Sharp features of a mesh (all per-vertex arrays are indexed like the input vertices).
struct SharpFeatures {
    std::vector<Scalar> edge_strength;              ///< s_i = v2/v1 in [0, 1]
    std::vector<Vec3> eigenvalues;                  ///< (v1, v2, v3), decreasing, summing to 1 (0 if no face near)
    std::vector<std::array<Vec3, 3>> eigenvectors;  ///< unit e1, e2, e3 (e3: crease direction)
    std::vector<std::array<Index, 2>> sharp_edges;  ///< vertex pairs (a < b), sorted
    std::size_t candidate_vertices = 0;             ///< vertices with s_i >= edge_threshold
    Scalar mean_edge_length = 0;                    ///< |e| of the input, model units
    /// Faces lying exactly in the plane of another face near them (impulsive noise leaves
    /// them; 0 under Gaussian noise), and the sharp edges their planes explain, counted
    /// whether or not the voting tensor found them too (SharpFeatureParams::coplanar_creases;
    /// "Impulsive noise" in the file comment).
    std::size_t anchored_faces = 0;
    std::size_t coplanar_sharp_edges = 0;
    /// Sharp edges the straight-crease detection added to the voting tensor's
    /// (SharpFeatureParams::straight_creases; "Straight creases" in the file comment).
    std::size_t straight_sharp_edges = 0;
};

/// Result of detect_sharp_features().
struct SharpFeatureResult {
    Status status = Status::ok;  ///< ok, or cancelled (features then empty)
    SharpFeatures features;
    std::vector<StageTiming> timings;  ///< "topology", "coplanar creases" (when enabled), "features"
};

/// How the vertices of sharp edges are treated after filters 1–2 (see "Edges that
/// straighten" in the file comment).
enum class EdgeVertexMotion {
    straighten,  ///< filter 4 moves them, then filters 1–2 run again at the end (default)
    free,        ///< filter 4 moves them like every vertex; the edge stage is mostly overwritten
    fixed,       ///< filter 4 leaves them where filters 1–2 put them (measured worse)
};

/// Parameters of smooth_feature_bilateral(). a and b are the paper's; c, d and the
/// iteration counts were tuned by measurement (see "Departures" in the file comment).
struct FeatureBilateralParams {
    Scalar a = 2;    ///< edge spatial scale: σ_mef = a|e|/2, σ_ef = a|e| (paper: 2)
    Scalar b = 0.1;  ///< edge range scale: σ_eg = b|e| (paper: 0.1)
    Scalar c = 1;    ///< face spatial scale: σ_mf = c|e|/2, σ_f = c|e| (paper: 2; measured, see above)
    /// Face range scale: σ_g = d|e| (paper: 0.1). Unset (default): set from the noise
    /// level estimated on the input (see "Parameters from the data" above); explicit
    /// values are used as given. Range: positive.
    std::optional<Scalar> d{};
    /// The sharp-edge detection (its `control` is not used: `control` below governs the run).
    SharpFeatureParams detection{};
    std::size_t edge_iterations = 2;  ///< passes of filters 1–2 (paper: 2)
    /// Passes of filters 3–4 (paper: 2). Unset (default): set from the estimated noise
    /// level (see "Parameters from the data" above). Range 0–10000.
    std::optional<std::size_t> face_iterations{};
    bool features = true;  ///< false: no feature detection, filters 3–4 alone
    /// Passes of filter 3 per face iteration (paper: 1). Unset (default): from the estimated
    /// noise r, 3 up to 0.15|e| and 10 from 0.2|e| (light noise and clean meshes: ten passes
    /// flattened curved detail, Twelve at 0.1|e| 5.8° → 3.5°, fertility 7.1° → 5.9°, the Block
    /// 2.2° → 2.6°; see normal_iterations_from_noise), 10 when nothing is estimated (d and
    /// face_iterations given). Range 0–10000.
    std::optional<std::size_t> normal_iterations{};
    std::size_t vertex_iterations = 2;     ///< passes of filter 4 per face iteration (paper: 1; measured)
    /// What becomes of the sharp-edge vertices after filters 1–2 (see EdgeVertexMotion;
    /// default straighten: measured in docs/methods/feature_bilateral.md).
    EdgeVertexMotion edge_vertex_motion = EdgeVertexMotion::straighten;
    bool separate_features = true;    ///< sharp edges bound the face filters' neighbourhoods (see above)
    /// Hold the corners of anchored faces (faces impulsive noise left exactly in their
    /// planes; SharpFeatureParams::coplanar_creases) in place through the low-pass and the
    /// filters: those vertices were not moved by the noise, so every move is an error
    /// (Block + 10 % impulsive: 3.6° → 1.0°; "Impulsive noise" above). Held: the corners of
    /// two anchored faces or more (a moved vertex can be the corner of one). No effect when
    /// the coplanar stage is off or stops (under 1 % of the faces anchored). false = the paper.
    bool hold_unmoved = true;
    /// Taubin λ|μ steps (λ = 0.5, μ = −0.5, one-ring umbrella; rim vertices along their normal only) run
    /// on the mesh before everything else (see "Strong noise: a low-pass first" above).
    /// Unset (default): when the noise is estimated (d or face_iterations unset), as many
    /// as bring the estimate to `lowpass_noise`·|e| or below, at most 20 (none when it is
    /// already there); otherwise none. Given: exactly that many. Range 0–10000.
    std::optional<std::size_t> lowpass_iterations{};
    /// The noise level σ/|e| an unset `lowpass_iterations` brings the mesh to. Range [0, 1];
    /// 0 disables the automatic low-pass. Default 0.2: clean meshes read 0–0.15, and the
    /// filters below are at their best from about there (docs/methods/feature_bilateral.md).
    Scalar lowpass_noise = 0.2;
    /// Also run Taubin smoothing (detail::taubin_risk_curves, at most
    /// `risk_taubin_max_iterations` pairs) and return its result when its estimated error along
    /// the normals is below 0.75 times the filters' (squared errors) and its face normals are not
    /// estimated far worse ("Risk selection" above). Default true:
    /// on smooth organic shapes Taubin wins (fertility at 0.3|e|: 8.9° → 5.7°), and the noise table is
    /// behind the best Taubin in 11 of 54 cells instead of 26 (6 with the impulse removal too); false
    /// (the `paper` preset): the filters'
    /// result always, without the second run and the sweep (about 0.75× the time).
    bool risk_selection = true;
    /// Most Taubin λ|μ pairs the risk selection tries. Range 1–10000; default 200 (the best
    /// counts measured were 2-120; the sweep stops earlier once the risk rises).
    std::size_t risk_taubin_max_iterations = 200;
    /// Put back the vertices impulsive noise moved far off the surface, after the coplanar
    /// stage and before the noise estimate, and hold the vertices it takes as unmoved (with
    /// `hold_unmoved`); kintsugi::remove_impulses, which changes nothing unless the vertices'
    /// heights above their neighbours are heavy-tailed ("Impulsive noise on any shape" above).
    /// Default true: with 10 % of the vertices moved by σ = |e|, fertility 9.5° → 3.8°, armadillo
    /// 14.2° → 6.4°; false (the `paper` preset): the filters see the impulses. Also puts back
    /// spikes (a few vertices over 10 median edge lengths off the surface) before everything else.
    bool impulse_removal = true;
    /// Unfold the faces that noise along the surface folded over, before everything else but the spikes
    /// (mesh/untangle.hpp: only when the vertices' offsets from their neighbours' mean read as
    /// tangential noise, and only the folded faces' corners move, within the tangent plane).
    /// Default true: in random directions at 0.5|e| the shark 10.5° → 2.3°, fertility 14.8° → 6.0°,
    /// Twelve 11.8° → 7.5° (docs/methods/feature_bilateral.md, "Noise in random directions");
    /// noise along the normals does not pass its gate. False (the `paper` preset): the input as given.
    bool untangle = true;
    RunControl control{};

    /// The paper's published parameters and detection (its synthetic-noise example:
    /// voting cube 3|e|, threshold 0.251, the direction test on raw normals, (a, b) =
    /// (2, 0.1) twice, then (c, d) = (2, 0.1) twice with one filter-3 and one filter-4
    /// pass, the face filters over the whole mesh, no sharp-edge barriers), so that the
    /// measured departures above stay measurable. Its scan example used a 9|e| cube,
    /// threshold 0.102, (a, b) = (10, 1) once and (c, d) = (2, 1) once.
    [[nodiscard]] static FeatureBilateralParams paper() {
        FeatureBilateralParams p;
        p.a = 2;
        p.b = 0.1;
        p.c = 2;
        p.d = 0.1;
        p.detection = {.voting_cube = 3, .edge_threshold = 0.251, .direction_threshold = 0.9,
                       .prefilter_iterations = 0, .crease_test = false, .presmooth_iterations = 0,
                       .coplanar_creases = false, .straight_creases = false};
        p.edge_iterations = 2;
        p.face_iterations = 2;
        p.normal_iterations = 1;
        p.vertex_iterations = 1;
        p.edge_vertex_motion = EdgeVertexMotion::free;
        p.separate_features = false;
        p.hold_unmoved = false;
        p.lowpass_noise = 0;
        p.risk_selection = false;
        p.impulse_removal = false;
        p.untangle = false;
        return p;
    }
};

/// Result of smooth_feature_bilateral().
struct FeatureBilateralResult {
    Status status = Status::ok;  ///< ok, or cancelled (mesh untouched)
    SharpFeatures features;      ///< the features used (empty when params.features is false)
    std::size_t vertices = 0, faces = 0;
    std::size_t feature_vertices = 0;  ///< vertices on sharp edges moved by filters 1–2
    /// Vertices held in place (FeatureBilateralParams::hold_unmoved): corners of anchored
    /// faces, and after impulse removal the vertices it took as unmoved.
    std::size_t held_vertices = 0;
    std::size_t degenerate_faces = 0;  ///< faces of zero area in the input
    /// "spikes" (impulse_removal), "untangle" (untangle), "topology", "coplanar creases"
    /// (features and SharpFeatureParams::coplanar_creases),
    /// "impulses" (impulse_removal), "noise level of the input" (when vertices were put back),
    /// "noise level" (when estimated), "low-pass" (when a step runs), "features",
    /// "edge smoothing", "face smoothing", "edge straightening" (EdgeVertexMotion::straighten
    /// with sharp edges found); with risk_selection also "risk: perturbed run" (the whole second
    /// run and its bookkeeping), inside it "risk: perturbed <stage>" for each of that run's stages
    /// (not to be added again), and "risk: Taubin sweep" (with the kept Taubin result, if any)
    std::vector<StageTiming> timings;
    /// Faces repeating an earlier face (same corners, same cyclic order): smoothed as one.
    std::size_t duplicate_faces = 0;
    /// The noise level estimated on the input (estimate_noise_level, model units), after
    /// impulse removal when vertices were put back (`input_noise` is the input's then);
    /// status ok and all figures 0 when d and face_iterations were both given.
    NoiseLevel noise{};
    bool noise_estimated = false;  ///< whether `noise` was estimated (d or face_iterations unset)
    Scalar d = 0;                  ///< the face range scale used
    std::size_t face_iterations = 0;  ///< the face iterations used
    std::size_t normal_iterations = 0;  ///< the filter-3 passes per face iteration used
    /// Whether the strong-noise rule raised the normal passes and the detection's
    /// pre-smoothing (face_iterations unset and estimated σ ≥ 0.47|e|; see "Parameters from
    /// the data").
    bool strong_noise = false;
    /// The detection settings used: params.detection, raised by the strong-noise rule
    /// when it applied (passing them back with d and the iteration counts repeats the filters'
    /// run; when `risk.taubin`, the mesh returned is Taubin's, not that run's).
    SharpFeatureParams detection{};
    /// Taubin steps of the low-pass run before the filters (0 when none ran).
    std::size_t lowpass_iterations = 0;
    /// The noise level after the low-pass (model units; `noise` when no step ran), from
    /// which d and the strong-noise rule were set (the face iterations too when the
    /// automatic low-pass is off; with it they follow `noise`).
    NoiseLevel noise_after_lowpass{};
    /// What the risk selection decided (FeatureBilateralParams::risk_selection).
    struct RiskSelection {
        /// Whether both risks were estimated: false when the option is off, when the noise
        /// was not estimated or is zero, when vertices were held (impulsive noise), and when
        /// the Taubin residual implied a σ more than 10 % above the estimate (30 % where
        /// `noise.relative` ≥ detail::fbs::strong_noise_ratio, detail::fbs::risk_sigma_limit_strong;
        /// `note` says which).
        bool evaluated = false;
        bool taubin = false;                 ///< the mesh holds Taubin's result (else the filters')
        std::size_t taubin_iterations = 0;   ///< Taubin's λ|μ pairs of least risk
        /// The noise level both risks were estimated with (model units): σ² = the Taubin
        /// residual over its degrees of freedom at the least-risk count, a fixed point from `noise`.
        Scalar sigma = 0;
        /// Estimated rms error along the normals of each result, model units (√(risk / m),
        /// m the moved vertices; 0 where the risk estimate is negative).
        Scalar filters_rms = 0, taubin_rms = 0;
        /// When Taubin's result was not chosen by the risks (0 otherwise): the median
        /// angle between neighbouring faces of Taubin's result (radians), and whether it exceeded
        /// detail::fbs::coarse_dihedral · d, which keeps Taubin's result (a mesh too coarse for the
        /// filters) unless `normal_veto`.
        Scalar median_dihedral = 0;
        bool coarse = false;
        /// When the filters were kept and `median_dihedral` exceeds detail::fbs::recheck_dihedral · d:
        /// the filters' rms error estimated again with the detection run on each of
        /// `recheck_probes` probes, and whether Taubin's result was returned for it (Taubin's
        /// risk below detail::fbs::recheck_ratio times that estimate); 0 / false otherwise.
        Scalar filters_rms_recheck = 0;
        std::size_t recheck_probes = 0;
        bool recheck = false;
        /// When the heights (risk ratio) or the coarseness chose Taubin (0 otherwise): Taubin's mean
        /// squared face-normal error minus the filters', estimated (rad² per face), the estimate
        /// over its standard error, and whether it kept the filters' result (above
        /// detail::fbs::normal_veto_min at more than normal_veto_z standard errors: a faceted shape;
        /// not where `noise.relative` ≥ detail::fbs::strong_noise_ratio and the filters' height
        /// risk reads zero or below, `filters_rms` 0).
        Scalar normal_difference = 0, normal_z = 0;
        bool normal_veto = false;
        std::string note;                    ///< why it was not evaluated, empty otherwise
    } risk{};
    /// Whether the input's noise read as impulsive (remove_impulses' gate passed;
    /// FeatureBilateralParams::impulse_removal), and how many vertices were put back.
    bool impulsive_noise = false;
    std::size_t impulse_vertices = 0;
    /// The noise read as impulsive but too many vertices were flagged (ImpulseParams::max_fraction):
    /// nothing was put back.
    bool impulses_dense = false;
    /// The input's noise level: `noise` when no vertex was put back (0 when the noise was not
    /// estimated); else the repaired mesh's, with `sigma` = √(its σ² + the mean squared move of
    /// the repair over the vertices), `mean_edge_length` the input's and `relative` = sigma over
    /// the repaired mesh's clean |e| (the impulses' own rms: a median of local fits reads the
    /// unmoved majority).
    NoiseLevel input_noise{};
    /// The untangling stage (FeatureBilateralParams::untangle): its tangential-noise reading, the
    /// faces found folded over and the vertices moved (all 0 when it is off).
    UntangleReport untangle{};
    /// Spikes put back before everything else (with `impulse_removal`): a few vertices far off the
    /// surface (mesh/impulses.hpp, SpikeConstants), which the impulse removal's gate does not see.
    std::size_t spike_vertices = 0;
};

namespace detail::fbs {

inline void check_mesh(const char* fn, const IndexedMesh& m) {
    const std::string f = fn;
    if (m.faces.empty()) throw invalid_input(f + ": the mesh has no faces; pass a non-empty triangle mesh");
    if (m.faces.size() >= (std::size_t{1} << 32))
        throw invalid_input(f + ": more than 2^32 - 1 faces are not supported; split the mesh");
    detail::check_mesh_values(m, fn);
}

inline void check_positive(const std::string& fn, const char* name, Scalar x) {
    if (!(x > 0) || !std::isfinite(x))
        throw invalid_input(fn + ": " + name + " = " + std::to_string(x) + " must be a positive finite number");
}
inline void check_unit(const std::string& fn, const char* name, Scalar x) {
    check_fraction(fn + ": ", name, x);
}
inline void check_count(const std::string& fn, const char* name, std::size_t n) {
    if (n > 10000) throw invalid_input(fn + ": " + name + " = " + std::to_string(n) + " must be at most 10000");
}

inline void check_detection(const std::string& fn, const SharpFeatureParams& p) {
    check_positive(fn, "voting_cube", p.voting_cube);
    check_unit(fn, "edge_threshold", p.edge_threshold);
    check_unit(fn, "direction_threshold", p.direction_threshold);
    check_positive(fn, "prefilter_scale", p.prefilter_scale);
    check_positive(fn, "presmooth_range", p.presmooth_range);
    check_positive(fn, "presmooth_vertex_scale", p.presmooth_vertex_scale);
    check_count(fn, "prefilter_iterations", p.prefilter_iterations);
    check_count(fn, "presmooth_iterations", p.presmooth_iterations);
}

inline Scalar checked_mean_edge(const char* fn, const std::vector<Vec3>& V, const MeshTopology& topo) {
    const Scalar L = detail::mean_edge_length(V, topo, /*self_edges=*/false);
    if (!(L > 0) || !std::isfinite(L))
        throw invalid_input(std::string(fn) + ": every edge has zero length; the mesh has no extent to smooth");
    return L;
}

inline std::vector<unsigned char> used_vertices(const IndexedMesh& m) {
    std::vector<unsigned char> used(m.vertices.size(), 0);
    for (const Face& f : m.faces)
        for (Index v : f) used[v] = 1;
    return used;
}

/// The detection shared by both public functions.
inline FeatureData run_detection(const IndexedMesh& m, const MeshTopology& topo, Scalar L,
                                 const std::vector<unsigned char>& has_face, const SharpFeatureParams& p,
                                 Progress& progress, Workspace& ws, const CoplanarCreases* coplanar = nullptr) {
    FilterSettings pre;
    pre.c = p.prefilter_scale;
    pre.d = p.presmooth_range;
    pre.normal_iterations = std::max<std::size_t>(p.prefilter_iterations, 1);
    pre.vertex_c = p.presmooth_vertex_scale;
    FeatureData fd = detect_features_presmoothed(m.vertices, m.faces, topo, L, p, pre, p.presmooth_iterations,
                                                 has_face, progress, ws);
    if (coplanar) apply_coplanar(fd, *coplanar, topo);
    return fd;
}

/// The coplanar-crease stage on the mesh as given (before any smoothing), when enabled;
/// its own progress stage.
inline std::optional<CoplanarCreases> run_coplanar(const IndexedMesh& m, const MeshTopology& topo, Scalar L,
                                                   const SharpFeatureParams& p, Progress& progress, double from,
                                                   double to) {
    if (!p.coplanar_creases) return std::nullopt;
    progress.stage("coplanar creases", from, to);
    return coplanar_creases(m.vertices, m.faces, topo, L, crease_cosine(p.edge_threshold), progress, 0.0, 1.0);
}

/// The face filter's range scale and iteration count set from the noise level
/// r = σ/|e| (σ from estimate_noise_level, |e| the input's mean edge length) when the
/// caller leaves them unset; see "Parameters from the data" in the file comment.
struct DataScales {
    Scalar d;
    std::size_t face_iterations;
};
/// Strong noise (r ≥ 0.47, about 0.7|e| of Gaussian noise and above; see "Parameters from
/// the data"): at least 20 filter-3 passes per face iteration, and the detection's
/// pre-smoothing with at least 6 passes and a normal filter of c = 3.
inline constexpr Scalar strong_noise_ratio = 0.47;
/// Whether a mesh the impulse removal repaired still carries Gaussian noise on its unmoved
/// vertices, so that holding them would keep it: its quadric fits read 0.3|e| or more, its
/// umbrella differences read σ_d ≥ 0.1|e|, or σ_d > 0 and the quadric fits read less than
/// 1.35 σ_d. Independent noise reads alike at both scales, a shape's own detail more over
/// the quadrics' two rings (armadillo + 10 % impulsive, repaired: 1.64; the same plus
/// 0.03-0.1|e| Gaussian on the shark, bunny00 and bun_zipper: 1.10-1.27). σ_d is 0 (not
/// read) when an exact majority makes the differences heavy-tailed (clean shapes with
/// impulses: held) and when the quadric fits read 0.3|e| or more (not computed). Measured in
/// docs/methods/feature_bilateral.md ("Impulses on top of Gaussian noise").
inline bool impulse_gaussian_after_repair(const NoiseLevel& n) {
    const Scalar d = n.difference_sigma, L = n.mean_edge_length;
    // From 0.3|e| the quadric reading alone (the differences are not computed there): 10 % ×
    // 3|e| plus 0.3|e| on bunny.off, 25.0° held, 12.7° not.
    return n.quadric_sigma >= Scalar(0.3) * L || d >= Scalar(0.1) * L || (d > 0 && n.quadric_sigma < Scalar(1.35) * d);
}
inline void raise_for_strong_noise(std::size_t& normal_iterations, SharpFeatureParams& detection) {
    normal_iterations = std::max<std::size_t>(normal_iterations, 20);
    detection.presmooth_iterations = std::max<std::size_t>(detection.presmooth_iterations, 6);
    detection.prefilter_scale = std::max<Scalar>(detection.prefilter_scale, 3);
}

/// Filter-3 passes per face iteration when normal_iterations is unset and no noise was
/// estimated: 10 (measured on the Block).
inline constexpr std::size_t default_normal_iterations = 10;
/// ... and from the input's estimated noise r = σ/|e|: 3 up to r = 0.15, 10 from r = 0.2
/// (where the low-pass starts), rounded linearly between. Ten passes flatten curved detail
/// under light noise (Twelve at 0.1|e| 5.8° → 3.5°, fertility 7.1° → 5.9°, clean fertility
/// 4.6° → 3.6°) where the Block's flat faces lose little (2.2° → 2.6°); measured in
/// docs/methods/feature_bilateral.md ("Normal passes under light noise").
inline std::size_t normal_iterations_from_noise(Scalar r) {
    const Scalar t = std::clamp<Scalar>((r - Scalar(0.15)) / Scalar(0.05), 0, 1);
    return static_cast<std::size_t>(std::lround(3 + 7 * t));
}

/// Most Taubin steps an unset lowpass_iterations runs.
inline constexpr std::size_t max_lowpass_steps = 20;

/// The low-pass before the filters (see "Strong noise: a low-pass first"), called when at
/// least one step is to run: `given` Taubin steps, or (unset) steps until the noise
/// estimate `noise` (updated after each step) is at most target·|e| with |e| the
/// low-passed mesh's mean edge length, at most max_lowpass_steps. Rim vertices move along
/// their normal only; those of non-manifold edges stay fixed. Returns the steps run;
/// `noise` then holds the estimate after the last (unchanged when `given`: the estimate is
/// not repeated).
inline std::size_t lowpass(std::vector<Vec3>& V, const std::vector<Face>& F, const MeshTopology& topo,
                           std::optional<std::size_t> given, Scalar target, NoiseLevel& noise,
                           const RunControl& control, Progress& progress,
                           const std::vector<unsigned char>* hold = nullptr) {
    const std::size_t steps = given ? *given : max_lowpass_steps;
    std::vector<std::uint8_t> movable(V.size(), 1);
    if (hold && !hold->empty())
        for (std::size_t v = 0; v < V.size(); ++v) movable[v] = !(*hold)[v];
    // Rim vertices (boundary edges only, none non-manifold) move too, but only along their
    // normal: their umbrella points into the surface, and moving along it would pull hole
    // rims and open borders inward; fixed, they kept their noise (CGAL's elephant-with-holes,
    // half its vertices on 106 rims, at 0.5|e|: 23.3° fixed, 20.8° moving along the normal).
    std::vector<std::uint8_t> rim_flag(V.size(), 0);  // 1 rim, 2 non-manifold or self edge (fixed)
    for (std::size_t e = 0; e < topo.num_edges(); ++e) {
        const std::size_t nf = topo.edge_faces(e).size();
        if (nf == 2) continue;
        const auto& ab = topo.edges()[e];
        const bool rim_edge = nf == 1 && ab[0] != ab[1];  // a self edge (repeated index) is no rim
        for (Index v : ab) {
            movable[v] = 0;
            rim_flag[v] = std::max<std::uint8_t>(rim_flag[v], rim_edge ? 1 : 2);
        }
    }
    std::vector<Index> rim;
    for (std::size_t v = 0; v < V.size(); ++v)
        if (rim_flag[v] == 1 && !(hold && !hold->empty() && (*hold)[v])) rim.push_back(static_cast<Index>(v));
    std::vector<Vec3> rim_next(rim.size());
    auto rim_step = [&](Scalar factor) {
        parallel_for(0, rim.size(), [&](std::size_t i) {
            const Index v = rim[i];
            Vec3 n = Vec3::Zero();  // area-weighted normal
            for (Index f : topo.vertex_faces(v))
                n += (V[F[f][1]] - V[F[f][0]]).cross(V[F[f][2]] - V[F[f][0]]);
            const Scalar len = n.norm();
            rim_next[i] = len > 0 ? V[v] + factor * n.dot(detail::umbrella(V, topo, v)) / (len * len) * n : V[v];
        }, 1024);
        for (std::size_t i = 0; i < rim.size(); ++i) V[rim[i]] = rim_next[i];
    };
    // The Taubin steps and the estimates check for cancellation; only this loop reports.
    const RunControl quiet_control{{}, control.stop};
    Progress quiet(quiet_control);
    const TaubinParams one{.iterations = 1};
    std::size_t done = 0;
    while (done < steps) {
        detail::taubin_smooth(V, topo, movable, one, quiet);
        rim_step(one.lambda);
        rim_step(one.mu);
        ++done;
        progress.update(static_cast<double>(done) / static_cast<double>(steps));
        if (given) continue;
        noise = detail::noise::estimate(V, F, topo, 2, quiet, false);  // the stopping rule was set on the quadric estimate
        if (noise.sigma <= target * noise.mean_edge_length) break;  // |e| as the filters will take it
    }
    return done;
}

inline DataScales scales_from_noise(Scalar r) {
    const Scalar over = std::max<Scalar>(r - Scalar(0.38), 0);
    // Light noise: fewer face iterations (1 below 0.025, 2 from 0.075, 3 from 0.125), so
    // that a clean or nearly clean mesh keeps its detail.
    const std::size_t iterations =
        r < Scalar(0.15) ? std::clamp<std::size_t>(static_cast<std::size_t>(std::lround(std::max<Scalar>(r, 0) / Scalar(0.05))), 1, 3)
                         : std::min<std::size_t>(8, 3 + static_cast<std::size_t>(std::lround(20 * over)));
    return {std::max<Scalar>(0.14, Scalar(0.5) * (r - Scalar(0.05))), iterations};
}

/// Face iterations after the automatic low-pass, from r0 = σ/|e| of the input (before
/// the low-pass; |e| the clean edge length, NoiseLevel::relative): clamp(round(1 + 7·r0),
/// 1, 8). The low-pass brings every strong noise to about 0.2|e|, so the mapping above on
/// the noise after it gave 3 iterations at every level; the noise the low-pass leaves is
/// smoother the stronger the input's, and the face filters need more iterations to remove
/// it (Block at 0.7|e|: 3 → 6 iterations, 9.5° → 8.4°). Chosen on the Block, SharpSphere,
/// Twelve and fertility at 0.1-0.8|e|; measured in docs/methods/feature_bilateral.md
/// ("Face iterations from the input's noise").
inline std::size_t face_iterations_after_lowpass(Scalar r0) {
    const Scalar f = std::round(1 + 7 * std::max<Scalar>(r0, 0));
    return static_cast<std::size_t>(std::clamp<Scalar>(f, 1, 8));
}

inline SharpFeatures to_public(FeatureData&& fd, Scalar L) {
    return {std::move(fd.strength), std::move(fd.eigenvalues), std::move(fd.eigenvectors),
            std::move(fd.sharp_edges), fd.candidate_vertices, L, fd.anchored_faces, fd.coplanar_sharp_edges,
            fd.straight_sharp_edges};
}

/// The mesh with vertices and faces renumbered along a Morton curve (ties by index), so
/// that the cube neighbourhoods read nearby memory (about 30 % faster on a 147K-face
/// mesh in scan-like order). `order[v]` is the new index of input vertex v.
struct SpatialOrder {
    IndexedMesh mesh;
    std::vector<Index> order;
    /// The copy's power-of-two rescaling (any magnitude works; see core/frame.hpp).
    ScaleFrame frame;
};

inline SpatialOrder spatial_order(const IndexedMesh& m) {
    const std::size_t nv = m.vertices.size(), nf = m.faces.size();
    SpatialOrder out;
    out.frame = scale_frame(m.vertices);
    std::vector<Vec3> local = m.vertices;
    out.frame.to_local(local);
    const MortonBox box(local);
    const std::vector<Index> vk = morton_order(nv, box, [&](Index v) { return local[v]; });
    const std::vector<Index> fk = morton_order(nf, box, [&](Index f) {
        const Face& t = m.faces[f];
        return Vec3((local[t[0]] + local[t[1]] + local[t[2]]) / 3);
    });
    out.order.resize(nv);
    out.mesh.vertices.resize(nv);
    out.mesh.faces.resize(nf);
    for (std::size_t k = 0; k < nv; ++k) {
        out.order[vk[k]] = k;
        out.mesh.vertices[k] = local[vk[k]];
    }
    for (std::size_t k = 0; k < nf; ++k) {
        const Face& t = m.faces[fk[k]];
        out.mesh.faces[k] = {out.order[t[0]], out.order[t[1]], out.order[t[2]]};
    }
    return out;
}

/// Removes the faces that repeat an earlier face (the same corners in the same cyclic
/// order), keeping the first of each, and returns how many went. A repeated face adds
/// no geometry, but every copy would sit in every neighbourhood of the others: 20,000
/// copies of one triangle (a 160 KB file) made 4·10^8 neighbour entries.
inline std::size_t drop_duplicate_faces(std::vector<Face>& faces) {
    const std::size_t nf = faces.size();
    std::vector<std::pair<Face, Index>> key(nf);
    parallel_for(0, nf, [&](std::size_t f) {
        Face t = faces[f];
        std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
        key[f] = {t, f};
    }, 4096);
    sort_maybe_parallel(key);  // unique (face, index) pairs: one result
    std::vector<unsigned char> repeat(nf, 0);
    std::size_t removed = 0;
    for (std::size_t k = 1; k < nf; ++k)
        if (key[k].first == key[k - 1].first) {
            repeat[key[k].second] = 1;
            ++removed;
        }
    if (removed == 0) return 0;
    std::size_t out = 0;
    for (std::size_t f = 0; f < nf; ++f)
        if (!repeat[f]) faces[out++] = faces[f];
    faces.resize(out);
    return removed;
}

/// Edges (vertex pairs) renumbered through `map`, each as (a < b), the list sorted.
inline void renumber_edges(std::vector<std::array<Index, 2>>& edges, const std::vector<Index>& map) {
    for (auto& e : edges) {
        e = {map[e[0]], map[e[1]]};
        if (e[0] > e[1]) std::swap(e[0], e[1]);
    }
    std::sort(edges.begin(), edges.end());
}

/// Features computed on the reordered mesh, renumbered back to the input's vertices.
inline void restore_order(SharpFeatures& f, const std::vector<Index>& order) {
    if (f.edge_strength.empty()) return;
    auto back = [&](auto& a) {
        auto copy = a;
        for (std::size_t v = 0; v < order.size(); ++v) a[v] = copy[order[v]];
    };
    back(f.edge_strength);
    back(f.eigenvalues);
    back(f.eigenvectors);
    std::vector<Index> inverse(order.size());
    for (std::size_t v = 0; v < order.size(); ++v) inverse[order[v]] = v;
    renumber_edges(f.sharp_edges, inverse);
}

}  // namespace detail::fbs

/// @brief Finds sharp edges with the normal voting tensor (Sun et al. 2002), as in
/// Shimizu, Date, Kanai, Kishinami's feature-aware smoothing (§2.2); see the file
/// comment for the edge strength and the measured changes for heavy noise.
/// @tparam M a type modelling TriangleMesh
/// @param mesh   the mesh (not modified); units are the model's
/// @param params voting cube side (mean edge lengths), thresholds, noise handling, control
/// @return per-vertex edge strength s_i = v2/v1, normalised eigenvalues, eigenvectors,
///         and the sharp edges as vertex pairs. Status::ok: complete.
///         Status::cancelled: features empty.
/// @pre the mesh has at least one face and finite coordinates
/// @throws invalid_input on an empty mesh, NaN/Inf coordinates, a face index out of
///         range, all-zero edge lengths, or parameters out of range (scales not
///         positive and finite, thresholds outside [0, 1], more than 10000 passes).
template <TriangleMesh M>
[[nodiscard]] SharpFeatureResult detect_sharp_features(const M& mesh, const SharpFeatureParams& params = {}) {
    constexpr const char* fn = "kintsugi::detect_sharp_features";
    detail::fbs::check_detection(fn, params);
    detail::fbs::SpatialOrder so = [&] {
        const IndexedMesh input = kintsugi::to_indexed_mesh(mesh);
        detail::fbs::check_mesh(fn, input);
        return detail::fbs::spatial_order(input);
    }();
    detail::fbs::drop_duplicate_faces(so.mesh.faces);
    const IndexedMesh& m = so.mesh;
    SharpFeatureResult result;
    detail::Progress progress(params.control);
    try {
        progress.stage("topology", 0.0, 0.05);
        const MeshTopology topo(m.vertices.size(), m.faces);
        const Scalar L = detail::fbs::checked_mean_edge(fn, m.vertices, topo);
        const auto coplanar = detail::fbs::run_coplanar(m, topo, L, params, progress, 0.05, 0.1);
        progress.stage("features", 0.1, 1.0);
        detail::fbs::Workspace ws;
        auto fd = detail::fbs::run_detection(m, topo, L, detail::fbs::used_vertices(m), params, progress, ws,
                                             coplanar ? &*coplanar : nullptr);
        result.features = detail::fbs::to_public(std::move(fd), so.frame.to_world(L));
        detail::fbs::restore_order(result.features, so.order);
        result.timings = progress.finish();
    } catch (const detail::cancelled_exception&) {
        result = {};
        result.status = Status::cancelled;
    }
    return result;
}

namespace detail::fbs {
template <MutableTriangleMesh M>
FeatureBilateralResult select_by_risk(M& mesh, const FeatureBilateralParams& params);

/// The sharp edges `given` (input vertex indices) in the internal vertex order, in place of a
/// detection (select_by_risk's perturbed run: the features of the first run).
inline FeatureData given_features(const std::vector<std::array<Index, 2>>& given, const std::vector<Index>& order) {
    FeatureData fd;
    fd.sharp_edges = given;
    renumber_edges(fd.sharp_edges, order);
    return fd;
}

/// What select_by_risk's perturbed run takes over from the first run instead of computing it
/// again: the vertex order, the faces (duplicates dropped) and the frame, the topology, the
/// buffers, and the mean edge length after the low-pass. Filters 3 and 4 keep the first run's
/// neighbour sets of the face smoothing (filter 3 those of its first iteration, as in the first
/// run; filter 4 those of each iteration): like the sharp edges, discrete choices the divergence
/// (a derivative) must not see change. With the sets kept the perturbed run's face filters
/// search no neighbourhood (filters 1-2 still do, over the few sharp edges): 0.5-0.6 s instead
/// of 0.9 s at 590K faces, for 50-80 bytes per vertex and face iteration (12-19 faces each;
/// kept only when the selection will compare: the noise estimated, no vertex held).
struct RunReuse {
    bool filled = false;  ///< set by the first run; the second run then reads it
    SpatialOrder so;
    MeshTopology topo;
    Workspace ws;
    Scalar L = 0;
    std::vector<Neighbourhoods> vertex_sets;  ///< filter 4's sets of each face iteration
};

/// Why select_by_risk cannot compare the two results of a run, or "" when it can: its
/// estimates need the noise estimated, non-zero, and no vertex held (held vertices mean
/// impulsive noise or exact planes, not the Gaussian-like noise the estimates assume).
inline std::string risk_skip_reason(const FeatureBilateralResult& r) {
    if (!r.noise_estimated) return "the noise was not estimated (d and face_iterations given)";
    if (!(r.noise.sigma > 0)) return "the estimated noise is zero";
    if (r.held_vertices > 0) return "vertices were held (anchored faces: impulsive noise or exact planes)";
    if (r.impulse_vertices > 0)
        return "impulsive noise: vertices were put back (the estimates assume Gaussian-like noise)";
    return {};
}

/// The parameters of select_by_risk's perturbed run: `params` with the values the first run
/// (`first`) chose, so that it runs the same filters without estimating anything.
inline FeatureBilateralParams repeat_params(const FeatureBilateralParams& params, const FeatureBilateralResult& first) {
    FeatureBilateralParams p = params;
    p.d = first.d;
    p.face_iterations = first.face_iterations;
    p.normal_iterations = first.normal_iterations;
    p.lowpass_iterations = first.lowpass_iterations;
    p.detection = first.detection;
    return p;
}

/// smooth_feature_bilateral without the risk selection; with `given_edges`, those sharp edges
/// (input indices) instead of the coplanar stage and the detection. With `reuse` (unfilled),
/// the run leaves its state there; with `reuse` filled, it starts from that state and reads only
/// the mesh's positions (in the first run's vertex order; its faces are taken as the first
/// run's: select_by_risk's perturbed input).
template <MutableTriangleMesh M>
FeatureBilateralResult smooth_run(M& mesh, const FeatureBilateralParams& params,
                                  const std::vector<std::array<Index, 2>>* given_edges, RunReuse* reuse = nullptr);
}  // namespace detail::fbs

/// @brief Feature-aware bilateral smoothing (Shimizu, Date, Kanai, Kishinami): sharp
/// edges from the normal voting tensor, then the four bilateral filters of the paper's
/// Table 1 (edge directions, edge vertices, face normals, vertices). See the file
/// comment for the exact filters and the measured defaults.
/// @tparam M a type modelling MutableTriangleMesh
/// @param mesh   the mesh, smoothed in place (positions only; connectivity unchanged)
/// @param params a, b, c, d (dimensionless multiples of the mean edge length |e|),
///               edge threshold, voting cube (in |e|), iteration counts, features, control
/// @return features used, counts, per-stage timings, the risk selection's decision.
///         Status::ok: the mesh holds the result. Status::cancelled: the mesh is
///         untouched (all work is on a copy written back at the end).
/// @pre the mesh has at least one face and finite coordinates
/// @throws invalid_input on an empty mesh, NaN/Inf coordinates, a face index out of
///         range, all-zero edge lengths, or parameters out of range (scales not
///         positive and finite, thresholds outside [0, 1], more than 10000 passes).
///         The mesh is then untouched.
template <MutableTriangleMesh M>
FeatureBilateralResult smooth_feature_bilateral(M& mesh, const FeatureBilateralParams& params = {}) {
    constexpr const char* fn = "kintsugi::smooth_feature_bilateral";
    namespace fbs = detail::fbs;
    if (params.risk_selection) {
        fbs::check_count(fn, "risk_taubin_max_iterations", params.risk_taubin_max_iterations);
        if (params.risk_taubin_max_iterations == 0)
            throw invalid_input(std::string(fn) + ": risk_taubin_max_iterations = 0; pass at least 1");
    }
    auto run = [&](auto& m) {
        return params.risk_selection ? fbs::select_by_risk(m, params) : fbs::smooth_run(m, params, nullptr);
    };
    if (!params.untangle && !params.impulse_removal) return run(mesh);
    // The input with its spikes put back and its folded faces unfolded, on a copy (the mesh is
    // written only once the run is done).
    IndexedMesh input = kintsugi::to_indexed_mesh(mesh);
    fbs::check_mesh(fn, input);
    const auto t0 = std::chrono::steady_clock::now();
    UntangleReport untangled;
    std::size_t spikes = 0;
    double spike_seconds = 0;
    {
        const detail::ScaleFrame frame = detail::scale_frame(input.vertices);  // powers of two: exact
        frame.to_local(input.vertices);
        const MeshTopology topo(input.vertices.size(), input.faces);
        if (params.impulse_removal) {
            // Before everything else: a spike inflates the mean edge length every scale rests on,
            // and Taubin's steps (the low-pass, the risk selection) would spread it.
            const auto ts = std::chrono::steady_clock::now();
            const RunControl stop_only{.stop = params.control.stop};  // the stop token; no progress events
            detail::Progress quiet(stop_only);
            try {
                spikes = detail::impulses::put_back_spikes(input.vertices, input.faces, topo, quiet).size();
            } catch (const detail::cancelled_exception&) {
                return detail::cancelled_result<FeatureBilateralResult>();
            }
            spike_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - ts).count();
        }
        if (params.untangle) untangled = detail::untangle::run(input.vertices, input.faces, topo);
        frame.to_world(input.vertices);
    }
    // The copy, the frame and the topology count with the untangling (reported when it runs).
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() - spike_seconds;
    if (params.control.stop.stop_requested()) return detail::cancelled_result<FeatureBilateralResult>();
    FeatureBilateralResult result = run(input);
    result.untangle = untangled;
    result.spike_vertices = spikes;
    if (params.untangle) result.timings.insert(result.timings.begin(), StageTiming{"untangle", seconds});
    if (params.impulse_removal) result.timings.insert(result.timings.begin(), StageTiming{"spikes", spike_seconds});
    if (result.status == Status::ok)
        for (std::size_t v = 0; v < input.vertices.size(); ++v) kintsugi::set_vertex_position(mesh, v, input.vertices[v]);
    return result;
}

namespace detail::fbs {

template <MutableTriangleMesh M>
FeatureBilateralResult smooth_run(M& mesh, const FeatureBilateralParams& params,
                                  const std::vector<std::array<Index, 2>>* given_edges, RunReuse* reuse) {
    constexpr const char* fn = "kintsugi::smooth_feature_bilateral";
    namespace fbs = detail::fbs;
    SharpFeatureParams detection = params.detection;
    fbs::check_positive(fn, "a", params.a);
    fbs::check_positive(fn, "b", params.b);
    fbs::check_positive(fn, "c", params.c);
    if (params.d) fbs::check_positive(fn, "d", *params.d);
    fbs::check_detection(fn, detection);
    fbs::check_count(fn, "edge_iterations", params.edge_iterations);
    if (params.face_iterations) fbs::check_count(fn, "face_iterations", *params.face_iterations);
    if (params.normal_iterations) fbs::check_count(fn, "normal_iterations", *params.normal_iterations);
    fbs::check_count(fn, "vertex_iterations", params.vertex_iterations);
    if (params.lowpass_iterations) fbs::check_count(fn, "lowpass_iterations", *params.lowpass_iterations);
    fbs::check_unit(fn, "lowpass_noise", params.lowpass_noise);
    const bool reused = reuse && reuse->filled;
    fbs::SpatialOrder own_so;
    fbs::SpatialOrder& so = reuse ? reuse->so : own_so;
    if (reused) {  // this run's positions in the first run's order and frame
        const IndexedMesh input = kintsugi::to_indexed_mesh(mesh);
        fbs::check_mesh(fn, input);
        if (input.vertices.size() != so.order.size())
            throw invalid_input(std::string(fn) + ": internal: the reused run has another vertex count");
        for (std::size_t v = 0; v < input.vertices.size(); ++v)
            so.mesh.vertices[so.order[v]] = so.frame.to_local(input.vertices[v]);
    } else {
        so = [&] {
            const IndexedMesh input = kintsugi::to_indexed_mesh(mesh);
            fbs::check_mesh(fn, input);
            return fbs::spatial_order(input);
        }();
    }
    IndexedMesh& m = so.mesh;

    FeatureBilateralResult result;
    result.vertices = m.vertices.size();
    result.faces = m.faces.size();
    if (!reused) {
        fbs::FaceGeometry geo;
        fbs::compute_face_geometry(m.vertices, m.faces, geo);
        for (Scalar a : geo.area) result.degenerate_faces += a == 0;
        result.duplicate_faces = fbs::drop_duplicate_faces(m.faces);
    }
    detail::Progress progress(params.control);
    try {
        progress.stage("topology", 0.0, 0.02);
        MeshTopology own_topo;
        MeshTopology& topo = reuse ? reuse->topo : own_topo;
        if (!reused) topo = MeshTopology(m.vertices.size(), m.faces);
        Scalar L = fbs::checked_mean_edge(fn, m.vertices, topo);
        const std::size_t nv = m.vertices.size();
        const std::vector<unsigned char> has_face = fbs::used_vertices(m);
        std::vector<unsigned char> fixed(nv, 0);
        // On the input, before the low-pass moves the vertices impulsive noise left in place.
        const auto coplanar = params.features && !given_edges
                                  ? fbs::run_coplanar(m, topo, L, detection, progress, 0.02, 0.03)
                                  : std::nullopt;
        // The corners of anchored faces were not moved by the noise: held where they are.
        std::vector<unsigned char> held;
        std::optional<NoiseLevel> repaired_noise;  // after the impulse removal, if it moved vertices
        if (params.hold_unmoved && coplanar && !coplanar->unmoved.empty()) held = coplanar->unmoved;
        const std::vector<unsigned char>* hold = held.empty() ? nullptr : &held;
        if (params.impulse_removal && !reused) {
            progress.stage("impulses", 0.03, 0.035);
            std::vector<unsigned char> labels;
            std::vector<Vec3> before;  // the input's positions, for its noise level, if vertices move
            const ImpulseResult ir =
                detail::impulses::run(m.vertices, m.faces, topo, L, hold, {}, progress, &labels, &before);
            result.impulsive_noise = ir.impulsive;
            result.impulses_dense = ir.dense;
            result.impulse_vertices = ir.moved_vertices;
            if (ir.moved_vertices > 0) {
                L = fbs::checked_mean_edge(fn, m.vertices, topo);
                progress.stage("noise level", 0.035, 0.037);
                repaired_noise = detail::noise::estimate(m.vertices, m.faces, topo, 2, progress);
                // The input's level: the repaired mesh's with the repair's moves added in
                // quadrature (a median of fits reads the unmoved majority of impulsive noise:
                // the shark + 10 % read 0.73 times the rms of the impulses).
                Scalar moved2 = 0;
                for (std::size_t v = 0; v < nv; ++v) moved2 += (m.vertices[v] - before[v]).squaredNorm();
                result.input_noise = *repaired_noise;
                result.input_noise.sigma =
                    std::sqrt(repaired_noise->sigma * repaired_noise->sigma + moved2 / static_cast<Scalar>(nv));
                result.input_noise.mean_edge_length = fbs::checked_mean_edge(fn, before, topo);
                result.input_noise.relative = repaired_noise->clean_edge_length > 0
                                                  ? result.input_noise.sigma / repaired_noise->clean_edge_length
                                                  : 0;
                // The noise moved few vertices: those left in the plane of three neighbours
                // are held, as the corners of anchored faces are (armadillo + 10 % impulsive:
                // 11.3° with the repair alone, 6.4° holding them); not when the repaired mesh
                // reads as Gaussian noise (impulses on top of it: the held vertices would keep
                // it; fbs::impulse_gaussian_after_repair).
                if (params.hold_unmoved && !impulse_gaussian_after_repair(*repaired_noise)) {
                    held.resize(nv, 0);
                    for (std::size_t v = 0; v < nv; ++v) held[v] |= labels[v] == 2;
                    hold = &held;
                }
            }
        }
        if (hold) {
            for (std::size_t v = 0; v < nv; ++v) fixed[v] |= held[v];
            for (unsigned char h : held) result.held_vertices += h;
        }
        if (!params.d || !params.face_iterations) {
            progress.stage("noise level", 0.037, 0.04);
            result.noise = repaired_noise ? *repaired_noise : detail::noise::estimate(m.vertices, m.faces, topo, 2, progress);
            result.noise_estimated = true;
            if (result.impulse_vertices == 0) result.input_noise = result.noise;
        }
        result.noise_after_lowpass = result.noise;
        // σ / |e| of the input with |e| its clean estimate (edges lengthened by the noise
        // taken off), before the low-pass moves anything.
        const Scalar r_input = result.noise.relative;
        if (params.lowpass_iterations ? *params.lowpass_iterations > 0
                                      : result.noise_estimated && params.lowpass_noise > 0 &&
                                            result.noise.sigma > params.lowpass_noise * L) {
            progress.stage("low-pass", 0.04, 0.1);
            result.lowpass_iterations =
                fbs::lowpass(m.vertices, m.faces, topo, params.lowpass_iterations, params.lowpass_noise,
                             result.noise_after_lowpass, params.control, progress, hold);
            if (!reused) L = fbs::checked_mean_edge(fn, m.vertices, topo);
        }
        if (reused) L = reuse->L;  // as the first run's (the scale of filter 3's kept sets)
        else if (reuse) reuse->L = L;
        const Scalar sigma = result.noise_after_lowpass.sigma;
        fbs::DataScales auto_scales = fbs::scales_from_noise(sigma / L);
        // The automatic low-pass on: the iterations follow the input's noise, whether or
        // not the low-pass had to run (see face_iterations_after_lowpass).
        if (!params.lowpass_iterations && params.lowpass_noise > 0)
            auto_scales.face_iterations = fbs::face_iterations_after_lowpass(r_input);
        result.d = params.d ? *params.d : auto_scales.d;
        result.face_iterations = params.face_iterations ? *params.face_iterations : auto_scales.face_iterations;
        result.normal_iterations = params.normal_iterations ? *params.normal_iterations
                                   : result.noise_estimated ? fbs::normal_iterations_from_noise(r_input)
                                                            : fbs::default_normal_iterations;
        result.strong_noise = !params.face_iterations && sigma >= fbs::strong_noise_ratio * L;
        if (result.strong_noise) fbs::raise_for_strong_noise(result.normal_iterations, detection);
        result.detection = detection;
        result.detection.control = {};
        for (NoiseLevel* n : {&result.noise, &result.noise_after_lowpass, &result.input_noise})
            detail::noise::to_world(*n, so.frame);
        const std::size_t face_iterations = result.face_iterations;
        const fbs::FilterSettings fs{params.a, params.b, params.c, result.d, params.edge_iterations,
                                     face_iterations, params.features, result.normal_iterations,
                                     params.vertex_iterations};
        fbs::Barriers barriers;
        fbs::Workspace own_ws;
        fbs::Workspace& ws = reuse ? reuse->ws : own_ws;
        std::vector<std::array<Index, 2>> final_edges;  // straighten: the edges filters 1–2 rerun on
        std::vector<Index> final_vertices;
        if (params.features) {
            progress.stage("features", 0.1, 0.45);
            auto fd = given_edges ? fbs::given_features(*given_edges, so.order)
                                  : fbs::run_detection(m, topo, L, has_face, detection, progress, ws,
                                                       coplanar ? &*coplanar : nullptr);
            std::vector<unsigned char> on_edge(nv, 0);
            for (const auto& e : fd.sharp_edges) on_edge[e[0]] = on_edge[e[1]] = 1;
            std::vector<Index> edge_vertices;
            for (std::size_t v = 0; v < nv; ++v)
                if (on_edge[v] && !(hold && (*hold)[v])) edge_vertices.push_back(v);
            result.feature_vertices = edge_vertices.size();
            if (params.edge_vertex_motion == EdgeVertexMotion::fixed)  // added to the held vertices
                for (std::size_t v = 0; v < nv; ++v) fixed[v] |= on_edge[v];

            progress.stage("edge smoothing", 0.45, 0.5);
            for (std::size_t it = 0; it < params.edge_iterations; ++it) {
                const double n = static_cast<double>(params.edge_iterations);
                fbs::edge_iteration(m.vertices, fd.sharp_edges, edge_vertices, L, fs, progress,
                                    static_cast<double>(it) / n, static_cast<double>(it + 1) / n);
            }
            if (params.edge_vertex_motion == EdgeVertexMotion::straighten) {
                final_edges = fd.sharp_edges;
                final_vertices = edge_vertices;
            }
            if (params.separate_features) {
                barriers.topo = &topo;
                barriers.sharp_edge.assign(topo.num_edges(), 0);
                for (const auto& e : fd.sharp_edges)
                    if (const auto id = topo.find_edge(e[0], e[1])) barriers.sharp_edge[*id] = 1;
                barriers.feature_vertices = edge_vertices;
            }
            result.features = fbs::to_public(std::move(fd), so.frame.to_world(L));
            fbs::restore_order(result.features, so.order);
            if (given_edges) result.features.sharp_edges = *given_edges;  // no strengths to reorder with
        }
        progress.stage("face smoothing", params.features ? 0.5 : 0.1, final_edges.empty() ? 1.0 : 0.98);
        // Filter 4's sets kept for the perturbed run only where select_by_risk will compare.
        const bool keep_vertex_sets = reuse && !reused && fbs::risk_skip_reason(result).empty();
        for (std::size_t it = 0; it < face_iterations; ++it) {
            const double n = static_cast<double>(face_iterations);
            // The perturbed run takes filter 4's sets of the first run's same iteration.
            const bool kept_vertex_sets = reused && it < reuse->vertex_sets.size();
            if (kept_vertex_sets) std::swap(ws.vertex_lists, reuse->vertex_sets[it]);
            fbs::face_iteration(m.vertices, m.faces, fixed, has_face, L, fs, progress, static_cast<double>(it) / n,
                                static_cast<double>(it + 1) / n, ws, &barriers, it > 0 || reused, kept_vertex_sets);
            if (keep_vertex_sets) reuse->vertex_sets.push_back(ws.vertex_lists);
        }
        if (!final_edges.empty()) {
            progress.stage("edge straightening", 0.98, 1.0);
            for (std::size_t it = 0; it < params.edge_iterations; ++it) {
                const double n = static_cast<double>(params.edge_iterations);
                fbs::edge_iteration(m.vertices, final_edges, final_vertices, L, fs, progress,
                                    static_cast<double>(it) / n, static_cast<double>(it + 1) / n);
            }
        }
        result.timings = progress.finish();
    } catch (const detail::cancelled_exception&) {
        FeatureBilateralResult cancelled;
        cancelled.status = Status::cancelled;
        cancelled.vertices = result.vertices;
        cancelled.faces = result.faces;
        return cancelled;
    }
    for (std::size_t v = 0; v < m.vertices.size(); ++v)
        kintsugi::set_vertex_position(mesh, v, so.frame.to_world(m.vertices[so.order[v]]));
    if (reuse) reuse->filled = true;
    return result;
}

/// Taubin's result is returned when its estimated risk is below this fraction of the
/// filters' (see select_by_risk).
inline constexpr Scalar risk_ratio = 0.75;
/// Taubin's result is also returned when the median angle between its neighbouring faces
/// exceeds this multiple of the range scale d, in radians (see select_by_risk). Set between
/// the shapes it must keep for Taubin (CGAL's eight.off, 634 faces, median 15.6-16.4°: filters
/// 24-27° against Taubin's 10-13° at 0.5-0.8|e|; a 24 × 12 torus, 10.9-11.8°) and a 16-sided
/// prism whose facets the filters keep (up to 8.3°; 1.25 × 0.14 rad = 10.0°). Measured in
/// docs/methods/feature_bilateral.md ("Coarse meshes").
inline constexpr Scalar coarse_dihedral = 1.25;

/// Taubin's result is not returned, whatever the height risks, when its mean squared face-normal
/// error is estimated (normal_risk_difference) above the filters' by more than normal_veto_min
/// (rad² per face, about (10°)²) at more than normal_veto_z standard errors. Set on a 16-sided
/// prism with its caps wound against its sides (352 faces; where the height risks chose Taubin,
/// 8.7-16.1° against the filters' 5.5-6.0°: estimated +0.035 to +0.087 at z 2.8-6.4) against
/// bun_zipper_res4 and CGAL's
/// eight.off, where Taubin is better (z at most 0.94 and 0.61). Seeds 11-13, 0.1-0.8|e|;
/// held-out shapes in docs/methods/feature_bilateral.md ("Faceted shapes").
/// Not applied where the input's estimated relative noise (`noise.relative`, before any
/// low-pass; not `strong_noise`) is at least strong_noise_ratio and the filters' height risk
/// reads zero or below (NaN included): the estimate is first order in the noise and rests on the
/// same probe as the filters' divergence, and a non-positive risk (a squared error) says that
/// probe's response is outside the regime both assume (24 × 12 tori of radii 2 and 0.7 and
/// 20 × 10 of 2 and 0.6 at 0.9-1.0|e|: vetoed at z 2.9-3.1, the filters' 25-29° against Taubin's
/// 8-9°). Under lighter noise a veto with such a risk stands (a 12-sided prism at 0.3|e|, z 5.8:
/// 5.5° against 13.7°; test_feature_bilateral). docs/methods/feature_bilateral.md, "Strong
/// noise beyond the table".
inline constexpr Scalar normal_veto_min = 0.03, normal_veto_z = 2.5;

/// Where the filters were chosen and the median angle between Taubin's neighbouring faces
/// exceeds recheck_dihedral · d (radians), the filters' risk is estimated again with the
/// detection run on each probe's input (recheck_max_probes of them, fewer on meshes over 2K
/// vertices: probes × vertices ≤ 2^15), and Taubin's result returned when its risk is below
/// recheck_ratio times that estimate. Set on tori of 30 × 15 and 40 × 20 faces (the filters
/// 14-22° against Taubin's 6-8° at 0.5-0.8|e|; median 1.05-1.2 d; the ratio 0.27-0.48) against
/// consistently oriented prisms of 10-40 sides where the filters are better (0.54 and above;
/// one at 0.42 that the face-normal veto returns to the filters). SharpSphere (median
/// 0.77-0.83 d) reads 0.98-1.83 on its 3 probes; the Block and Twelve are not checked (0.3-0.5 d).
/// docs/methods/feature_bilateral.md ("Detection recheck").
inline constexpr Scalar recheck_dihedral = 0.6, recheck_ratio = 0.5;
inline constexpr std::size_t recheck_max_probes = 16;

/// What normal_risk_difference returns: the estimated mean over the faces, and that mean over
/// its standard error (0 below 4 blocks).
struct NormalRiskDifference {
    Scalar mean = 0, z = 0;
};

/// Monte-Carlo SURE of the mean squared face-normal error of a result A minus that of a result
/// B, from the noisy input alone. |n̂ − n_x|² = 2 − 2 n̂·n_x, and to first order (Stein)
/// E n̂·n_y = n_x·E n̂ + σ² tr(J_n̂ᵀ J_y), n_y the input's face normal; the trace comes from one
/// probe δ of variance p² per vertex: σ²/p² · (n̂(y + δ) − n̂(y))·(n_y(y + δ) − n_y(y)). Per face,
/// with `sigma2_over_probe` = σ²/p²:
///   −2 (n_A − n_B)·n_y + 2 σ²/p² ((Δn_A − Δn_B)·Δn_y).
/// `corner(i, v)` is vertex v's position (input index) in: 0 the input, 1 the input + δ,
/// 2 A, 3 A on the input + δ, 4 B, 5 B on the input + δ. Faces with a degenerate normal in
/// the input, A or B are left out. The standard error: batch means over blocks of faces
/// ordered by `key` of their first corner (a spatial order), as adjacent faces' terms correlate.
template <class Corner>
NormalRiskDifference normal_risk_difference(const std::vector<Face>& faces, const Corner& corner, Scalar sigma2_over_probe,
                                            const std::vector<Index>& key) {
    std::vector<std::pair<Index, Scalar>> terms;  // (key, the face's term)
    terms.reserve(faces.size());
    for (const Face& t : faces) {
        auto normal = [&](int i) { return unit_triangle_normal(corner(i, t[0]), corner(i, t[1]), corner(i, t[2])); };
        const Vec3 ny = normal(0), na = normal(2), nb = normal(4);
        if (ny.squaredNorm() == 0 || na.squaredNorm() == 0 || nb.squaredNorm() == 0) continue;
        const Vec3 dy = normal(1) - ny, da = normal(3) - na, db = normal(5) - nb;
        terms.emplace_back(key[t[0]], -2 * (na - nb).dot(ny) + 2 * sigma2_over_probe * (da - db).dot(dy));
    }
    NormalRiskDifference out;
    if (terms.empty()) return out;
    std::stable_sort(terms.begin(), terms.end(), [](const auto& p, const auto& q) { return p.first < q.first; });
    const std::size_t n = terms.size();
    const std::size_t block = std::clamp<std::size_t>(n / 16, 16, 64);
    std::vector<Scalar> sums;  // the full blocks'
    Scalar total = 0, sum = 0;
    for (std::size_t i = 0; i < n; ++i) {
        total += terms[i].second;
        sum += terms[i].second;
        if ((i + 1) % block == 0) sums.push_back(sum), sum = 0;
    }
    out.mean = total / static_cast<Scalar>(n);
    if (sums.size() < 4) return out;
    Scalar mean = 0, var = 0;
    for (Scalar b : sums) mean += b;
    mean /= static_cast<Scalar>(sums.size());
    for (Scalar b : sums) var += (b - mean) * (b - mean);
    var /= static_cast<Scalar>(sums.size() - 1);
    const Scalar se = std::sqrt(var * static_cast<Scalar>(n) / static_cast<Scalar>(block));  // of the total
    out.z = se > 0 ? total / se : 0;
    return out;
}

/// The selection is skipped when the σ its Taubin residual implies exceeds the estimate by
/// more than this factor; the sweep covers the least-risk counts of every σ up to it.
/// risk_sigma_limit: heavy tails and a shape Taubin removes read high (CAD parts at 0.1|e|:
/// 1.11-1.28, the creases it rounds). risk_sigma_limit_strong, where the input's estimated
/// relative noise (`noise.relative`, before any low-pass; not `strong_noise`) is at least
/// strong_noise_ratio: the quadric fits under-read strong noise (0.78-0.94 of the truth at
/// 0.9-1.2|e|), and Gaussian noise there read up to 1.25 on 23 shapes, seeds 11-13; with 1.1 a
/// 24 × 12 torus and CGAL's eight.off at 0.9-1.2|e| skipped the selection and kept the filters'
/// 22-28° against Taubin's 8-15°. Heavy tails above 0.47 are left to the impulse removal
/// (risk_skip_reason). docs/methods/feature_bilateral.md, "Strong noise beyond the table".
inline constexpr Scalar risk_sigma_limit = 1.1, risk_sigma_limit_strong = 1.3;

/// The run of FeatureBilateralParams::risk_selection ("Risk selection" in the file comment):
/// the filters, their Monte-Carlo SURE from a second run on a perturbed input, Taubin's sweep,
/// and the result of lower estimated risk written to `mesh`. Progress: the filters' run
/// 0-0.4, the perturbed run 0.4-0.8, the sweep 0.8-0.9, the recheck (where it runs) 0.9-1.
template <MutableTriangleMesh M>
FeatureBilateralResult select_by_risk(M& mesh, const FeatureBilateralParams& params) {
    // The two runs, the sweep and the recheck report into [0, 0.4], [0.4, 0.8], [0.8, 0.9] and
    // [0.9, 1] of the whole, throttled together; the whole run's "done" is reported once, before
    // the mesh is written, so that a cancel there leaves it untouched.
    double last = -1;
    FeatureBilateralParams inner = params;
    inner.risk_selection = false;
    inner.control = part_control(params.control, 0.0, 0.4, last);
    const IndexedMesh input = kintsugi::to_indexed_mesh(mesh);
    IndexedMesh filtered = input;
    RunReuse reuse;  // the first run's state, for the perturbed run
    FeatureBilateralResult result = smooth_run(filtered, inner, nullptr, &reuse);  // validates the input
    if (result.status == Status::cancelled) return result;
    auto report_done = [&] {
        if (params.control.stop.stop_requested()) throw cancelled_exception{};
        if (params.control.progress && !params.control.progress(ProgressEvent{"done", 1.0}))
            throw cancelled_exception{};
    };
    const std::vector<Vec3>* chosen = &filtered.vertices;  // world coordinates
    IndexedMesh taubin;  // Taubin's result, in world coordinates when kept
    try {
        auto skip = [&](std::string why) { result.risk.note = std::move(why); };
        if (std::string why = risk_skip_reason(result); !why.empty()) {
            skip(std::move(why));
        } else {
            const auto t0 = std::chrono::steady_clock::now();
            // In the first run's vertex order and power-of-two frame (exact: any magnitude), on its
            // topology (duplicate faces dropped).
            const SpatialOrder& so = reuse.so;
            const ScaleFrame& frame = so.frame;
            const MeshTopology& topo = reuse.topo;
            const std::size_t nv = input.vertices.size();
            std::vector<Vec3> y(nv), f(nv);
            for (std::size_t v = 0; v < nv; ++v) {
                y[so.order[v]] = frame.to_local(input.vertices[v]);
                f[so.order[v]] = frame.to_local(filtered.vertices[v]);
            }
            // The quadric fits' estimate: like Taubin's residual it reads a shape's detail as
            // noise, so the consistency test below compares like with like (the lower umbrella-
            // difference estimate made the elephant at 0.1|e| skip the selection: 8.0° → 10.7°).
            const Scalar sigma = frame.to_local(result.noise.quadric_sigma);
            const std::vector<Vec3> normals = kintsugi::vertex_normals(IndexedMesh{f, so.mesh.faces, {}});
            const std::vector<std::uint8_t> counted = risk_counted(topo, normals);  // as the sweep's

            // The filters' divergence along the normals: one run, with the values and the sharp
            // edges the first chose, on the input moved by eps·σ·z_v along n_v (z_v = ±1, fixed seed).
            constexpr Scalar eps = 0.1;
            FeatureBilateralParams fixed = repeat_params(inner, result);
            fixed.control = part_control(params.control, 0.4, 0.8, last);
            std::vector<Scalar> z(nv, 0);  // by input index: the draws do not depend on the order
            std::uint64_t state = 0xD1B54A32D192ED03ull;
            // A probe's input at input vertex v with draw zv, local coordinates; probe_input: the
            // first probe's (z[v] drawn first).
            auto probe_at = [&](std::size_t v, Scalar zv) -> Vec3 {
                const Index k = so.order[v];
                return y[k] + eps * sigma * zv * normals[k];
            };
            auto probe_input = [&](std::size_t v) { return probe_at(v, z[v]); };
            // A probe: its draws `zs` (one per input vertex, 0 where not counted) and its input
            // written into `out` (world coordinates).
            auto draw_probe = [&](std::vector<Scalar>& zs, IndexedMesh& out) {
                for (std::size_t v = 0; v < nv; ++v) {
                    const int draw = rademacher(state);
                    zs[v] = counted[so.order[v]] ? draw : 0;
                    out.vertices[v] = frame.to_world(probe_at(v, zs[v]));
                }
            };
            // Adds to `acc` a probe's divergence term Σ σ z_v n_v·(run_v − f_v) / eps over the
            // counted vertices, `run` the filters' result on that probe's input.
            auto add_divergence = [&](Scalar& acc, const std::vector<Scalar>& zs, const IndexedMesh& run) {
                for (std::size_t v = 0; v < nv; ++v) {
                    const Index k = so.order[v];
                    if (counted[k]) acc += sigma * zs[v] * normals[k].dot(frame.to_local(run.vertices[v]) - f[k]) / eps;
                }
            };
            IndexedMesh perturbed{input.vertices, input.faces, {}};
            draw_probe(z, perturbed);
            // The first run's sharp edges, not a new detection: the divergence is a derivative,
            // which the detection's discrete choices do not have (a flipped edge would count).
            const FeatureBilateralResult second = smooth_run(perturbed, fixed, &result.features.sharp_edges, &reuse);
            if (second.status == Status::cancelled) throw cancelled_exception{};
            reuse.ws = {};  // the buffers, before the sweep allocates its own
            reuse.vertex_sets = {};
            Scalar residual = 0, divergence = 0;
            std::size_t m = 0;
            for (std::size_t v = 0; v < nv; ++v) {
                const Index k = so.order[v];
                if (!counted[k]) continue;
                ++m;
                const Scalar h = normals[k].dot(f[k] - y[k]);
                residual += h * h;
            }
            add_divergence(divergence, z, perturbed);
            const auto t1 = std::chrono::steady_clock::now();
            result.timings.push_back({"risk: perturbed run", std::chrono::duration<double>(t1 - t0).count()});
            for (const StageTiming& t : second.timings) result.timings.push_back({"risk: perturbed " + t.stage, t.seconds});

            const RunControl sweep_control = part_control(params.control, 0.8, 0.9, last);
            Progress progress(sweep_control);
            progress.stage("risk: Taubin sweep", 0.0, 1.0);
            // The probes drawn in the input's vertex order (so.order: input index → internal).
            const bool strong = result.noise.relative >= strong_noise_ratio;  // the input's estimate
            const Scalar limit = strong ? risk_sigma_limit_strong : risk_sigma_limit;
            const TaubinRiskCurves curves = taubin_risk_curves(y, topo, normals, limit * sigma,
                                                               params.risk_taubin_max_iterations, TaubinParams{}, progress,
                                                               so.order);
            // σ from the Taubin residual itself: E res_k = σ²(m − 2 tr S_k + tr S_kᵀS_k) + bias, so
            // σ² = res_k / (m − 2 tr S_k + tr S_kᵀS_k) at the count of least risk for σ, to a fixed
            // point from the quadric estimate. That estimate reads detail as noise under light
            // noise (elephant at 0.1|e|: 1.9× the true σ) and under-reads strong noise (about 7 %
            // at 0.7-0.8|e|, 6-22 % at 0.9-1.2|e|); the count follows σ closely.
            const Scalar ms = static_cast<Scalar>(std::max<std::size_t>(m, 1));
            auto implied = [&](std::size_t k) {
                const Scalar dof = ms - 2 * curves.trace[k] + curves.trace_sq[k];
                return dof > 0 ? std::sqrt(curves.residual[k] / dof) : Scalar(0);
            };
            Scalar s = sigma;
            std::size_t k = least_risk_steps(curves, s);
            for (int it = 0; it < 20; ++it) {
                const Scalar next = implied(k);
                if (!(next > 0)) break;
                const std::size_t k2 = least_risk_steps(curves, next);
                s = next;
                if (k2 == k) break;
                k = k2;
            }
            if (const Scalar sk = implied(k); sk > 0) s = sk;  // not converged in 20: σ of the last count
            const Scalar risk_taubin = taubin_risk(curves, k, s);
            const Scalar risk_filters = stein_risk(residual, m, s, divergence / (sigma * sigma));
            result.risk.taubin_iterations = k;
            result.risk.sigma = frame.to_world(s);
            result.risk.filters_rms = frame.to_world(std::sqrt(std::max<Scalar>(0, risk_filters) / ms));
            result.risk.taubin_rms = frame.to_world(std::sqrt(std::max<Scalar>(0, risk_taubin) / ms));
            if (!(s <= limit * sigma)) {
                skip("the Taubin residual implies a noise of " + std::to_string(s / sigma) +
                     " times the estimate, above " + std::to_string(limit) +
                     " (heavy-tailed noise, or shape Taubin removes; the estimates assume Gaussian-like noise)");
            } else {
                result.risk.evaluated = true;
                // Taubin only when its risk is clearly lower: position error favours it on faceted
                // shapes whose normals the filters get better (SharpSphere at 0.7|e|: ratio 0.88,
                // 11.1° against 14.3°); organic shapes read 0.23-0.62 (fertility; chosen on the
                // tuned shapes).
                result.risk.taubin = risk_filters > 0 && risk_taubin < risk_ratio * risk_filters;
                {
                    // In the input's order, on the input's faces: smooth_taubin's result bit for bit
                    // (the internal order sums each one-ring in another order: ~1e-9|e| apart 1e6 from
                    // the origin).
                    taubin = IndexedMesh{input.vertices, input.faces, {}};
                    frame.to_local(taubin.vertices);
                    const MeshTopology input_topo(nv, taubin.faces);
                    (void)taubin_smooth(taubin.vertices, input_topo, {}, TaubinParams{.iterations = k}, progress);
                    if (!result.risk.taubin) {
                        // Taubin's result is also kept on a mesh too coarse for the filters: where
                        // the median angle θ between neighbouring faces of Taubin's result exceeds
                        // coarse_dihedral·d (radians), a face's plane lies about θ|e| > 1.25 σ_g from the
                        // vertices one edge away, so filter 4 reads the surface's own bending as
                        // features and flattens it into facets, and the filters' risk reads low.
                        result.risk.median_dihedral = median_dihedral_angle(kintsugi::face_normals(taubin), input_topo);
                        result.risk.taubin = result.risk.coarse = result.risk.median_dihedral > coarse_dihedral * result.d;
                    }
                    if (!result.risk.taubin && result.risk.median_dihedral > recheck_dihedral * result.d) {
                        // The filters' risk above kept the first run's sharp edges: on a mesh that
                        // bends by nearly d between faces the detection reads the bending as
                        // creases, a choice that follows the noise, and the frozen estimate misses
                        // it (a 30 × 15 torus: 0.11-0.18|e| estimated against 0.22-0.31|e|). Again
                        // with the detection on each probe's input, averaged over several probes.
                        const auto t2 = std::chrono::steady_clock::now();
                        const std::size_t probes =
                            std::clamp<std::size_t>((std::size_t{1} << 15) / std::max<std::size_t>(m, 1), 1, recheck_max_probes);
                        FeatureBilateralParams again = repeat_params(inner, result);
                        again.impulse_removal = false;  // none were found on the input (risk_skip_reason)
                        Scalar div = 0;
                        for (std::size_t p = 0; p < probes; ++p) {
                            std::vector<Scalar> zp(nv, 0);
                            IndexedMesh probe{input.vertices, input.faces, {}};
                            draw_probe(zp, probe);
                            again.control = part_control(params.control, 0.9 + 0.1 * static_cast<double>(p) / static_cast<double>(probes),
                                                         0.9 + 0.1 * static_cast<double>(p + 1) / static_cast<double>(probes), last);
                            if (smooth_run(probe, again, nullptr).status == Status::cancelled) throw cancelled_exception{};
                            add_divergence(div, zp, probe);
                        }
                        div /= static_cast<Scalar>(probes);
                        const Scalar risk_again = stein_risk(residual, m, s, div / (sigma * sigma));
                        result.risk.recheck_probes = probes;
                        result.risk.filters_rms_recheck = frame.to_world(std::sqrt(std::max<Scalar>(0, risk_again) / ms));
                        result.risk.taubin = result.risk.recheck = risk_again > 0 && risk_taubin < recheck_ratio * risk_again;
                        result.timings.push_back({"risk: detection recheck",
                                                  std::chrono::duration<double>(std::chrono::steady_clock::now() - t2).count()});
                    }
                    if (result.risk.taubin) {
                        // The heights or the coarseness chose Taubin; its face normals may still be
                        // far worse (thin facets of a prism, every vertex on a crease: alike heights,
                        // 12-17° against 5-8°). Both normal errors estimated from the same probe as
                        // the filters' divergence; Taubin on the probe's input, in the input's order.
                        const auto t2 = std::chrono::steady_clock::now();
                        std::vector<Vec3> probe_taubin(nv);
                        for (std::size_t v = 0; v < nv; ++v) probe_taubin[v] = probe_input(v);
                        (void)taubin_smooth(probe_taubin, input_topo, {}, TaubinParams{.iterations = k}, progress);
                        auto corner = [&](int i, Index v) -> Vec3 {
                            switch (i) {
                                case 0: return y[so.order[v]];
                                case 1: return probe_input(v);
                                case 2: return taubin.vertices[v];
                                case 3: return probe_taubin[v];
                                case 4: return f[so.order[v]];
                                default: return frame.to_local(perturbed.vertices[v]);
                            }
                        };
                        // The probe's variance per counted vertex is (eps σ)²; the noise's is s².
                        const NormalRiskDifference nd =
                            normal_risk_difference(input.faces, corner, (s * s) / (eps * eps * sigma * sigma), so.order);
                        result.risk.normal_difference = nd.mean;
                        result.risk.normal_z = nd.z;
                        result.risk.normal_veto = nd.mean > normal_veto_min && nd.z > normal_veto_z &&
                                                  (risk_filters > 0 || !strong);
                        result.risk.taubin = !result.risk.normal_veto;
                        result.timings.push_back({"risk: face-normal estimate",
                                                  std::chrono::duration<double>(std::chrono::steady_clock::now() - t2).count()});
                    }
                    if (result.risk.taubin) {
                        frame.to_world(taubin.vertices);
                        chosen = &taubin.vertices;
                    } else {
                        taubin = {};
                    }
                }
            }
            for (StageTiming& t : progress.finish()) result.timings.push_back(std::move(t));
        }
        report_done();
    } catch (const cancelled_exception&) {
        FeatureBilateralResult cancelled;
        cancelled.status = Status::cancelled;
        cancelled.vertices = result.vertices;
        cancelled.faces = result.faces;
        return cancelled;
    }
    for (std::size_t v = 0; v < chosen->size(); ++v) kintsugi::set_vertex_position(mesh, v, (*chosen)[v]);
    return result;
}

}  // namespace detail::fbs

}  // namespace kintsugi
