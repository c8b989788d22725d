// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file sharp_feature_params.hpp
/// @brief The settings of the sharp-edge detection (normal voting tensor) that
/// kintsugi::detect_sharp_features and kintsugi::smooth_feature_bilateral share; both
/// are in smooth/feature_bilateral.hpp, and docs/methods/feature_bilateral.md gives the
/// measurements behind the defaults.

#include <kintsugi/core/control.hpp>
#include <kintsugi/core/types.hpp>

#include <cstddef>

namespace kintsugi {

/// The sharp-edge detection's settings: the parameters of detect_sharp_features() and
/// FeatureBilateralParams::detection (the one place they are kept, with their defaults).
struct SharpFeatureParams {
    /// Side of the voting cube, in mean edge lengths. Paper: 3 (synthetic noise), 9 (scan).
    Scalar voting_cube = 3;
    /// Edge-strength threshold for edge-candidate vertices. Paper: 0.251 (synthetic
    /// noise; ≈ edges sharper than 53°), 0.102 for its real scan (≈ 35°).
    Scalar edge_threshold = 0.251;
    /// |d_e · e3| needed for a mesh edge at a candidate vertex to be sharp (paper: 0.9).
    /// Used when crease_test is false.
    Scalar direction_threshold = 0.9;
    /// Whether boundary edges may be sharp edges (default: never).
    bool boundary_edges_sharp = false;
    /// Passes of filter 3 on the face normals before voting (0 = the paper: raw normals).
    std::size_t prefilter_iterations = 3;
    /// Spatial scale c of that filter and of the pre-smoothing, in mean edge lengths.
    Scalar prefilter_scale = 2;
    /// true: a sharp edge needs its two faces' (filtered) normals at least
    /// 2·atan(√edge_threshold) apart instead of the direction test (false = the paper).
    bool crease_test = true;
    /// Passes of filters 3–4 on a copy of the mesh before voting (0 = the paper).
    std::size_t presmooth_iterations = 3;
    /// Range scale d of that pre-smoothing (σ_g = d|e|).
    Scalar presmooth_range = 0.45;
    /// Spatial scale c of the pre-smoothing's vertex filter (its normal filter uses
    /// prefilter_scale), in mean edge lengths.
    Scalar presmooth_vertex_scale = 1;
    /// true: where faces that impulsive noise left exactly in the part's planes are near an
    /// edge, the edge is sharp when a pair of those planes at least 2·atan(√edge_threshold)
    /// apart explains it, whatever the voting tensor says ("Impulsive noise" in
    /// smooth/feature_bilateral.hpp; Twelve0.5Impulsive recall 0.02 → 0.82). Inert when fewer
    /// than 1 % of the faces are such faces (Gaussian noise, scans). false = the paper.
    bool coplanar_creases = true;
    /// true: a second detection whose pre-smoothing and prefilter average only normals within
    /// about 50° of each other (filter 3's range kernel σ 0.3, cut 0.85 instead of 0.6, 1) adds
    /// its sharp edges that lie on straight runs of 8 or more edges whose two sides' input
    /// normals are at least 45° apart. The default kernel averages across a crease of 53-65°
    /// once noise tilts the normals: Twelve's 63° creases were not found under any Gaussian
    /// noise (0.1|e|: P/R 0/0 → 1.0/1.0, 3.5° → 1.9°). Costs a second pre-smoothing on the
    /// first one's neighbour sets. false = the paper (and the detection before 2026-12-07).
    bool straight_creases = true;
    RunControl control{};
};


}  // namespace kintsugi
