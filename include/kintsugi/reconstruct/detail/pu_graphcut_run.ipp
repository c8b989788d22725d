// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file pu_graphcut_run.ipp
/// @brief The body of reconstruct_pu_graphcut (steps 1-7 per part, and the parts).
/// Included by pu_graphcut.hpp, or, with KINTSUGI_SEPARATE_STAGES, by the one file of
/// the program that compiles it (kintsugi/core/stages.hpp).

#include <kintsugi/reconstruct/pu_graphcut.hpp>

namespace kintsugi::detail {

/// Steps 1-7 on one part (validated, in its frame).
KINTSUGI_STAGE PUGraphcutResult pu_graphcut_part(std::vector<Vec3> pts, std::vector<Vec3> nrm, const PUGraphcutParams& params,
                                         const RunControl& control) {
    PUGraphcutResult res;
    res.points = pts.size();
    // Fractions of the overall progress per stage (measured on the 100K bunny).
    constexpr double pu_end = 0.35, tri_end = 0.7, cut_end = 0.85, mt_end = 0.92, smooth_end = 0.96;
    constexpr double handles_end = 0.97;
    // Step 8 needs the points and outward normals after the field has taken them.
    // (Copied in parallel: filling fresh pages costs page faults, 0.3 s on one core for
    // the 2M bench input, and they are served on both cores at once.)
    std::vector<Vec3> data_pts, data_nrm;
    if (params.refine_spacing > 0) {
        const Scalar sign = params.normals == NormalConvention::inward ? -1 : 1;
        data_pts.resize(pts.size());  // (Eigen's vectors are left uninitialised: no page touched)
        data_nrm.resize(nrm.size());
        parallel_for(0, pts.size(), [&](std::size_t i) {
            data_pts[i] = pts[i];
            data_nrm[i] = sign * nrm[i];
        }, 1 << 14);
    }

    // Steps 1-3: the PU field.
    PUFieldResult pu = PUField::build_from(std::move(pts), std::move(nrm),
                                           PUFieldParams{.max_level = params.max_level,
                                                         .epsilon = params.epsilon,
                                                         .seed = params.seed,
                                                         .inward_normals = params.normals == NormalConvention::inward,
                                                         .keep_octree = false,
                                                         .control = sub_control(control, 0.0, pu_end)});
    if (pu.status == Status::cancelled) {
        res.status = Status::cancelled;
        return res;
    }
    res.octree_cells = pu.octree_cells;
    res.supports = pu.supports;
    res.timings = pu.timings;
    const PUField& field = pu.field;
    const auto& sup = field.supports();

    return run_cancellable<PUGraphcutResult>(control, [&](Progress& progress) {
        // Step 4: regular triangulation of the supports (weights (s r)²) plus an outer layer
        // of plain points on a box enclosing every support ball: never hidden (no ball
        // contains them), never hiding a support, labelled outside so the surface closes.
        progress.stage("triangulation", pu_end, tri_end);
        const std::size_t ns = sup.size();
        std::vector<Vec3> sites(ns);
        std::vector<Scalar> radii(ns);
        BoundingBox balls;
        for (std::size_t i = 0; i < ns; ++i) {
            sites[i] = sup[i].center;
            radii[i] = params.triangulation_weight_scale * sup[i].radius;
            balls.extend(sup[i].center - Vec3::Constant(sup[i].radius));
            balls.extend(sup[i].center + Vec3::Constant(sup[i].radius));
        }
        const Scalar margin = Scalar(0.05) * balls.extent().maxCoeff();
        balls.min -= Vec3::Constant(margin);
        balls.max += Vec3::Constant(margin);
        const auto outer = box_surface_points(balls, 6);
        for (const Vec3& p : outer) {
            sites.push_back(p);
            radii.push_back(0);
        }
        // f at the vertices: the PU field at the support centres (eq. 1). A support
        // holding fewer than min_support_points input points, or points whose normals
        // disagree (an outlier's support, an empty one far from the data, a coarse one
        // full of outliers) carries no information about inside and outside, and with
        // many outliers such supports fill the empty space with wrong-signed values. At
        // those vertices, and at the outer layer, the terminal links use instead the
        // median signed distance to the tangent planes g_j of the nearest trusted
        // supports (centroids d_j nearest; Hoppe et al. 1992 with a median, so that one
        // trusted-looking outlier support cannot flip a region), which keeps the deep
        // inside and outside anchored by the terminal links of eq. 8-9.
        auto trusted_support = [&](const PUSupport& s) {
            return s.point_count >= params.min_support_points && s.coherence >= params.min_support_coherence;
        };
        // The PU field with the weights of untrusted supports scaled by untrusted_weight:
        // where a trusted support covers x it decides f(x), elsewhere the untrusted
        // supports still define a (continuous) field. Used for eq. 10 and the vertex
        // placement of step 6.
        std::vector<Scalar> factors(ns);
        for (std::size_t i = 0; i < ns; ++i)
            factors[i] = trusted_support(sup[i]) ? Scalar(1) : params.untrusted_weight;
        const PUField tfield = params.untrusted_weight == 1 ? field : field.reweighted(std::move(factors));
        std::vector<Index> trusted;
        std::vector<std::uint8_t> trusted_site(ns, 0);
        for (std::size_t i = 0; i < ns; ++i)
            if (trusted_support(sup[i])) {
                trusted.push_back(i);
                trusted_site[i] = 1;
            }
        if (trusted.empty())
            for (std::size_t i = 0; i < ns; ++i) trusted.push_back(i);

        // The terminal values of the untrusted sites and the outer layer first: they decide
        // which sites the triangulation needs (below). The median signed distance to the
        // tangent planes g_j of the 7 nearest trusted supports, in Morton order (nearby
        // queries read nearby memory of the kd-tree).
        const std::size_t n_sites = sites.size();
        std::vector<Scalar> site_f(n_sites), site_f_pu(n_sites);
        const std::vector<Index> along = morton_order(sites);
        {
            std::vector<Vec3> origins(trusted.size());
            for (std::size_t j = 0; j < trusted.size(); ++j) origins[j] = sup[trusted[j]].origin;
            const auto origin_tree = KdTree::adopt(std::move(origins));
            parallel_for(0, n_sites, [&](std::size_t j) {
                const std::size_t i = along[j];
                const bool outer = i >= ns;
                if (!outer && trusted_site[i]) return;
                constexpr std::size_t planes = 7;  // odd: the median is one plane's value
                const std::size_t kp = std::min(planes, trusted.size());
                // Most untrusted sites lie far from every trusted support, where a plain
                // k-nearest search visits much of the tree; the previous query's planes
                // (any kp of them bound the kp-th distance; the sites come along the
                // Morton curve, so they are near) bound it. The planes found are the same.
                thread_local std::vector<Neighbor> nbs;
                Scalar bound = std::numeric_limits<Scalar>::max();
                if (nbs.size() == kp) {
                    bound = 0;
                    for (const auto& nb : nbs)
                        bound = std::max(bound, (origin_tree.point(nb.index) - sites[i]).squaredNorm());
                }
                origin_tree.knn_within(sites[i], kp, bound, nbs);
                thread_local std::vector<Scalar> ds;
                ds.clear();
                for (const auto& nb : nbs) {
                    const PUSupport& s = sup[trusted[nb.index]];
                    ds.push_back(s.normal.dot(sites[i] - s.origin));
                }
                std::nth_element(ds.begin(), ds.begin() + ds.size() / 2, ds.end());
                site_f[i] = ds[ds.size() / 2];
                if (outer) site_f_pu[i] = std::min(site_f[i], Scalar(-1e-12));
            }, 1024);
        }
        progress.check();  // (the terminal values take seconds at 10M points)
        // The sites the triangulation needs (far_site_band): every trusted support, every
        // untrusted one whose terminal value lies within the band around the zero set, the
        // outer layer, and one far site per grid cell (the first in the cover's seeded
        // order, so the choice is deterministic).
        const std::vector<Index> kept = pu_thinned_sites(sites, ns, site_f, trusted_site,
                                                         params.labeling == Labeling::graphcut ? params.far_site_band : 0,
                                                         sup, balls.min, res.thinned_supports);
        std::vector<Vec3> kept_sites(kept.size());
        std::vector<Scalar> kept_radii(kept.size());
        for (std::size_t j = 0; j < kept.size(); ++j) {
            kept_sites[j] = sites[kept[j]];
            kept_radii[j] = radii[kept[j]];
        }

        // CGAL's insertion is sequential: what needs only the sites and the data is made
        // on the other threads meanwhile: step 8's inliers and the fit's samples first (their
        // memory is freed before the triangulation's peak, when its tets are listed), then
        // the PU field at the kept supports, in Morton order (2M bench input: this
        // stage and step 8 took 6.3 + 4.4 s, now 5.7 + 1.5 s; the stage's peak 978 -> 937
        // MB, that of the graph cut 1132 -> 1008 MB with the input's copy freed here;
        // output identical).
        RefineSamples fit_samples;
        RefineData fit_data;
        const bool refining = params.refine_spacing > 0 && params.refine_neighbors <= data_pts.size();
        PUTetMesh tm;
        parallel_invoke(
            [&] {
                if (refining) {
                    fit_samples = refine_data(tfield, data_pts, data_nrm, params.refine_neighbors, field.epsilon(),
                                              control.stop);
                    // The fit holds its own copy of the samples it uses; the input's is freed.
                    std::vector<Vec3>().swap(data_pts);
                    std::vector<Vec3>().swap(data_nrm);
                    // (With the heap kept, CGAL's cells reuse that memory instead: trimming
                    // here made them fault in new pages, and the stage's peak no lower.)
                    if (!heap_kept()) release_free_memory();
                }
                // The paper's sign (> 0 inside) from here on: f_pu, f, the graph and the labels.
                std::vector<std::uint8_t> is_kept(ns, 0);
                for (const Index i : kept)
                    if (i < ns) is_kept[i] = 1;
                std::vector<Index> which;
                which.reserve(kept.size());
                for (const Index i : along)
                    if (i < ns && is_kept[i]) which.push_back(i);
                std::vector<Vec3> xs(which.size());
                for (std::size_t j = 0; j < which.size(); ++j) xs[j] = sites[which[j]];
                const std::vector<Scalar> v = tfield.values(xs);
                for (std::size_t j = 0; j < which.size(); ++j) {
                    const Index i = which[j];
                    site_f_pu[i] = std::isnan(v[j]) ? Scalar(0) : -v[j];
                    if (trusted_site[i]) site_f[i] = site_f_pu[i];
                }
            },
            [&] {
                tm = regular_tet_mesh(kept_sites, kept_radii, progress, 0.0, 0.95);
                for (auto& s : tm.site) s = kept[s];
            });
        const std::size_t nv = tm.vertices.size();
        // Vertices are numbered by increasing site index, so the surviving supports come
        // first (vertex v < alive_supports is support tm.site[v]) and the outer layer last.
        const auto alive_supports = static_cast<std::size_t>(
            std::lower_bound(tm.site.begin(), tm.site.end(), ns) - tm.site.begin());
        std::vector<std::uint8_t> is_outer(nv, 0);
        std::fill(is_outer.begin() + static_cast<std::ptrdiff_t>(alive_supports), is_outer.end(), 1);
        res.hidden_supports = ns - res.thinned_supports - alive_supports;
        res.outer_vertices = nv - alive_supports;
        res.tetrahedra = tm.tets.size();
        res.graph_nodes = nv;
        res.graph_edges = tm.edges.size();
        std::vector<Scalar> f(nv), f_pu(nv);
        for (std::size_t v = 0; v < nv; ++v) {
            f[v] = site_f[tm.site[v]];
            f_pu[v] = site_f_pu[tm.site[v]];
        }
        // Per site, not read again (30 MB at 2M points).
        std::vector<Vec3>().swap(sites);
        std::vector<Scalar>().swap(radii);
        std::vector<Vec3>().swap(kept_sites);
        std::vector<Scalar>().swap(kept_radii);
        std::vector<Scalar>().swap(site_f);
        std::vector<Scalar>().swap(site_f_pu);

        // Step 5: labels. (The triangulation's freed cells go back to the system first:
        // core/memory.hpp.)
        progress.stage("graph_cut", tri_end, cut_end);
        release_free_memory();
        std::vector<std::uint8_t> inside;
        auto label = [&] {
            if (params.labeling == Labeling::graphcut) {
                inside = graphcut_labels(tm, f_pu, f, is_outer, params.k, res.cut_value, control);
                if (params.min_region_fraction > 0) {
                    std::vector<std::uint8_t> trusted_vertex(nv, 0);
                    for (std::size_t v = 0; v < alive_supports; ++v)
                        trusted_vertex[v] = trusted_support(sup[tm.site[v]]);
                    res.removed_regions = remove_small_regions(tm, is_outer, inside, params.min_region_fraction,
                                                               trusted_vertex, params.min_region_supports, control.stop);
                }
            } else {
                // PU alone: the sign of the field (outer layer outside).
                inside.resize(nv);
                for (std::size_t v = 0; v < nv; ++v) inside[v] = !is_outer[v] && f_pu[v] > 0;
            }
        };
        // Step 8's MLS surface and spacing, then the tets' canonical order, on the other
        // threads meanwhile: the graph cut runs on one and reads only the edges (2M bench
        // input: 0.36-0.43 s and 0.25-0.45 s beside its 0.8-1.1 s, both taken off the
        // triangulation stage, whose two sides keep both cores busy; output identical).
        parallel_invoke(
            [&] {
                if (refining) fit_data = refine_fit(std::move(fit_samples), control.stop);
                canonical_tet_order(tm.tets);
            },
            label);
        for (std::size_t v = 0; v < nv; ++v) {
            res.inside_vertices += inside[v];
            if (!is_outer[v] && (inside[v] != 0) != (f_pu[v] > 0)) ++res.sign_disagreements;
        }
        progress.check();

        // Step 6: marching tetrahedra with the same-sign rule.
        progress.stage("marching_tetrahedra", cut_end, mt_end);
        std::vector<std::array<Index, 2>>().swap(tm.edges);  // the graph's; no later step reads them
        release_free_memory();
        MarchingTetrahedraParams mp;
        mp.tets_positively_oriented = true;
        mp.control.stop = control.stop;
        MarchingTetrahedraResult mt;
        {
            const std::vector<Tet> tets = widened_tets(tm);
            mt = marching_tetrahedra(tm.vertices, tets, inside, f_pu, mp);
        }
        if (mt.status == Status::cancelled) throw cancelled_exception{};
        (void)place_on_zero_set(tfield, tm.vertices, f_pu, mt, mp.min_edge_fraction, 8, progress);
        res.same_sign_vertices = mt.same_sign_vertices;

        // Step 7: selective Taubin smoothing of the vertices on same-sign edges and on
        // edges with an end whose support holds fewer than 10 input points; before it,
        // the thin-plate fill of the unsupported vertices (fill_radius_fraction).
        progress.stage("smoothing", mt_end, smooth_end);
        constexpr std::size_t few_points = 10;
        auto sparse = [&](Index v) { return is_outer[v] || sup[tm.site[v]].point_count < few_points; };
        std::vector<std::uint8_t> movable(mt.mesh.vertices.size(), 0);
        for (std::size_t i = 0; i < movable.size(); ++i) {
            const auto& e = mt.vertex_edges[i];
            movable[i] = mt.same_sign[i] || sparse(e[0]) || sparse(e[1]);
        }
        // Unsupported vertices (hole fills, see fill_radius_fraction): farther than
        // fill_radius_fraction x r_i from the centre of every trusted support.
        std::vector<std::uint8_t> unsupported(mt.mesh.vertices.size(), 0);
        if (params.fill_radius_fraction > 0)
            mark_unsupported(mt.mesh.vertices, sup, trusted, params.fill_radius_fraction, unsupported, control.stop);
        // The fill first (from the placed vertices around it), then the selective
        // smoothing of the other movable vertices, which sees the filled positions.
        const MeshTopology topo(mt.mesh.vertices.size(), mt.mesh.faces);
        progress.check();
        res.filled_vertices = biharmonic_fill(mt.mesh.vertices, topo, unsupported);
        progress.check();
        for (std::size_t i = 0; i < movable.size(); ++i) movable[i] = movable[i] && !unsupported[i];
        if (params.smoothing_iterations > 0) {
            TaubinParams tp;
            tp.iterations = params.smoothing_iterations;
            res.smoothed_vertices = taubin_smooth(mt.mesh.vertices, topo, movable, tp, progress);
        }
        // Topological noise: handles and tunnels a loop of at most max_handle_loop x the
        // median edge goes around (kintsugi::remove_small_handles).
        progress.stage("handles", smooth_end, handles_end);
        if (params.max_handle_loop > 0 && !topo.edges().empty()) {
            HandleParams hp;
            hp.max_loop_length = params.max_handle_loop * upper_median(edge_lengths(mt.mesh.vertices, topo));
            hp.control = sub_control(control, smooth_end, handles_end);
            // The mesh is closed and manifold by construction; should smoothing ever
            // flatten a face to zero area, the cut is skipped rather than the run failed.
            const TopologyReport rep = topology_report(mt.mesh.vertices, mt.mesh.faces);
            if (rep.closed && rep.manifold && rep.degenerate_faces == 0 && rep.isolated_vertices == 0) {
                const HandleResult hr = remove_small_handles_indexed(mt.mesh.vertices, mt.mesh.faces, hp, rep.genus,
                                                                     rep.components,
                                                                     "kintsugi::reconstruct_pu_graphcut: ");
                if (hr.status == Status::cancelled) throw cancelled_exception{};
                res.handles_removed = hr.handles_removed;
            }
        }
        // Step 8 (ours): detail at the samples' resolution (refine_spacing).
        progress.stage("refine", handles_end, 1.0);
        if (refining) {
            const RefineStats rs = refine_to_samples(mt.mesh, fit_data, tfield, params.refine_spacing, field.epsilon(),
                                                     sup, trusted, params.fill_radius_fraction, progress);
            res.refined_vertices = rs.projected;
            res.refine_noise_ratio = rs.noise_ratio;
            res.refine_neighbors_used = rs.neighbors;
            res.refine_budget_reached = rs.budget_reached;
        }
        res.mesh = std::move(mt.mesh);
        auto t = progress.finish();
        res.timings.insert(res.timings.end(), t.begin(), t.end());
        res.status = Status::ok;
        return std::move(res);
    });
}

/// The whole run: validation, the separated parts (part_gap_fraction), each
/// reconstructed in its own frame (PUFrame: the caller's coordinates when safe, else
/// recentred and scaled by a power of two) and mapped back, the meshes concatenated.
KINTSUGI_STAGE PUGraphcutResult pu_graphcut_run(std::vector<Vec3> pts, std::vector<Vec3> nrm, const PUGraphcutParams& params) {
    pu_graphcut_validate(pts, nrm, params);
    const std::string fn = "kintsugi::reconstruct_pu_graphcut: ";
    const std::size_t n = pts.size();
    std::vector<std::vector<Index>> groups = pu_separated_parts(pts, params.part_gap_fraction);
    const std::size_t min_points = std::max<std::size_t>(
        {static_cast<std::size_t>(std::ceil(params.min_part_fraction * static_cast<Scalar>(n))),
         params.min_support_points, 4});
    std::vector<std::size_t> chosen;
    for (std::size_t g = 0; g < groups.size(); ++g)
        if (groups.size() == 1 || groups[g].size() >= min_points) chosen.push_back(g);
    if (chosen.empty())
        throw invalid_input(fn + "no part of the input can be reconstructed: the points fall into " +
                            std::to_string(groups.size()) + " groups separated by empty space (gaps wider than " +
                            "part_gap_fraction = " + std::to_string(params.part_gap_fraction) +
                            " of their extent) and none holds " + std::to_string(min_points) +
                            " points or more (min_part_fraction of the input, at least min_support_points); "
                            "remove the scattered points, or set part_gap_fraction = 0 to reconstruct them in one box");
    std::size_t total = 0;
    for (const std::size_t g : chosen) total += groups[g].size();

    PUGraphcutResult res;
    res.points = n;
    res.far_points = n - total;
    std::string problem;  // why the last part left out gave nothing
    std::size_t done = 0;
    double last = -1;
    for (const std::size_t g : chosen) {
        const std::vector<Index>& ids = groups[g];
        const double a = static_cast<double>(done) / static_cast<double>(total);
        done += ids.size();
        const double b = static_cast<double>(done) / static_cast<double>(total);
        const PUFrame frame = PUFrame::of(pts, ids);
        std::vector<Vec3> pp, nn;
        if (ids.size() == n) {
            pp = std::move(pts);
            nn = std::move(nrm);
        } else {
            pp.reserve(ids.size());
            nn.reserve(ids.size());
            for (const Index i : ids) {
                pp.push_back(pts[i]);
                nn.push_back(nrm[i]);
            }
        }
        if (!frame.identity)
            for (Vec3& x : pp) x = frame.to_frame(x);
        pu_safe_normals(nn);
        if (std::string bad = pu_graphcut_validate_part(pp, nn, params); !bad.empty()) {
            if (chosen.size() == 1) {
                if (res.far_points > 0)
                    bad += " (" + std::to_string(res.far_points) + " points far from the others were left out)";
                throw invalid_input(bad);
            }
            problem = bad;
            res.far_points += ids.size();
            continue;
        }
        const RunControl control = chosen.size() == 1 ? params.control : part_control(params.control, a, b, last);
        PUGraphcutResult r = pu_graphcut_part(std::move(pp), std::move(nn), params, control);
        if (r.status == Status::cancelled) {
            return cancelled_result<PUGraphcutResult>();
        }
        if (r.mesh.faces.empty()) {
            problem = fn + "the surface is empty: the labelling put none of the " + std::to_string(r.supports) +
                      " supports inside, so the points do not enclose a volume at this resolution; check that the "
                      "normals point out of the object (or set normals = NormalConvention::inward), or raise "
                      "max_level / lower epsilon";
            res.far_points += ids.size();
            continue;
        }
        for (Vec3& v : r.mesh.vertices) {
            v = frame.from_frame(v);
            if (!v.allFinite())
                throw invalid_input(fn + "the surface reaches beyond the largest finite double (the points lie too "
                                         "close to it); scale the points down first");
        }
        const Index base = res.mesh.vertices.size();
        res.mesh.vertices.insert(res.mesh.vertices.end(), r.mesh.vertices.begin(), r.mesh.vertices.end());
        for (auto f : r.mesh.faces) {
            for (auto& v : f) v += base;
            res.mesh.faces.push_back(f);
        }
        ++res.parts;
        using R = PUGraphcutResult;
        for (std::size_t R::*count :
             {&R::octree_cells, &R::supports, &R::hidden_supports, &R::outer_vertices, &R::tetrahedra,
              &R::graph_nodes, &R::graph_edges, &R::inside_vertices, &R::sign_disagreements, &R::same_sign_vertices,
              &R::smoothed_vertices, &R::removed_regions, &R::filled_vertices, &R::handles_removed,
              &R::refined_vertices, &R::thinned_supports})
            res.*count += r.*count;
        res.cut_value += r.cut_value;
        res.refine_noise_ratio = std::max(res.refine_noise_ratio, r.refine_noise_ratio);
        res.refine_neighbors_used = std::max(res.refine_neighbors_used, r.refine_neighbors_used);
        res.refine_budget_reached = res.refine_budget_reached || r.refine_budget_reached;
        for (const StageTiming& t : r.timings) {
            auto it = std::find_if(res.timings.begin(), res.timings.end(),
                                   [&](const StageTiming& u) { return u.stage == t.stage; });
            if (it == res.timings.end()) res.timings.push_back(t);
            else it->seconds += t.seconds;
        }
    }
    if (res.mesh.faces.empty()) {
        if (groups.size() > 1)
            problem += " (the points fall into " + std::to_string(groups.size()) +
                       " parts separated by empty space; " + std::to_string(chosen.size()) + " hold " +
                       std::to_string(min_points) + " points or more and none of them gave a surface)";
        throw invalid_input(problem);
    }
    if (chosen.size() > 1 && params.control.progress && !params.control.progress(ProgressEvent{"done", 1.0})) {
        return cancelled_result<PUGraphcutResult>();
    }
    res.status = Status::ok;
    return res;
}

}  // namespace kintsugi::detail
