// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file complete_indexed.ipp
/// @brief The body of complete_holes_example_based (on its working copy).
/// Included by example_completion.hpp, or, with KINTSUGI_SEPARATE_STAGES, by the one
/// file of the program that compiles it (kintsugi/core/stages.hpp).

#include <kintsugi/complete/example_completion.hpp>

namespace kintsugi::detail::completion {

KINTSUGI_STAGE CompletionResult complete_indexed(IndexedMesh& work, const CompletionParams& params, const std::string& fn,
                                                 std::vector<Vec3>& new_pos, std::vector<Face>& new_faces) {
    const std::size_t nv0 = work.vertices.size(), nf0 = work.faces.size();
    CompletionResult out;
    detail::Progress progress(params.control);
    try {
        // ---- holes
        progress.stage("detect", 0.0, 0.02);
        std::vector<std::vector<Index>> selected;
        if (!params.holes.empty()) {
            selected = params.holes;
        } else {
            const auto loops = find_boundary_loops(work, HoleParams{params.outer_border_extent});
            BoundingBox box;
            for (const Vec3& p : work.vertices) box.extend(p);
            for (const auto& l : loops.loops) {
                if (l.outer || l.extent > params.max_hole_size * box.diagonal()) continue;
                if (params.max_hole_edges > 0 && l.vertices.size() > params.max_hole_edges) continue;
                selected.push_back(l.vertices);
            }
        }
        // ---- initial patch
        progress.stage("initial patch", 0.02, 0.08);
        IndexedMesh filled = work;
        std::vector<std::uint8_t> unfilled(selected.size(), 0);
        // The paper's fan from the centroid of each loop not skipped.
        auto add_fans = [&](IndexedMesh& m, const std::vector<std::uint8_t>& skip) {
            const HalfedgeMesh base = HalfedgeMesh::from_faces(work.vertices, work.faces);
            for (std::size_t li = 0; li < selected.size(); ++li) {
                if (skip[li]) continue;
                auto l = selected[li];
                const Index hb = base.find_halfedge(l[1], l[0]);
                if (hb == HalfedgeMesh::invalid || !base.is_boundary_halfedge(hb)) std::reverse(l.begin(), l.end());
                Vec3 c = Vec3::Zero();
                for (const Index v : l) c += work.vertices[v];
                c /= static_cast<Scalar>(l.size());
                const Index cv = m.vertices.size();
                m.vertices.push_back(c);
                for (std::size_t i = 0; i < l.size(); ++i) m.faces.push_back({l[i], l[(i + 1) % l.size()], cv});
            }
        };
        if (!selected.empty()) {
            if (params.initial == InitialPatch::thin_plate) {
                FillParams fp;
                fp.control.stop = params.control.stop;
                FillResult fr;
                try {
                    fr = fill_holes(filled, selected, fp);
                } catch (const invalid_input& e) {
                    throw invalid_input(fn + e.what());
                }
                if (fr.status == Status::cancelled) throw detail::cancelled_exception{};
                for (const Index u : fr.unfilled_holes) unfilled[u] = 1;
            } else {
                // Validate (and orient) the loops through fill_holes without refinement.
                IndexedMesh probe = work;
                FillParams fp;
                fp.max_rounds = 1;
                fp.split_factor = 4;
                fp.fair = false;
                try {
                    const FillResult fr = fill_holes(probe, selected, fp);
                    for (const Index u : fr.unfilled_holes) unfilled[u] = 1;
                } catch (const invalid_input& e) {
                    throw invalid_input(fn + e.what());
                }
                add_fans(filled, unfilled);
            }
        }
        for (std::size_t li = 0; li < selected.size(); ++li)
            if (unfilled[li]) out.unfilled_holes.push_back(selected[li]);
        out.filled_holes = selected.size() - out.unfilled_holes.size();

        // l_ave: mean edge length of the data faces.
        {
            Scalar sum = 0;
            std::size_t cnt = 0;
            for (Index f = 0; f < nf0; ++f)
                for (int k = 0; k < 3; ++k) {
                    const Face& t = work.faces[f];
                    sum += (work.vertices[t[(k + 1) % 3]] - work.vertices[t[k]]).norm();
                    ++cnt;
                }
            out.mean_edge_length = sum / static_cast<Scalar>(cnt);
        }
        const Scalar lave = out.mean_edge_length;

        // The filled holes (in the order of the selected loops) with what the explosion
        // guard needs: the rim's hole, each hole's reach (mesh/holes.hpp) and vertex bound.
        constexpr std::uint32_t no_hole = std::numeric_limits<std::uint32_t>::max();
        std::vector<std::size_t> filled_index;  // filled hole -> selected loop
        for (std::size_t li = 0; li < selected.size(); ++li)
            if (!unfilled[li]) filled_index.push_back(li);
        const std::size_t nh = filled_index.size();
        std::vector<std::uint32_t> rim_hole(nv0, no_hole);
        std::vector<BoundingBox> reach(nh);
        std::vector<std::size_t> max_patch(nh);
        for (std::size_t h = 0; h < nh; ++h) {
            const auto& l = selected[filled_index[h]];
            for (const Index v : l) rim_hole[v] = static_cast<std::uint32_t>(h);
            reach[h] = detail::hole_reach(l, work.vertices);
            Scalar perimeter = 0;
            for (std::size_t i = 0; i < l.size(); ++i)
                perimeter += (work.vertices[l[(i + 1) % l.size()]] - work.vertices[l[i]]).norm();
            // A flat disk of this perimeter, about 2 / (sqrt 3 l_ave^2) vertices per unit area.
            const Scalar disk = perimeter * perimeter / (4 * std::numbers::pi_v<Scalar>) /
                                (std::sqrt(Scalar(3)) / 2 * lave * lave);
            const Scalar bound = std::ceil(params.max_patch_growth * (disk + static_cast<Scalar>(l.size())));
            max_patch[h] = std::isfinite(bound) && bound < Scalar(1e15) ? static_cast<std::size_t>(bound)
                                                                          : std::size_t(1e15);
        }
        out.hole_status.assign(nh, HoleStatus::completed);
        // Per vertex slot of a working mesh: the filled hole whose patch holds it (the
        // patch faces joined through shared vertices, named by their rim), or no_hole.
        auto patch_holes = [&](const HalfedgeMesh& hm) {
            const std::size_t cap = hm.vertex_capacity();
            detail::DisjointSets<Index> sets(cap);
            for (Index f = nf0; f < hm.face_capacity(); ++f) {
                if (hm.is_removed_face(f)) continue;
                sets.unite(hm.face_vertex(f, 0), hm.face_vertex(f, 1));
                sets.unite(hm.face_vertex(f, 0), hm.face_vertex(f, 2));
            }
            std::vector<std::uint32_t> comp(cap, no_hole), lab(cap, no_hole);
            for (Index v = 0; v < nv0; ++v)
                if (rim_hole[v] != no_hole) comp[sets.find(v)] = rim_hole[v];
            for (Index v = 0; v < cap; ++v)
                if (!hm.is_removed_vertex(v)) lab[v] = comp[sets.find(v)];
            return lab;
        };

        // Data-only structures: faces per vertex, kd-tree over the data vertices.
        std::vector<std::vector<Index>> vf(nv0);
        for (Index f = 0; f < nf0; ++f)
            for (const Index v : work.faces[f]) vf[v].push_back(f);
        const KdTree data_tree = KdTree::adopt(work.vertices);
        std::vector<Vec3> data_normal(nv0, Vec3::Zero());
        for (const Face& t : work.faces) {
            const Vec3 c = (work.vertices[t[1]] - work.vertices[t[0]]).cross(work.vertices[t[2]] - work.vertices[t[0]]);
            for (const Index v : t) data_normal[v] += c;
        }
        for (Vec3& n : data_normal)
            if (n.norm() > 0) n.normalize();
        const Scalar rb2 = (params.b_radius * lave) * (params.b_radius * lave);

        State st;
        std::vector<Vec3> residual_at;                     // data vertices of the last Ω'
        std::vector<std::pair<Scalar, Scalar>> residual;   // their (R_e, R_q); (0, 0) = no evidence
        // One run of the schedule; when the guard fires, the holes it names are reverted
        // (their thin-plate patch frozen) and the run starts again from the initial patch.
        for (;;) {
            st = State{};
            st.nv0 = nv0;
            st.nf0 = nf0;
            st.hm = HalfedgeMesh::from_faces(filled.vertices, filled.faces);
            st.grow();
            st.fixed_face.assign(st.hm.face_capacity(), 0);
            {
                const auto lab = patch_holes(st.hm);
                auto reverted = [&](Index v) {
                    return lab[v] != no_hole && out.hole_status[lab[v]] != HoleStatus::completed;
                };
                for (Index v = nv0; v < st.omega.size(); ++v) st.omega[v] = !reverted(v);
                for (Index f = nf0; f < st.hm.face_capacity(); ++f)
                    st.fixed_face[f] = reverted(st.hm.face_vertex(f, 0));
            }
            bool any_patch_vertex = false;
            for (Index v = nv0; v < st.omega.size(); ++v) any_patch_vertex = any_patch_vertex || st.omega[v];
            std::size_t patch_cap = 0;  // the remesh stops splitting beyond the bounds' sum
            for (std::size_t h = 0; h < nh; ++h)
                if (out.hole_status[h] == HoleStatus::completed) patch_cap += max_patch[h];

            // The guard: names each hole with a patch vertex outside its reach (or not
            // finite) or more patch vertices than its bound; false when it named any.
            std::vector<std::pair<std::size_t, HoleStatus>> fired;
            auto guard = [&]() {
                const auto lab = patch_holes(st.hm);
                std::vector<std::size_t> count(nh, 0);
                std::vector<std::uint8_t> far(nh, 0);
                for (Index v = nv0; v < st.hm.vertex_capacity(); ++v) {
                    if (st.hm.is_removed_vertex(v) || !st.omega[v] || lab[v] == no_hole) continue;
                    ++count[lab[v]];
                    if (!detail::within_reach(reach[lab[v]], st.hm.position(v))) far[lab[v]] = 1;
                }
                for (std::size_t h = 0; h < nh; ++h) {
                    if (out.hole_status[h] != HoleStatus::completed) continue;
                    if (far[h])
                        fired.emplace_back(h, HoleStatus::reverted_left_reach);
                    else if (count[h] > max_patch[h])
                        fired.emplace_back(h, HoleStatus::reverted_vertex_bound);
                }
                return fired.empty();
            };
            // A non-finite energy names every hole still minimised (E is one sum over them).
            auto energy_ok = [&](Scalar e) {
                if (std::isfinite(e)) return true;
                for (std::size_t h = 0; h < nh; ++h)
                    if (out.hole_status[h] == HoleStatus::completed) fired.emplace_back(h, HoleStatus::reverted_energy);
                return fired.empty();
            };

            const std::size_t nlev = any_patch_vertex ? params.levels.size() : 0;
            out.energy.clear();
            residual_at.clear();
            residual.clear();
            for (std::size_t level = 0; level < nlev; ++level) {
                const CompletionLevel& L = params.levels[level];
                const double f0 = 0.08 + 0.9 * static_cast<double>(level) / static_cast<double>(nlev);
                const double f1 = 0.08 + 0.9 * static_cast<double>(level + 1) / static_cast<double>(nlev);
                progress.stage("level " + std::to_string(level + 1), f0, f1);
                const Scalar A = L.a_radius * lave, A2 = A * A, miss2 = A2;
                st.remesh(L.split_above * lave, L.merge_below * lave, patch_cap);
                progress.check();
                if (!guard()) break;

                // ---- the candidate pool Φ: data vertices whose sphere A holds no patch
                // vertex and no boundary, at most max_candidates of them.
                std::vector<Index> pool;
                {
                    std::vector<Vec3> avoid;
                    for (Index v = 0; v < st.hm.vertex_capacity(); ++v) {
                        if (st.hm.is_removed_vertex(v)) continue;
                        if (st.omega[v] || st.hm.is_boundary_vertex(v)) avoid.push_back(st.hm.position(v));
                    }
                    // seam vertices (data vertices next to the patch)
                    std::vector<Index> ring;
                    for (Index v = 0; v < nv0; ++v) {
                        st.hm.vertex_ring(v, ring);
                        for (const Index u : ring)
                            if (st.omega[u]) {
                                avoid.push_back(work.vertices[v]);
                                break;
                            }
                    }
                    const KdTree avoid_tree = KdTree::adopt(std::move(avoid));
                    std::vector<std::uint8_t> ok(nv0, 0);
                    parallel_for(0, nv0, [&](std::size_t v) {
                        if (vf[v].empty()) return;
                        std::vector<Neighbor> nn;
                        avoid_tree.knn(work.vertices[v], 1, nn);
                        ok[v] = nn.empty() || nn[0].squared_distance > A2;
                    });
                    for (Index v = 0; v < nv0; ++v)
                        if (ok[v]) pool.push_back(v);
                    if (pool.size() < 8) {  // a tiny mesh: every data vertex off the boundary
                        pool.clear();
                        for (Index v = 0; v < nv0; ++v)
                            if (!vf[v].empty() && !st.hm.is_boundary_vertex(v)) pool.push_back(v);
                    }
                    if (pool.size() > params.max_candidates) {
                        std::mt19937_64 rng(params.seed * 1000003ULL + level);
                        for (std::size_t i = 0; i < params.max_candidates; ++i) {
                            std::uniform_int_distribution<std::size_t> pick(i, pool.size() - 1);
                            std::swap(pool[i], pool[pick(rng)]);
                        }
                        pool.resize(params.max_candidates);
                        std::sort(pool.begin(), pool.end());
                    }
                }
                if (pool.empty()) break;
                progress.check();

                // ---- frames and height maps of the candidates
                std::vector<LocalFrame> pframe(pool.size());
                HeightMaps maps;
                maps.cell = lave / 2;
                maps.inv_cell = 1 / maps.cell;
                maps.r = static_cast<int>(std::ceil(A / maps.cell)) + 1;
                maps.g = 2 * maps.r + 1;
                maps.h.assign(pool.size() * static_cast<std::size_t>(maps.g * maps.g), std::numeric_limits<float>::quiet_NaN());
                parallel_for(
                    0, pool.size(),
                    [&](std::size_t c) {
                        std::vector<Neighbor> nb;
                        const Index pv = pool[c];
                        pframe[c] = fit_frame(work.vertices[pv], data_normal[pv], data_tree, rb2, nb);
                        const LocalFrame& F = pframe[c];
                        const Scalar reach = (maps.r + 1) * maps.cell * Scalar(1.5) + lave;
                        data_tree.radius_search_squared(F.o, reach * reach, nb, false);
                        // Each face once: through the first of its corners within reach.
                        std::vector<Index> faces;
                        auto within = [&](Index v) { return (work.vertices[v] - F.o).squaredNorm() <= reach * reach; };
                        for (const Neighbor& n : nb)
                            for (const Index f : vf[n.index]) {
                                const Face& t = work.faces[f];
                                const bool first = t[0] == n.index || (t[1] == n.index && !within(t[0])) ||
                                                   (t[2] == n.index && !within(t[0]) && !within(t[1]));
                                if (first) faces.push_back(f);
                            }
                        float* H = maps.h.data() + c * static_cast<std::size_t>(maps.g * maps.g);
                        for (const Index f : faces) {
                            const Face& t = work.faces[f];
                            const Vec3 a = F.local(work.vertices[t[0]]), b = F.local(work.vertices[t[1]]),
                                       d = F.local(work.vertices[t[2]]);
                            const Scalar den = (b.x() - a.x()) * (d.y() - a.y()) - (d.x() - a.x()) * (b.y() - a.y());
                            if (!(std::abs(den) > 1e-12 * lave * lave)) continue;
                            const Scalar lo_u = std::min({a.x(), b.x(), d.x()}), hi_u = std::max({a.x(), b.x(), d.x()});
                            const Scalar lo_v = std::min({a.y(), b.y(), d.y()}), hi_v = std::max({a.y(), b.y(), d.y()});
                            const int i0 = std::max(0, static_cast<int>(std::ceil(lo_u * maps.inv_cell + maps.r)));
                            const int i1 = std::min(maps.g - 1, static_cast<int>(std::floor(hi_u * maps.inv_cell + maps.r)));
                            const int j0 = std::max(0, static_cast<int>(std::ceil(lo_v * maps.inv_cell + maps.r)));
                            const int j1 = std::min(maps.g - 1, static_cast<int>(std::floor(hi_v * maps.inv_cell + maps.r)));
                            for (int i = i0; i <= i1; ++i)
                                for (int j = j0; j <= j1; ++j) {
                                    const Scalar u = (i - maps.r) * maps.cell, v = (j - maps.r) * maps.cell;
                                    const Scalar l1 = ((b.x() - u) * (d.y() - v) - (d.x() - u) * (b.y() - v)) / den;
                                    const Scalar l2 = ((d.x() - u) * (a.y() - v) - (a.x() - u) * (d.y() - v)) / den;
                                    const Scalar l3 = 1 - l1 - l2;
                                    if (l1 < -1e-9 || l2 < -1e-9 || l3 < -1e-9) continue;
                                    const Scalar w = l1 * a.z() + l2 * b.z() + l3 * d.z();
                                    float& cellh = H[i * maps.g + j];
                                    if (std::isnan(cellh) || std::abs(w) < std::abs(cellh)) cellh = static_cast<float>(w);
                                }
                        }
                    },
                    16);
                progress.check();
                const std::size_t top =
                    std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(params.top_percent / 100 * static_cast<Scalar>(pool.size()))));
                for (auto& m : st.match) m = Match{};

                // ---- one evaluation: Ω', frames, search (i), energy (eq. 1)
                struct Eval {
                    std::vector<Index> active;           // vertices of Ω' in the energy, increasing
                    std::vector<LocalFrame> frame;       // per active
                    std::vector<Scalar> weight;          // per active
                    std::vector<Index> slot;             // per vertex slot: position in active, or invalid
                    Scalar energy = 0;
                };
                auto evaluate = [&](Eval& ev) {
                    HalfedgeMesh& hm = st.hm;
                    const std::size_t cap = hm.vertex_capacity();
                    std::vector<Index> live;
                    std::vector<Vec3> lp;
                    for (Index v = 0; v < cap; ++v)
                        if (!hm.is_removed_vertex(v)) {
                            live.push_back(v);
                            lp.push_back(hm.position(v));
                        }
                    // Vertex normals (area weighted).
                    std::vector<Vec3> vn(cap, Vec3::Zero());
                    for (Index f = 0; f < hm.face_capacity(); ++f) {
                        if (hm.is_removed_face(f)) continue;
                        const Index a = hm.face_vertex(f, 0), b = hm.face_vertex(f, 1), c = hm.face_vertex(f, 2);
                        const Vec3 n = (hm.position(b) - hm.position(a)).cross(hm.position(c) - hm.position(a));
                        vn[a] += n;
                        vn[b] += n;
                        vn[c] += n;
                    }
                    for (Vec3& n : vn)
                        if (n.norm() > 0) n.normalize();
                    const KdTree tree = KdTree::adopt(lp);
                    // m: links from the hole boundary (BFS from data vertices into Ω).
                    std::vector<std::uint32_t> m(cap, std::numeric_limits<std::uint32_t>::max());
                    std::vector<Index> queue, ring;
                    for (const Index v : live)
                        if (!st.omega[v]) m[v] = 0;
                    for (const Index v : live) {
                        if (!st.omega[v]) continue;
                        hm.vertex_ring(v, ring);
                        for (const Index u : ring)
                            if (!st.omega[u]) {
                                m[v] = 1;
                                queue.push_back(v);
                                break;
                            }
                    }
                    for (std::size_t qi = 0; qi < queue.size(); ++qi) {
                        const Index v = queue[qi];
                        hm.vertex_ring(v, ring);
                        for (const Index u : ring)
                            if (st.omega[u] && m[u] == std::numeric_limits<std::uint32_t>::max()) {
                                m[u] = m[v] + 1;
                                queue.push_back(u);
                            }
                    }
                    // Ω': within A of a patch vertex; fixed ones thinned.
                    std::vector<std::uint8_t> in_omega_p(cap, 0);
                    std::vector<Neighbor> nb;
                    for (const Index v : live) {
                        if (!st.omega[v]) continue;
                        tree.radius_search_squared(hm.position(v), A2, nb, false);
                        for (const Neighbor& n : nb) in_omega_p[live[n.index]] = 1;
                    }
                    // Fixed vertices whose sphere A holds more than dense_ratio times what a mesh at
                    // l_ave holds there keep that share only (the bound on what one vertex reads,
                    // max_ssd_samples, keeps each one's cost; this keeps their number).
                    std::vector<Scalar> keep(cap, 1);
                    {
                        const Scalar usual = dense_ratio * uniform_vertices_within(A / lave);
                        std::vector<Index> fixed_in;
                        for (const Index v : live)  // those the levels' thinning keeps
                            if (in_omega_p[v] && !st.omega[v] && !(hash01(v, level, params.seed) < L.thin_fraction))
                                fixed_in.push_back(v);
                        parallel_for(0, fixed_in.size(), [&](std::size_t i) {
                            thread_local std::vector<Neighbor> around;
                            tree.radius_search_squared(hm.position(fixed_in[i]), A2, around, false);
                            const Scalar n = static_cast<Scalar>(around.size());
                            if (n > usual) keep[fixed_in[i]] = usual / n;
                        }, 64);
                    }
                    ev.active.clear();
                    ev.slot.assign(cap, HalfedgeMesh::invalid);
                    for (const Index v : live) {
                        if (!in_omega_p[v]) continue;
                        if (!st.omega[v] && hash01(v, level, params.seed) < L.thin_fraction) continue;
                        if (keep[v] < 1 && hash01(v, level + nlev, params.seed) >= keep[v]) continue;
                        ev.slot[v] = ev.active.size();
                        ev.active.push_back(v);
                    }
                    const std::size_t na = ev.active.size();
                    ev.frame.resize(na);
                    ev.weight.resize(na);
                    std::vector<Scalar> e(na, 0);
                    parallel_for(
                        0, na,
                        [&](std::size_t ai) {
                            const Index v = ev.active[ai];
                            std::vector<Neighbor> nbl;
                            ev.frame[ai] = fit_frame(hm.position(v), vn[v], tree, rb2, nbl);
                            const LocalFrame& F = ev.frame[ai];
                            ev.weight[ai] = st.omega[v] ? std::pow(params.s, -static_cast<Scalar>(
                                                                          m[v] == std::numeric_limits<std::uint32_t>::max() ? 1 : m[v]))
                                                        : Scalar(1);
                            tree.radius_search_squared(hm.position(v), A2, nbl, true);
                            // At most max_ssd_samples of them, spread evenly by distance.
                            const std::size_t ns = std::min(nbl.size(), max_ssd_samples);
                            std::vector<Sample> S(ns);
                            for (std::size_t k = 0; k < ns; ++k) {
                                const Index u = live[nbl[spread(k, nbl.size(), ns)].index];
                                S[k] = {F.local(hm.position(u)), F.local_dir(vn[u])};
                            }
                            const std::size_t stride = std::max<std::size_t>(1, S.size() / params.search_samples);
                            // Candidates by curvature likeness (eq. 9).
                            std::vector<std::pair<Scalar, std::uint32_t>> K(pool.size());
                            for (std::size_t c = 0; c < pool.size(); ++c) {
                                const Scalar a = F.k1 - pframe[c].k1, b = F.k2 - pframe[c].k2;
                                K[c] = {a * a + b * b, static_cast<std::uint32_t>(c)};
                            }
                            const std::size_t nt = std::min(top, K.size());
                            std::nth_element(K.begin(), K.begin() + static_cast<std::ptrdiff_t>(nt - 1), K.end());
                            std::sort(K.begin(), K.begin() + static_cast<std::ptrdiff_t>(nt));
                            // Rank by the SSD of search_samples vertices of A (two Newton
                            // steps), keep the best `keep`, then their exact SSD.
                            constexpr std::size_t keep = 8;
                            std::array<std::pair<Scalar, Match>, keep> best;
                            best.fill({std::numeric_limits<Scalar>::infinity(), Match{}});
                            for (std::size_t ti = 0; ti < nt; ++ti) {
                                const std::uint32_t c = K[ti].second;
                                for (int var = 0; var < 4; ++var) {
                                    const Scalar sc =
                                        ssd(maps, maps.map(c), S.data(), S.size(), stride, var, A, miss2, best[keep - 1].first, 2);
                                    if (sc < best[keep - 1].first) {
                                        std::size_t k = keep - 1;
                                        for (; k > 0 && best[k - 1].first > sc; --k) best[k] = best[k - 1];
                                        best[k] = {sc, Match{c, static_cast<std::uint8_t>(var)}};
                                    }
                                }
                            }
                            Scalar bs = std::numeric_limits<Scalar>::infinity();
                            Match bm;
                            auto consider = [&](const Match& mm) {
                                if (!mm.valid()) return;
                                const Scalar sc = ssd(maps, maps.map(mm.cand), S.data(), S.size(), 1, mm.variant, A, miss2);
                                if (sc < bs || (sc == bs && (mm.cand < bm.cand || (mm.cand == bm.cand && mm.variant < bm.variant)))) {
                                    bs = sc;
                                    bm = mm;
                                }
                            };
                            consider(st.match[v]);
                            for (const auto& b : best) consider(b.second);
                            st.match[v] = bm;
                            e[ai] = std::isfinite(bs) ? bs : miss2;
                        },
                        8);
                    Scalar num = 0, den = 0;
                    for (std::size_t ai = 0; ai < na; ++ai) {
                        num += ev.weight[ai] * e[ai];
                        den += ev.weight[ai];
                    }
                    ev.energy = den > 0 ? num / den : 0;
                };
                // ---- (ii) the parallel update of the patch vertices (eq. 16)
                auto update = [&](const Eval& ev) {
                    HalfedgeMesh& hm = st.hm;
                    std::vector<Vec3> ap;
                    for (const Index v : ev.active) ap.push_back(hm.position(v));
                    const KdTree atree = KdTree::adopt(ap);
                    std::vector<Vec3> np(ev.active.size());
                    parallel_for(
                        0, ev.active.size(),
                        [&](std::size_t ai) {
                            const Index v = ev.active[ai];
                            np[ai] = hm.position(v);
                            if (!st.omega[v]) return;
                            const Vec3 p = hm.position(v), n = ev.frame[ai].z;
                            std::vector<Neighbor> nb;
                            atree.radius_search_squared(p, A2, nb, true);
                            Scalar num = 0, den = 0;
                            for (const Neighbor& k : nb) {
                                const Index u = ev.active[k.index];
                                const Match mk = st.match[u];
                                if (!mk.valid()) continue;
                                const LocalFrame& Fk = ev.frame[k.index];
                                const Scalar sx = (mk.variant & 1) ? -1 : 1, sy = (mk.variant & 2) ? -1 : 1;
                                Vec3 q = Fk.local(p), d = Fk.local_dir(n);
                                q.x() *= sx;
                                q.y() *= sy;
                                d.x() *= sx;
                                d.y() *= sy;
                                Scalar t = 0;
                                if (!maps.intersect(maps.map(mk.cand), q, d, A, t)) continue;
                                num += ev.weight[k.index] * t;
                                den += ev.weight[k.index];
                            }
                            if (den > 0) np[ai] = p + (num / den) * n;
                        },
                        8);
                    for (std::size_t ai = 0; ai < ev.active.size(); ++ai)
                        if (st.omega[ev.active[ai]]) hm.position(ev.active[ai]) = np[ai];
                };

                Eval ev;
                evaluate(ev);
                progress.check();
                if (!energy_ok(ev.energy)) break;
                std::vector<Scalar> hist{ev.energy};
                for (std::size_t it = 0; it < params.max_iterations; ++it) {
                    progress.update(static_cast<double>(it + 1) / static_cast<double>(params.max_iterations + 1));
                    const State saved = st;
                    update(ev);
                    if (test_after_update) test_after_update(st.hm, st.omega);
                    st.remesh(L.split_above * lave, L.merge_below * lave, patch_cap);
                    progress.check();
                    if (!guard()) break;
                    Eval next;
                    evaluate(next);
                    progress.check();
                    if (!energy_ok(next.energy)) break;
                    if (!(next.energy <= hist.back())) {
                        st = saved;  // would raise E: undone, the level has converged
                        break;
                    }
                    const Scalar prev = hist.back();
                    hist.push_back(next.energy);
                    ev = std::move(next);
                    if (prev - hist.back() <= params.tolerance * prev) break;
                }
                if (!fired.empty()) break;
                out.energy.push_back(std::move(hist));

                // ---- the evidence for the blend: how well the data around the holes is
                // explained by the shapes it matched (R_e) and by a quadric (R_q), over A.
                if (params.blend_with_smooth && level + 1 == nlev) {
                    std::vector<Index> fixed;
                    for (std::size_t ai = 0; ai < ev.active.size(); ++ai)
                        if (!st.omega[ev.active[ai]] && st.match[ev.active[ai]].valid()) fixed.push_back(static_cast<Index>(ai));
                    residual_at.resize(fixed.size());
                    residual.assign(fixed.size(), {0, 0});
                    parallel_for(
                        0, fixed.size(),
                        [&](std::size_t k) {
                            const std::size_t ai = fixed[k];
                            const Index v = ev.active[ai];
                            const LocalFrame& F = ev.frame[ai];
                            const Match mv = st.match[v];
                            residual_at[k] = st.hm.position(v);
                            std::vector<Neighbor> nb;
                            data_tree.radius_search_squared(st.hm.position(v), A2, nb, false);
                            const Scalar sx = (mv.variant & 1) ? -1 : 1, sy = (mv.variant & 2) ? -1 : 1;
                            Eigen::Matrix<Scalar, 6, 6> AtA = Eigen::Matrix<Scalar, 6, 6>::Zero();
                            Eigen::Matrix<Scalar, 6, 1> Atb = Eigen::Matrix<Scalar, 6, 1>::Zero();
                            std::vector<Vec3> q;
                            Scalar se = 0;
                            std::size_t ne = 0;
                            const std::size_t nn = std::min(nb.size(), max_ssd_samples);  // an even subset beyond it
                            for (std::size_t i = 0; i < nn; ++i) {
                                const Neighbor& n = nb[spread(i, nb.size(), nn)];
                                if (vf[n.index].empty()) continue;
                                const Vec3 l = F.local(work.vertices[n.index]);
                                const Vec3 d = F.local_dir(data_normal[n.index]);
                                q.push_back(l);
                                Eigen::Matrix<Scalar, 6, 1> a;
                                a << 1, l.x(), l.y(), l.x() * l.x(), l.x() * l.y(), l.y() * l.y();
                                AtA += a * a.transpose();
                                Atb += a * l.z();
                                Scalar t = 0;
                                if (maps.intersect(maps.map(mv.cand), Vec3(sx * l.x(), sy * l.y(), l.z()),
                                                   Vec3(sx * d.x(), sy * d.y(), d.z()), A, t)) {
                                    se += t * t;
                                    ++ne;
                                }
                            }
                            if (q.size() < 12 || ne < q.size() / 2) return;  // too little data: no evidence
                            const Eigen::Matrix<Scalar, 6, 1> c = AtA.ldlt().solve(Atb);
                            Scalar sq = 0;
                            for (const Vec3& l : q) {
                                const Scalar z = c[0] + c[1] * l.x() + c[2] * l.y() + c[3] * l.x() * l.x() +
                                                 c[4] * l.x() * l.y() + c[5] * l.y() * l.y();
                                sq += (l.z() - z) * (l.z() - z);
                            }
                            residual[k] = {se / static_cast<Scalar>(ne), sq / static_cast<Scalar>(q.size())};
                        },
                        16);
                }
            }

            if (fired.empty()) break;
            for (const auto& [h, why] : fired) out.hole_status[h] = why;
            // The next run's initial patch: a reverted hole gets its thin-plate fill (with the
            // thin-plate initial patch it has it already and is only frozen).
            if (params.initial == InitialPatch::fan) {
                filled = work;
                std::vector<std::vector<Index>> smooth;
                std::vector<std::uint8_t> skip(unfilled);
                for (std::size_t h = 0; h < nh; ++h)
                    if (out.hole_status[h] != HoleStatus::completed) {
                        smooth.push_back(selected[filled_index[h]]);
                        skip[filled_index[h]] = 1;
                    }
                FillParams fp;
                fp.control.stop = params.control.stop;
                if (fill_holes(filled, smooth, fp).status == Status::cancelled) throw detail::cancelled_exception{};
                add_fans(filled, skip);
            }
        }

        // ---- write out: the live patch vertices and faces, appended in index order.
        progress.stage("write", 0.98, 1.0);
        std::vector<Index> map(st.hm.vertex_capacity(), HalfedgeMesh::invalid);
        for (Index v = 0; v < nv0; ++v) map[v] = v;
        for (Index v = nv0; v < st.hm.vertex_capacity(); ++v)
            if (!st.hm.is_removed_vertex(v)) {
                map[v] = nv0 + new_pos.size();
                new_pos.push_back(st.hm.position(v));
            }
        for (Index f = nf0; f < st.hm.face_capacity(); ++f)
            if (!st.hm.is_removed_face(f))
                new_faces.push_back({map[st.hm.face_vertex(f, 0)], map[st.hm.face_vertex(f, 1)], map[st.hm.face_vertex(f, 2)]});

        // ---- the blend with the thin-plate fairing of the same patch, per hole.
        auto is_reverted = [&](std::uint32_t h) { return h < nh && out.hole_status[h] != HoleStatus::completed; };
        out.example_weight.assign(nh, Scalar(1));
        for (std::size_t h = 0; h < nh; ++h)
            if (is_reverted(static_cast<std::uint32_t>(h))) out.example_weight[h] = 0;
        if (params.blend_with_smooth && !new_pos.empty()) {
            // The hole of each new vertex: new vertices joined by new faces, labelled by
            // the rim vertex they touch.
            const std::size_t nn = new_pos.size();
            detail::DisjointSets<Index> sets(nn);
            for (const Face& t : new_faces)
                for (int k = 0; k < 3; ++k) {
                    const Index a = t[k], b = t[(k + 1) % 3];
                    if (a >= nv0 && b >= nv0) sets.unite(a - nv0, b - nv0);
                }
            std::vector<std::uint32_t> comp_hole(nn, std::numeric_limits<std::uint32_t>::max());
            for (const Face& t : new_faces)
                for (int k = 0; k < 3; ++k)
                    if (t[k] < nv0 && rim_hole[t[k]] != std::numeric_limits<std::uint32_t>::max())
                        for (const Index u : t)
                            if (u >= nv0) comp_hole[sets.find(u - nv0)] = rim_hole[t[k]];
            std::vector<std::uint32_t> hole_of(nn);
            for (std::size_t i = 0; i < nn; ++i) hole_of[i] = comp_hole[sets.find(static_cast<Index>(i))];
            // λ per hole from the evidence of the data vertices nearest to its patch.
            std::vector<Scalar> re(filled_index.size(), 0), rq(filled_index.size(), 0);
            const KdTree new_tree = KdTree::adopt(std::vector<Vec3>(new_pos));
            std::vector<Neighbor> nb;
            for (std::size_t k = 0; k < residual.size(); ++k) {
                if (residual[k].first == 0 && residual[k].second == 0) continue;
                new_tree.knn(residual_at[k], 1, nb);
                if (nb.empty() || hole_of[nb[0].index] >= re.size()) continue;
                re[hole_of[nb[0].index]] += residual[k].first;
                rq[hole_of[nb[0].index]] += residual[k].second;
            }
            for (std::size_t h = 0; h < re.size(); ++h)
                if (rq[h] > 0 && !is_reverted(static_cast<std::uint32_t>(h)))
                    out.example_weight[h] = std::clamp(1 - re[h] / rq[h], Scalar(0), Scalar(1));
            // The smooth surface: the thin-plate fairing of the final patch (same
            // connectivity, the rim fixed); each new vertex keeps λ of its offset from it.
            std::vector<Vec3> x(work.vertices);
            x.insert(x.end(), new_pos.begin(), new_pos.end());
            std::vector<Face> all(work.faces);
            all.insert(all.end(), new_faces.begin(), new_faces.end());
            std::vector<std::uint8_t> free(x.size(), 0);
            std::fill(free.begin() + static_cast<std::ptrdiff_t>(nv0), free.end(), 1);
            for (std::size_t i = 0; i < nn; ++i)
                if (is_reverted(hole_of[i])) free[nv0 + i] = 0;  // keeps its thin-plate fill
            const MeshTopology topo(x.size(), all);
            progress.check();
            if (detail::biharmonic_fill(x, topo, free) > 0)
                for (std::size_t i = 0; i < nn; ++i) {
                    if (!free[nv0 + i]) continue;
                    const Scalar lam = hole_of[i] < out.example_weight.size() ? out.example_weight[hole_of[i]] : Scalar(1);
                    new_pos[i] = x[nv0 + i] + lam * (new_pos[i] - x[nv0 + i]);
                }
        }
        out.timings = progress.finish();
    } catch (const detail::cancelled_exception&) {
        CompletionResult c;
        c.status = Status::cancelled;
        return c;
    }
    return out;
}

}  // namespace kintsugi::detail::completion
