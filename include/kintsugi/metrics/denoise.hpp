// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file denoise.hpp
/// @brief `denoise_metrics`: errors of a denoised mesh against its ground truth with
/// the same connectivity (mean/max angle between face normals, vertex RMS).
///
/// These are the two error measures of the mesh denoising literature, e.g. Zheng et
/// al., "Bilateral Normal Filtering for Mesh Denoising", IEEE TVCG 2011 (mean normal
/// angle) and Sun et al., "Fast and Effective Feature-Preserving Mesh Denoising",
/// IEEE TVCG 2007 (vertex-position error).

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>
#include <kintsugi/core/types.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <type_traits>

namespace kintsugi {

/// Errors of a mesh against a ground truth with identical connectivity.
struct DenoiseMetrics {
    double mean_normal_angle_deg = 0;  ///< mean angle between corresponding face normals, degrees
    double vertex_rms = 0;             ///< sqrt(mean |p_result - p_truth|^2), mesh units
    double max_normal_angle_deg = 0;   ///< largest angle between corresponding face normals, degrees
    /// Faces of zero area in the result whose truth face has an area: counted as 90° (a
    /// face without a normal agrees with no direction), so a collapsed result cannot score well.
    std::size_t degenerate_result_faces = 0;
};

namespace detail {

inline DenoiseMetrics denoise_metrics(const IndexedMesh& r, const IndexedMesh& t) {
    constexpr const char* fn = "kintsugi::denoise_metrics";
    if (r.vertices.empty() || r.faces.empty())
        throw invalid_input(std::string(fn) + ": the result mesh is empty; pass a mesh with faces");
    if (r.vertices.size() != t.vertices.size() || r.faces.size() != t.faces.size())
        throw invalid_input(std::string(fn) + ": the meshes differ in size (result " +
                            std::to_string(r.vertices.size()) + " vertices / " + std::to_string(r.faces.size()) +
                            " faces, truth " + std::to_string(t.vertices.size()) + " / " +
                            std::to_string(t.faces.size()) + "); they must have the same connectivity");
    // Faces are compared up to a cyclic rotation (CGAL::Surface_mesh may start a face
    // at another corner); the orientation must agree.
    auto same_cycle = [](const Face& a, const Face& b) {
        return a == b || (a[0] == b[1] && a[1] == b[2] && a[2] == b[0]) || (a[0] == b[2] && a[1] == b[0] && a[2] == b[1]);
    };
    for (std::size_t f = 0; f < r.faces.size(); ++f)
        if (!same_cycle(r.faces[f], t.faces[f]))
            throw invalid_input(std::string(fn) + ": face " + std::to_string(f) +
                                " differs between result and truth; they must have the same connectivity "
                                "(same vertex order and faces)");
    for (std::size_t f = 0; f < r.faces.size(); ++f)
        for (Index v : r.faces[f])
            if (v >= r.vertices.size())
                throw invalid_input(std::string(fn) + ": face " + std::to_string(f) + " uses vertex " +
                                    std::to_string(v) + " but there are " + std::to_string(r.vertices.size()) +
                                    " vertices; fix or remove the face");
    for (std::size_t v = 0; v < r.vertices.size(); ++v)
        if (!r.vertices[v].allFinite() || !t.vertices[v].allFinite())
            throw invalid_input(std::string(fn) + ": vertex " + std::to_string(v) +
                                " has a NaN or infinite coordinate; remove or fix it");
    // Any magnitude: squared lengths of 1e154 and more overflow, so both meshes are
    // rescaled by one power of two (the angles do not change, the RMS is mapped back).
    if (const ScaleFrame frame = scale_frame(r.vertices, t.vertices); !frame.identity()) {
        IndexedMesh rl = r, tl = t;
        frame.to_local(rl.vertices);
        frame.to_local(tl.vertices);
        DenoiseMetrics local = denoise_metrics(rl, tl);
        local.vertex_rms = frame.to_world(local.vertex_rms);
        return local;
    }

    DenoiseMetrics m;
    double sum2 = 0;
    for (std::size_t v = 0; v < r.vertices.size(); ++v) sum2 += (r.vertices[v] - t.vertices[v]).squaredNorm();
    m.vertex_rms = std::sqrt(sum2 / static_cast<double>(r.vertices.size()));

    auto normal = [](const IndexedMesh& mesh, const Face& f) {
        return Vec3((mesh.vertices[f[1]] - mesh.vertices[f[0]]).cross(mesh.vertices[f[2]] - mesh.vertices[f[0]]));
    };
    double sum = 0;
    std::size_t counted = 0;
    for (const Face& f : r.faces) {
        const Vec3 a = normal(r, f), b = normal(t, f);
        const double la = a.norm(), lb = b.norm();
        if (!(lb > 0)) continue;  // degenerate in the truth: no normal to compare with
        // atan2 of |a x b| and a.b is accurate for small angles, unlike acos.
        const double angle = la > 0 ? std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / std::numbers::pi : 90.0;
        m.degenerate_result_faces += !(la > 0);
        sum += angle;
        m.max_normal_angle_deg = std::max(m.max_normal_angle_deg, angle);
        ++counted;
    }
    m.mean_normal_angle_deg = counted ? sum / static_cast<double>(counted) : 0.0;
    return m;
}

}  // namespace detail

/// @brief Mean and max angle between corresponding face normals (degrees) and the
/// RMS of vertex displacements between a denoised mesh and its ground truth.
///
/// Faces that are degenerate (zero area) in the truth are left out of the angles; a face
/// degenerate in the result only counts as 90° (`degenerate_result_faces` says how many).
/// Orientation counts: a flipped face measures 180 degrees.
/// @tparam A a type modelling TriangleMesh (the result)
/// @tparam B a type modelling TriangleMesh (the truth)
/// @param result denoised mesh (not modified)
/// @param truth ground truth with the same vertex order and the same faces (not modified)
/// @return the metrics (no Status: linear time, cannot be cancelled)
/// @throws invalid_input if a mesh is empty, the vertex or face counts differ, a face
///   differs, an index is out of range or a coordinate is NaN/infinite.
template <TriangleMesh A, TriangleMesh B>
[[nodiscard]] DenoiseMetrics denoise_metrics(const A& result, const B& truth) {
    if constexpr (std::is_same_v<A, IndexedMesh> && std::is_same_v<B, IndexedMesh>) {
        return detail::denoise_metrics(result, truth);
    } else {
        return detail::denoise_metrics(kintsugi::to_indexed_mesh(result), kintsugi::to_indexed_mesh(truth));
    }
}

}  // namespace kintsugi
