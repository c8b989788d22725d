// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file pu_field_build.ipp
/// @brief The body of PUField::build (octree, support cover, partition of unity).
/// Included by pu_field.hpp, or, with KINTSUGI_SEPARATE_STAGES, by the one file of the
/// program that compiles it (kintsugi/core/stages.hpp).

#include <kintsugi/reconstruct/pu_field.hpp>

namespace kintsugi {

KINTSUGI_STAGE PUFieldResult PUField::build_from(std::vector<Vec3> pts, std::vector<Vec3> nrm, const PUFieldParams& params) {
    detail::pu_validate(pts, nrm, params);
    const std::size_t n_points = pts.size();
    PUFieldResult out = detail::run_cancellable<PUFieldResult>(params.control, [&](detail::Progress& progress) {
        PUFieldResult res;
        auto data = std::make_shared<detail::PUFieldData>();
        progress.stage("pu_octree", 0.0, 0.1);
        for (const auto& p : pts) data->box.extend(p);
        data->center = data->box.center();
        data->scale = 1 / data->box.extent().maxCoeff();
        data->epsilon = params.epsilon;
        const Scalar sign = params.inward_normals ? 1 : -1;
        parallel_for(0, pts.size(), [&](std::size_t i) {
            pts[i] = (pts[i] - data->center) * data->scale;
            nrm[i] = sign * nrm[i].normalized();
        }, 4096);
        data->octree = Octree(pts, OctreeParams{.max_level = params.max_level,
                                                .max_points_per_cell = 0,
                                                .balance = true,
                                                .cube_side = 1,
                                                .cube_min = Vec3::Constant(-0.5)});
        progress.check();
        // The cover's random order of the cells (a sequential shuffle, 0.36 s for the 12M
        // cells of the 2M bench input) is made beside the points' reordering and tree.
        std::vector<std::uint32_t> order;
        KdTree tree;
        parallel_invoke(
            [&] { order = detail::pu_random_order(data->octree.size(), params.seed); },
            [&] {
                // The fits read the points in Morton order (memory locality); the octree's
                // point lists keep the caller's indices.
                const auto& ord = data->octree.point_indices();
                std::vector<Vec3> p2(pts.size()), n2(pts.size());
                parallel_for(0, pts.size(), [&](std::size_t i) {
                    p2[i] = pts[ord[i]];
                    n2[i] = nrm[ord[i]];
                }, 4096);
                pts.swap(p2);
                nrm.swap(n2);
                // Buckets of 64 points rather than 12: the cover's candidates come in random
                // order, so its searches start from cold caches and a shallower tree misses
                // less (2M bench input, back to back: cover 6.6-7.3 s against 6.7-8.0 s, tree
                // 20 MB smaller).
                tree = KdTree(pts, KdTreeParams{.leaf_size = 64});
            });
        res.octree_cells = data->octree_cells = data->octree.size();
        res.max_level_cells = data->octree.cells_per_level().back();

        progress.stage("pu_cover", 0.1, 0.85);
        detail::PUCoverInput in;
        in.points = &pts;
        in.normals = &nrm;
        in.tree = &tree;
        in.octree = &data->octree;
        in.epsilon = params.epsilon;
        in.seed = params.seed;
        detail::PUCoverStats stats;
        const auto sup = detail::pu_cover(in, stats, [&](double f) { progress.update(f); }, std::move(order));
        res.supports = sup.size();
        res.fits_evaluated = stats.evaluated;
        res.fallback_supports = stats.fallback;
        if (!params.keep_octree) data->octree = Octree();

        progress.stage("pu_index", 0.85, 1.0);
        const Scalar inv_scale = 1 / data->scale;
        data->local.resize(sup.size());
        data->supports.resize(sup.size());
        std::vector<PUBall> balls(sup.size());
        for (std::size_t i = 0; i < sup.size(); ++i) {
            const auto& s = sup[i];
            balls[i] = {s.c, s.r};
            data->local[i] = {s.m, s.m.dot(s.d)};
            data->supports[i] = PUSupport{data->center + s.c * inv_scale, s.r * inv_scale, s.m,
                                          data->center + s.d * inv_scale, s.count, static_cast<int>(s.level),
                                          s.coherence};
        }
        data->pu = PartitionOfUnity::build(std::move(balls), Vec3::Constant(Scalar(-0.5)), Scalar(1),
                                           [&](double f) { progress.update(0.8 * f); });
        res.field.data_ = std::move(data);
        res.timings = progress.finish();
        return res;
    });
    out.points = n_points;  // also when cancelled: the field is empty, the input count stays
    return out;
}

}  // namespace kintsugi
