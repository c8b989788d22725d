// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file rbf_octree_fit.ipp
/// @brief The body of RBFOctreeField::build (the octree, the offsets, the per-cell
/// solves). Included by rbf_octree.hpp, or, with KINTSUGI_SEPARATE_STAGES, by the one
/// file of the program that compiles it (kintsugi/core/stages.hpp).

#include <kintsugi/rbf/rbf_octree.hpp>

namespace kintsugi {

/// The fit on the internal layout (positions and normals of equal length).
KINTSUGI_STAGE RBFOctreeResult detail::rbf_octree_fit(std::vector<Vec3> pts, std::vector<Vec3> nrm,
                                              const RBFOctreeParams& params) {
    detail::rbf_validate(pts, nrm, params, "kintsugi::RBFOctreeField::build: ");
    RBFOctreeResult res;
    res.stats.points = pts.size();
    detail::Progress progress(params.control);
    try {
        auto data = std::make_shared<detail::RBFOctreeData>();
        data->frame = detail::scale_frame(pts);
        data->alpha = params.overlap;
        data->blend = params.blend;
        data->frame.to_local(pts);

        // ---------------------------------------------------------- 1) offsets
        progress.stage("rbf_offsets", 0.0, 0.15);
        BoundingBox box;
        for (const Vec3& p : pts) box.extend(p);
        const std::size_t n0 = pts.size();
        std::vector<Vec3> sn(n0);
        parallel_for(0, n0, [&](std::size_t i) {
            const Vec3 n = nrm[i] / nrm[i].cwiseAbs().maxCoeff();  // no underflow in norm()
            sn[i] = n.normalized();
        }, 4096);
        std::vector<Vec3>().swap(nrm);
        // Exact copies first, by sorting (a cluster of m copies would otherwise cost m²
        // in the kd-tree, whose k-nearest query collects every tie): a later copy is
        // dropped whatever merge_distance, as the merge below would drop it.
        std::size_t removed = 0;
        {
            std::vector<std::tuple<Scalar, Scalar, Scalar, std::uint32_t>> order(n0);
            parallel_for(0, n0, [&](std::size_t i) {
                order[i] = {pts[i].x(), pts[i].y(), pts[i].z(), static_cast<std::uint32_t>(i)};
            }, 4096);
            detail::sort_maybe_parallel(order);
            std::vector<std::uint8_t> copy(n0, 0);
            for (std::size_t k = 1; k < n0; ++k)
                if (std::get<0>(order[k]) == std::get<0>(order[k - 1]) && std::get<1>(order[k]) == std::get<1>(order[k - 1]) &&
                    std::get<2>(order[k]) == std::get<2>(order[k - 1])) {
                    copy[std::get<3>(order[k])] = 1;
                    ++removed;
                }
            if (removed > 0) {
                std::size_t m = 0;
                for (std::size_t i = 0; i < n0; ++i)
                    if (!copy[i]) {
                        pts[m] = pts[i];
                        sn[m] = sn[i];
                        ++m;
                    }
                pts.resize(m);
                sn.resize(m);
            }
            progress.check();
        }
        const std::size_t n1 = pts.size();
        const Scalar merge_dist = params.merge_distance * box.diagonal();
        const Scalar merge2 = merge_dist * merge_dist;
        // Phase A, one kd-tree and one query of the 7 nearest per point: the spacing
        // (the 6 nearest others) and whether a point has a (near-)duplicate. The ids
        // are kept to know, after a merge, whose 7 nearest held a removed point.
        constexpr std::size_t K = 7;
        auto surface = std::make_shared<KdTree>(KdTree::adopt(std::move(pts)));
        std::vector<Scalar> spacing_of(n1);
        std::vector<std::uint8_t> suspect(n1);
        // Crease points: a neighbour's normal more than 105° from the point's own (an acute
        // edge or corner, under 75° inside, passes within about a spacing); they get crease
        // offsets below. Not right angles: on the guided-denoising Block (90° edges) the
        // offsets moved the surface off the truth (0.0028 → 0.0032 %, docs).
        std::vector<std::uint8_t> crease(n1, 0);
        auto near_point = [&](const KdTree& t, std::size_t i, std::vector<Neighbor>& nb, std::uint32_t* ids) {
            t.knn(t.point(i), K, nb);
            Scalar sum = 0;
            std::size_t cnt = 0;
            bool dup = false;
            bool sharp = false;
            for (std::size_t k = 0; k < nb.size(); ++k) {
                if (sn[nb[k].index].dot(sn[i]) < Scalar(-0.25)) sharp = true;
                if (ids) ids[k] = static_cast<std::uint32_t>(nb[k].index);
                if (nb[k].index == i) continue;
                if (nb[k].squared_distance <= merge2) dup = true;
                if (cnt < 6) {
                    sum += std::sqrt(nb[k].squared_distance);
                    ++cnt;
                }
            }
            if (ids)
                for (std::size_t k = nb.size(); k < K; ++k) ids[k] = static_cast<std::uint32_t>(i);
            spacing_of[i] = cnt > 0 ? sum / static_cast<Scalar>(cnt) : Scalar(1);
            crease[i] = sharp ? 1 : 0;
            return dup;
        };
        // The queries run in Morton order of the points (each result stored at its
        // point): neighbouring queries walk the same branches of the tree, which at 1M
        // points in scan or sampling order saves most cache misses. Same results.
        auto morton_order = [&](const std::vector<Vec3>& P) {
            std::vector<std::pair<std::uint64_t, std::uint32_t>> key(P.size());
            const Scalar scale = Scalar((1u << 21) - 1) / std::max(box.extent().maxCoeff(), Scalar(1e-300));
            parallel_for(0, P.size(), [&](std::size_t i) {
                std::array<std::uint32_t, 3> g{};
                for (int a = 0; a < 3; ++a)
                    g[static_cast<std::size_t>(a)] = static_cast<std::uint32_t>(
                        std::clamp<Scalar>((P[i][a] - box.min[a]) * scale, 0, Scalar((1u << 21) - 1)));
                key[i] = {morton_encode(g[0], g[1], g[2]), static_cast<std::uint32_t>(i)};
            }, 4096);
            detail::sort_maybe_parallel(key);
            std::vector<std::uint32_t> order(P.size());
            for (std::size_t i = 0; i < P.size(); ++i) order[i] = key[i].second;
            return order;
        };
        std::vector<std::uint32_t> visit = morton_order(surface->points());
        std::vector<std::uint32_t> knn_ids(n1 * K);
        constexpr std::size_t point_block = 1 << 16;
        for (std::size_t b0 = 0; b0 < n1; b0 += point_block) {
            const std::size_t b1 = std::min(n1, b0 + point_block);
            parallel_for(b0, b1, [&](std::size_t t) {
                thread_local std::vector<Neighbor> nb;
                const std::size_t i = visit[t];
                suspect[i] = near_point(*surface, i, nb, knn_ids.data() + i * K) ? 1 : 0;
            }, 256);
            progress.check();
            progress.update(0.4 * static_cast<double>(b1) / static_cast<double>(n1));
        }
        // Merge: keep point i unless an earlier kept point lies within merge_dist (exact
        // duplicates always). Only points with such a neighbour ("suspects") take part;
        // closeness is symmetric, so they are closed under it. Greedy in index order
        // over a BucketGrid of the kept suspects (cells of side merge_dist: a suspect's
        // rivals lie in the 2 x 2 x 2 cells its ball meets, and a cell holds at most a
        // few kept points), so a cluster of m copies costs O(m), not O(m²).
        std::vector<std::uint8_t> keep(n1, 1);
        std::size_t near_removed = 0;
        {
            // Cells of side merge_dist; for exact duplicates only, the finest the box allows
            // (the grid enlarges a side too small for 2^21 cells per axis).
            BucketGrid<std::uint32_t> grid(box.min, box.max,
                                           merge_dist > 0 ? merge_dist : std::numeric_limits<Scalar>::min());
            std::size_t seen = 0;
            for (std::size_t i = 0; i < n1; ++i) {
                if (!suspect[i]) continue;
                if (++seen % 65536 == 0) progress.check();
                const Vec3& p = surface->point(i);
                const bool near = grid.any_in_ball(p, merge_dist);
                if (near) {
                    keep[i] = 0;
                    ++near_removed;
                } else {
                    grid.insert(p, static_cast<std::uint32_t>(i));
                }
            }
        }
        removed += near_removed;
        res.stats.merged_points = removed;
        if (n0 - removed < 4)
            throw invalid_input("kintsugi::RBFOctreeField::build: needs at least 4 distinct points, got " +
                                std::to_string(n0 - removed) +
                                " after merging the (near-)duplicates within merge_distance; add points or lower "
                                "merge_distance");
        if (near_removed > 0) {
            // The kept points, in order, in a new tree; a spacing stands unless the
            // point's 7 nearest held a removed point.
            std::vector<Vec3> kp, kn;
            std::vector<std::uint8_t> redo;
            kp.reserve(n1 - near_removed);
            std::size_t m = 0;
            for (std::size_t i = 0; i < n1; ++i) {
                if (!keep[i]) continue;
                bool again = false;
                for (std::size_t k = 0; k < K && !again; ++k) again = !keep[knn_ids[i * K + k]];
                kp.push_back(surface->point(i));
                kn.push_back(sn[i]);
                spacing_of[m] = spacing_of[i];
                crease[m] = crease[i];
                redo.push_back(again ? 1 : 0);
                ++m;
            }
            spacing_of.resize(m);
            crease.resize(m);
            sn = std::move(kn);
            surface = std::make_shared<KdTree>(KdTree::adopt(std::move(kp)));
            visit = morton_order(surface->points());
            progress.check();
            parallel_for(0, m, [&](std::size_t i) {
                if (!redo[i]) return;
                thread_local std::vector<Neighbor> nb;
                (void)near_point(*surface, i, nb, nullptr);
            }, 256);
        }
        std::vector<std::uint32_t>().swap(knn_ids);
        data->surface = surface;
        const KdTree& tree = *data->surface;
        const std::vector<Vec3>& sp = tree.points();
        const std::size_t ns = sp.size();
        // Phase B, Carr's test of both offsets: d is halved while another point is
        // strictly nearer to p_i ± d n_i than p_i is (per try a search of the ball around
        // q through p_i that stops at the first other point: cheaper, measured, than the
        // nearest point to q and than one radius query of 2d around p_i).
        std::vector<std::array<Scalar, 2>> off(ns);           // d of the + and - offsets (0: dropped)
        std::vector<std::array<std::uint8_t, 2>> shrunk(ns);  // whether d was halved
        for (std::size_t b0 = 0; b0 < ns; b0 += point_block) {
            const std::size_t b1 = std::min(ns, b0 + point_block);
            parallel_for(b0, b1, [&](std::size_t t) {
                const std::size_t i = visit[t];
                const Vec3& p = sp[i];
                for (int s = 0; s < 2; ++s) {
                    Scalar d = params.offset_scale * spacing_of[i];
                    const Scalar sign = s == 0 ? Scalar(1) : Scalar(-1);
                    off[i][s] = 0;
                    shrunk[i][s] = 0;
                    for (int it = 0; it < 9; ++it) {
                        const Vec3 q = p + sign * d * sn[i];
                        const Scalar own = (q - p).squaredNorm();
                        if (!tree.any_other_within_squared(q, own, i)) {
                            off[i][s] = d;
                            break;
                        }
                        shrunk[i][s] = 1;
                        d /= 2;
                    }
                }
            }, 256);
            progress.check();
            progress.update(0.4 + 0.6 * static_cast<double>(b1) / static_cast<double>(ns));
        }
        // Crease offsets, beyond Carr's: the ±d offsets along each side's normal leave the
        // region beyond a sharp edge or corner without a constraint, where the cells'
        // RBFs extrapolate the two faces' zero sets on past the edge (blobs and sheets
        // off the blades of the guided-denoising SharpSphere, the tips of a star prism:
        // docs). A crease point gets two more centres at p ± d m, m the mean normal of its
        // 7 nearest points (skipped where they nearly cancel, |m| < 0.3 of their count,
        // e.g. a blade of almost parallel faces), valued ± their distance to the nearest
        // point, kept only when side_of agrees with that sign and that point lies at least
        // d/2 away (no constraint close to another, inconsistent one).
        data->surface_normals = std::move(sn);
        data->surface_area.resize(ns);
        for (std::size_t i = 0; i < ns; ++i) data->surface_area[i] = spacing_of[i] * spacing_of[i];
        const std::vector<Vec3>& sn_of = data->surface_normals;
        std::vector<std::uint32_t> crease_ids;
        for (std::size_t i = 0; i < ns; ++i)
            if (crease[i]) crease_ids.push_back(static_cast<std::uint32_t>(i));
        std::vector<std::array<Scalar, 2>> crease_value(crease_ids.size(), {0, 0});  // 0: none
        std::vector<Vec3> crease_dir(crease_ids.size(), Vec3::Zero());
        parallel_for(0, crease_ids.size(), [&](std::size_t t) {
            thread_local std::vector<Neighbor> nb;
            const std::size_t i = crease_ids[t];
            tree.knn(sp[i], K, nb);
            Vec3 m = Vec3::Zero();
            for (const Neighbor& q : nb) m += sn_of[q.index];
            if (!(m.norm() >= Scalar(0.3) * static_cast<Scalar>(nb.size()))) return;
            m.normalize();
            crease_dir[t] = m;
            const Scalar d = params.offset_scale * spacing_of[i];
            for (int s = 0; s < 2; ++s) {
                const Scalar sign = s == 0 ? Scalar(1) : Scalar(-1);
                const Vec3 q = sp[i] + sign * d * m;
                const Scalar r = std::sqrt(tree.nearest(q).squared_distance);
                if (r >= d / 2 && data->side_of(q) == sign) crease_value[t][s] = sign * r;
            }
        }, 64);
        progress.check();
        std::vector<std::uint32_t> crease_slot(crease_ids.empty() ? 0 : ns, 0);  // t + 1, 0: none
        for (std::size_t t = 0; t < crease_ids.size(); ++t) crease_slot[crease_ids[t]] = static_cast<std::uint32_t>(t + 1);
        std::vector<std::uint8_t>().swap(crease);

        // Centres: point i, then its + and - offsets, the points in Morton order: a cell's
        // centres then lie close together in memory, which the octree lists, the solves'
        // gathers and above all the evaluations (a gather of every centre of 2-3 cells per
        // value) read (fertility 1M, whole reconstruction: see the methods page).
        std::vector<Vec3>& C = data->centres;
        std::vector<Scalar> value;
        std::vector<std::uint8_t> on_surface;
        C.reserve(3 * ns);
        value.reserve(3 * ns);
        on_surface.reserve(3 * ns);
        // Where point i's centres start in C (its offsets follow it), and the largest
        // offset: the padding of small cells finds the nearest centres through the points.
        std::vector<std::uint32_t> centre_of(ns);
        Scalar max_offset = 0;
        for (const std::uint32_t vi : visit) {
            const std::size_t i = vi;
            centre_of[i] = static_cast<std::uint32_t>(C.size());
            C.push_back(sp[i]);
            value.push_back(0);
            on_surface.push_back(1);
            for (int s = 0; s < 2; ++s) {
                res.stats.shrunk_offsets += shrunk[i][s];
                max_offset = std::max(max_offset, off[i][s]);
                if (off[i][s] == 0) {
                    ++res.stats.dropped_offsets;
                    continue;
                }
                const Scalar sign = s == 0 ? Scalar(1) : Scalar(-1);
                C.push_back(sp[i] + sign * off[i][s] * sn_of[i]);
                value.push_back(sign * off[i][s]);
                on_surface.push_back(0);
            }
            if (crease_slot.empty() || crease_slot[i] == 0) continue;
            const std::size_t t = crease_slot[i] - 1;
            for (int s = 0; s < 2; ++s) {
                if (crease_value[t][s] == 0) continue;
                const Scalar d = params.offset_scale * spacing_of[i];
                max_offset = std::max(max_offset, d);
                C.push_back(sp[i] + (s == 0 ? d : -d) * crease_dir[t]);
                value.push_back(crease_value[t][s]);
                on_surface.push_back(0);
                ++res.stats.crease_offsets;
            }
        }
        std::vector<std::uint32_t>().swap(visit);
        res.stats.offset_points = C.size() - ns;

        // ---------------------------------------------------------- 2) octree
        progress.stage("rbf_octree", 0.15, 0.25);
        BoundingBox cb;
        for (const Vec3& c : C) cb.extend(c);
        const Scalar L = std::max(cb.extent().maxCoeff(), Scalar(1e-300));
        // A margin so that no centre lies on the far faces of the tiling.
        const Vec3 lo = cb.min - Vec3::Constant(Scalar(0.01) * L), hi = cb.max + Vec3::Constant(Scalar(0.01) * L);
        data->root_side = params.root_size * (hi - lo).maxCoeff();
        for (int k = 0; k < 3; ++k)
            data->root_count[k] = std::max(1, static_cast<int>(std::ceil((hi[k] - lo[k]) / data->root_side)));
        const Vec3 span(data->root_count[0] * data->root_side, data->root_count[1] * data->root_side,
                        data->root_count[2] * data->root_side);
        data->root_min = (lo + hi) / 2 - span / 2;
        const Scalar alpha = params.overlap, beta = params.activity, gamma = std::max(alpha, beta);
        // Level-by-level subdivision; a node's list holds the centres in its γ-box
        // (γ = max(α, β)), a child's list is a subset of its parent's. Each level's
        // splitting nodes are cut into chunks of their lists, processed in parallel and
        // concatenated in order: the same tree whatever the thread count.
        auto& nodes = data->nodes;
        const std::size_t n_roots =
            static_cast<std::size_t>(data->root_count[0]) * data->root_count[1] * data->root_count[2];
        for (int k = 0; k < data->root_count[2]; ++k)
            for (int j = 0; j < data->root_count[1]; ++j)
                for (int i = 0; i < data->root_count[0]; ++i)
                    nodes.push_back({data->root_min + data->root_side * Vec3(i, j, k), data->root_side, -1, -1});
        auto in_factor_box = [](const detail::RBFOctreeData::Node& n, const Vec3& p, Scalar factor) {
            const Scalar h = factor * n.side / 2;
            const Vec3 c = n.min + Vec3::Constant(n.side / 2);
            return std::abs(p.x() - c.x()) <= h && std::abs(p.y() - c.y()) <= h && std::abs(p.z() - c.z()) <= h;
        };
        std::vector<std::vector<std::uint32_t>> lists(n_roots);
        std::vector<std::size_t> alpha_count(n_roots, 0);  // centres in each node's α-box
        for (std::size_t c = 0; c < C.size(); ++c) {
            // Roots: bin every centre into the roots whose γ-boxes hold it.
            std::array<int, 3> r{};
            (void)data->root_of(C[c], r);
            for (int k = std::max(0, r[2] - 1); k <= std::min(data->root_count[2] - 1, r[2] + 1); ++k)
                for (int j = std::max(0, r[1] - 1); j <= std::min(data->root_count[1] - 1, r[1] + 1); ++j)
                    for (int i = std::max(0, r[0] - 1); i <= std::min(data->root_count[0] - 1, r[0] + 1); ++i) {
                        const std::size_t id = data->root_index(i, j, k);
                        if (!in_factor_box(nodes[id], C[c], gamma)) continue;
                        lists[id].push_back(static_cast<std::uint32_t>(c));
                        if (in_factor_box(nodes[id], C[c], alpha)) ++alpha_count[id];
                    }
        }
        constexpr int max_depth = 20;  // 2^-20 of the root: far below any merged spacing
        std::vector<std::size_t> level(n_roots);
        for (std::size_t i = 0; i < n_roots; ++i) level[i] = i;
        // Final lists of the leaves, by node.
        std::vector<std::vector<std::uint32_t>> node_list(n_roots);
        struct Chunk {
            std::size_t q, begin, end;
        };
        struct ChunkOut {
            std::array<std::vector<std::uint32_t>, 8> kid;  // γ-box lists of the 8 children
            std::array<std::size_t, 8> alpha{};             // their α-box counts
        };
        constexpr std::size_t chunk_size = 1 << 15;
        for (int depth = 0; !level.empty(); ++depth) {
            progress.check();
            res.stats.depth = depth;
            std::vector<Chunk> chunks;
            std::vector<std::size_t> first_chunk(level.size() + 1, 0);
            for (std::size_t q = 0; q < level.size(); ++q) {
                first_chunk[q] = chunks.size();
                if (alpha_count[q] <= params.n_max || depth >= max_depth) continue;
                for (std::size_t b = 0; b < lists[q].size(); b += chunk_size)
                    chunks.push_back({q, b, std::min(lists[q].size(), b + chunk_size)});
                if (lists[q].empty()) chunks.push_back({q, 0, 0});
            }
            first_chunk[level.size()] = chunks.size();
            std::vector<ChunkOut> outs(chunks.size());
            parallel_for(0, chunks.size(), [&](std::size_t t) {
                const Chunk& ch = chunks[t];
                const auto& node = nodes[level[ch.q]];
                const auto& list = lists[ch.q];
                // Per axis, the children's centres (low, high) and half-widths, computed
                // as in_factor_box computes them for the child nodes.
                const Scalar hs = node.side / 2;
                const Scalar hg = gamma * hs / 2, ha = alpha * hs / 2;
                Scalar clo[3], chi[3];
                for (int k = 0; k < 3; ++k) {
                    clo[k] = node.min[k] + hs / 2;
                    chi[k] = (node.min[k] + hs) + hs / 2;
                }
                ChunkOut& out = outs[t];
                for (std::size_t e = ch.begin; e < ch.end; ++e) {
                    const std::uint32_t c = list[e];
                    const Vec3& p = C[c];
                    unsigned g[3], a[3];  // bit 0: the low child's box holds p, bit 1: the high one's
                    for (int k = 0; k < 3; ++k) {
                        const Scalar dl = std::abs(p[k] - clo[k]), dh = std::abs(p[k] - chi[k]);
                        g[k] = (dl <= hg ? 1u : 0u) | (dh <= hg ? 2u : 0u);
                        a[k] = (dl <= ha ? 1u : 0u) | (dh <= ha ? 2u : 0u);
                    }
                    for (unsigned o = 0; o < 8; ++o) {
                        const unsigned bx = 1u << (o & 1), by = 1u << ((o >> 1) & 1), bz = 1u << ((o >> 2) & 1);
                        if (!((g[0] & bx) && (g[1] & by) && (g[2] & bz))) continue;
                        out.kid[o].push_back(c);
                        if ((a[0] & bx) && (a[1] & by) && (a[2] & bz)) ++out.alpha[o];
                    }
                }
            }, 1);
            std::vector<std::size_t> next, next_alpha;
            std::vector<std::vector<std::uint32_t>> next_lists;
            for (std::size_t q = 0; q < level.size(); ++q) {
                const std::size_t id = level[q];
                if (first_chunk[q] == first_chunk[q + 1]) {  // a leaf
                    if (node_list.size() < nodes.size()) node_list.resize(nodes.size());
                    node_list[id] = std::move(lists[q]);
                    continue;
                }
                const auto first = static_cast<std::int64_t>(nodes.size());
                nodes[id].child = first;
                const Scalar hs = nodes[id].side / 2;
                const Vec3 mn = nodes[id].min;
                for (std::size_t o = 0; o < 8; ++o) {
                    nodes.push_back({mn + hs * Vec3(o & 1 ? 1 : 0, o & 2 ? 1 : 0, o & 4 ? 1 : 0), hs, -1, -1});
                    next.push_back(static_cast<std::size_t>(first) + o);
                    std::vector<std::uint32_t> kid = std::move(outs[first_chunk[q]].kid[o]);
                    std::size_t na = outs[first_chunk[q]].alpha[o];
                    for (std::size_t t = first_chunk[q] + 1; t < first_chunk[q + 1]; ++t) {
                        kid.insert(kid.end(), outs[t].kid[o].begin(), outs[t].kid[o].end());
                        std::vector<std::uint32_t>().swap(outs[t].kid[o]);
                        na += outs[t].alpha[o];
                    }
                    next_lists.push_back(std::move(kid));
                    next_alpha.push_back(na);
                }
                std::vector<std::uint32_t>().swap(lists[q]);
            }
            level = std::move(next);
            lists = std::move(next_lists);
            alpha_count = std::move(next_alpha);
        }
        node_list.resize(nodes.size());
        // Leaves in node order; liveness from the β-box; the α-box centres for the system
        // (the list itself when γ = α).
        std::vector<std::size_t> leaf_node;
        for (std::size_t id = 0; id < nodes.size(); ++id) {
            if (nodes[id].child >= 0) continue;
            nodes[id].leaf = static_cast<std::int64_t>(leaf_node.size());
            leaf_node.push_back(id);
        }
        data->leaves.resize(leaf_node.size());
        std::vector<std::vector<std::uint32_t>> leaf_centres(leaf_node.size());
        parallel_for(0, leaf_node.size(), [&](std::size_t l) {
            const std::size_t id = leaf_node[l];
            auto& leaf = data->leaves[l];
            leaf.node = id;
            auto& list = node_list[id];
            for (const auto c : list)
                if (on_surface[c] && in_factor_box(nodes[id], C[c], beta)) {
                    leaf.live = true;
                    break;
                }
            if (gamma == alpha) {
                leaf_centres[l] = std::move(list);
            } else {
                for (const auto c : list)
                    if (in_factor_box(nodes[id], C[c], alpha)) leaf_centres[l].push_back(c);
                std::vector<std::uint32_t>().swap(list);
            }
        }, 16);
        res.stats.cells = data->leaves.size();
        // Beyond the paper: a cell the surface may cross between samples is live too
        // (its nearest point closer to its centre than β x the half diagonal plus
        // twice that point's spacing); the β-box rule alone leaves dead cells, with
        // the far value's error, on the surface where the samples are sparse.
        parallel_for(0, data->leaves.size(), [&](std::size_t l) {
            auto& leaf = data->leaves[l];
            if (leaf.live) return;
            const auto& node = nodes[leaf.node];
            const Neighbor nb = tree.nearest(data->node_center(node));
            const Scalar reach = beta * std::sqrt(Scalar(3)) / 2 * node.side + 2 * spacing_of[nb.index];
            if (nb.squared_distance <= reach * reach) leaf.live = true;
            else std::vector<std::uint32_t>().swap(leaf_centres[l]);
        }, 64);
        progress.check();

        // ---------------------------------------------------------- 3) solves
        progress.stage("rbf_solve", 0.25, 1.0);
        const std::size_t nl = data->leaves.size();
        constexpr std::size_t min_centres = 20;  // a well-posed r³ + linear fit
        // The k nearest centres to c (ties by index, as KdTree::knn), found through the
        // points' tree instead of a kd-tree of all 3N centres (fertility 1M: 28,726 padded
        // cells; 120 MB less peak memory, the same sets, see the methods page): the k
        // nearest points are centres, so the k nearest centres lie
        // within their radius r of c, and each lies within max_offset of its point, so
        // their points lie within r + max_offset of c. Where that ball holds too many
        // points (one long offset among dense points), a tree of the centres is built
        // once and used instead; both give the same set.
        std::unique_ptr<KdTree> centre_tree;
        std::once_flag centre_tree_once;
        const Scalar coord_scale = std::max(cb.max.cwiseAbs().maxCoeff(), cb.min.cwiseAbs().maxCoeff());
        auto nearest_centres = [&](const Vec3& c, std::size_t k, std::vector<std::uint32_t>& out) {
            thread_local std::vector<Neighbor> nb;
            thread_local std::vector<std::pair<Scalar, std::uint32_t>> cand;
            out.clear();
            tree.knn(c, k, nb);
            const Scalar r = std::sqrt(nb.back().squared_distance);
            const Scalar reach = (r + max_offset) * (1 + Scalar(1e-9)) + Scalar(1e-12) * coord_scale;
            tree.radius_search_squared(c, reach * reach, nb, false);
            if (nb.size() > 4096) {
                std::call_once(centre_tree_once, [&] { centre_tree = std::make_unique<KdTree>(C); });
                centre_tree->knn(c, k, nb);
                for (const Neighbor& q : nb) out.push_back(static_cast<std::uint32_t>(q.index));
                return;
            }
            cand.clear();
            for (const Neighbor& q : nb)
                for (std::size_t j = centre_of[q.index]; j < C.size() && (j == centre_of[q.index] || !on_surface[j]); ++j) {
                    // nanoflann's metric, term by term: the same distances as a centres' tree
                    Scalar d2 = 0;
                    for (int a = 0; a < 3; ++a) {
                        const Scalar diff = c[a] - C[j][a];
                        d2 += diff * diff;
                    }
                    cand.emplace_back(d2, static_cast<std::uint32_t>(j));
                }
            const std::size_t take = std::min(k, cand.size());
            std::partial_sort(cand.begin(), cand.begin() + static_cast<std::ptrdiff_t>(take), cand.end());
            for (std::size_t t = 0; t < take; ++t) out.push_back(cand[t].second);
        };
        // A cell splits while it has more than n_max centres, so only a cell at the depth
        // limit has more: a cluster of near-duplicates that merge_distance kept (2,000
        // copies 1e-9 apart at merge_distance 0: one cell of 6,000 centres, whose dense
        // fallback solve is cubic in its size). Such a cell keeps an evenly spread subset
        // of its centres in their (Morton) order, whole groups of a point and its offsets (its
        // value constraints stay consistent), at most cap of them; the field still
        // interpolates the kept ones, and the others lie within the cell's 2^-20 of the
        // root from them.
        const std::size_t cap = std::max(params.n_max, min_centres);
        auto cap_centres = [&](std::vector<std::uint32_t>& ids) {
            auto owner = [&](std::uint32_t c) {  // the point of an offset: at most 2 before it
                while (c > 0 && !on_surface[c]) --c;
                return c;
            };
            thread_local std::vector<std::size_t> group;  // start of each run of one owner in ids
            group.clear();
            for (std::size_t k = 0; k < ids.size(); ++k)
                if (k == 0 || owner(ids[k]) != owner(ids[k - 1])) group.push_back(k);
            const std::size_t ng = group.size();
            std::size_t largest = 1;  // 3 centres, 5 at a crease point
            for (std::size_t g = 0; g < ng; ++g)
                largest = std::max(largest, (g + 1 < ng ? group[g + 1] : ids.size()) - group[g]);
            const std::size_t take = std::min(ng, cap / largest);
            std::size_t out = 0;
            for (std::size_t t = 0; t < take; ++t) {
                const std::size_t gi = t * ng / take;
                const std::size_t e = gi + 1 < ng ? group[gi + 1] : ids.size();
                for (std::size_t k = group[gi]; k < e; ++k) ids[out++] = ids[k];
            }
            ids.resize(out);
        };
        std::vector<std::vector<Scalar>> leaf_w(nl);
        std::vector<std::uint8_t> bad(nl, 0), padded(nl, 0);
        std::vector<std::size_t> capped(nl, 0);
        const std::size_t block = 256;
        for (std::size_t b0 = 0; b0 < nl; b0 += block) {
            const std::size_t b1 = std::min(nl, b0 + block);
            parallel_for(b0, b1, [&](std::size_t l) {
                auto& leaf = data->leaves[l];
                if (!leaf.live) {
                    const Vec3 c = data->node_center(nodes[leaf.node]);
                    leaf.dead_sign = data->far_value(c, nullptr, nullptr) >= 0 ? Scalar(1) : Scalar(-1);
                    return;
                }
                auto& ids = leaf_centres[l];
                const Vec3 c = data->node_center(nodes[leaf.node]);
                if (ids.size() > cap) {
                    capped[l] = ids.size();
                    cap_centres(ids);
                    capped[l] -= ids.size();
                }
                if (ids.size() < min_centres) {
                    padded[l] = 1;
                    thread_local std::vector<std::uint32_t> nb;
                    nearest_centres(c, min_centres, nb);
                    for (const std::uint32_t q : nb)
                        if (std::find(ids.begin(), ids.end(), q) == ids.end()) ids.push_back(q);
                    std::sort(ids.begin(), ids.end());
                }
                const Scalar h = alpha * nodes[leaf.node].side / 2;
                thread_local std::vector<Vec3> u;  // reused: no allocation per cell
                thread_local std::vector<Scalar> v;
                u.resize(ids.size());
                v.resize(ids.size());
                for (std::size_t k = 0; k < ids.size(); ++k) {
                    u[k] = (C[ids[k]] - c) / h;
                    v[k] = value[ids[k]] / h;
                }
                const auto info = detail::rbf_solve_cell(u, v, params.smoothing, leaf_w[l], leaf.poly);
                bad[l] = info.ill_conditioned ? 1 : 0;
            }, 1);
            progress.update(static_cast<double>(b1) / static_cast<double>(nl));
        }
        std::size_t total = 0;
        for (std::size_t l = 0; l < nl; ++l) {
            auto& leaf = data->leaves[l];
            if (!leaf.live) {
                ++res.stats.dead_cells;
                continue;
            }
            ++res.stats.live_cells;
            res.stats.ill_conditioned_cells += bad[l];
            res.stats.padded_cells += padded[l];
            res.stats.capped_cells += capped[l] > 0 ? 1 : 0;
            res.stats.capped_centres += capped[l];
            res.stats.max_points_per_cell = std::max(res.stats.max_points_per_cell, leaf_centres[l].size());
            leaf.begin = data->ids.size();
            data->ids.insert(data->ids.end(), leaf_centres[l].begin(), leaf_centres[l].end());
            data->weights.insert(data->weights.end(), leaf_w[l].begin(), leaf_w[l].end());
            leaf.end = data->ids.size();
            total += leaf_centres[l].size();
        }
        res.stats.mean_points_per_cell =
            res.stats.live_cells > 0 ? static_cast<double>(total) / static_cast<double>(res.stats.live_cells) : 0.0;
        res.timings = progress.finish();
        res.field.data_ = std::move(data);
    } catch (const detail::cancelled_exception&) {
        res.status = Status::cancelled;  // the field is set last: still empty
    }
    return res;
}

}  // namespace kintsugi
