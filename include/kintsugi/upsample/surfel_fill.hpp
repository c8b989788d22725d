// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file surfel_fill.hpp
/// @brief `fill_surfel_gaps`: up-samples a surfel set (oriented disks) until no gap is
/// left between the disks at the user's radius, with as few new surfels as possible;
/// optionally curvature-adaptive radii and levels of detail.
///
/// @code
/// kintsugi::PointCloud cloud = kintsugi::read_point_cloud("scan.ply");   // with normals
/// auto r = kintsugi::fill_surfel_gaps(cloud, {.radius_rel = 0.005});
/// // r.surfels: the input then the new disks (radii at the finest level);
/// // r.level_counts[l]: the prefix that is level l; r.coverage_verified
/// @endcode
///
/// Method: Kanamori, Takahashi & Nishita, "An efficient up-sampling method for filling
/// holes on point-sampled surfaces" (IPSJ Journal 2007). For each surfel i: its
/// neighbours are projected onto i's tangent plane (circles of radius
/// max(0, n_j·n_i) r_j); the arcs of i's boundary they cover are found and each
/// uncovered arc (ω > 0; ω = 2π without neighbours) is filled with new surfels spaced
/// by Δω of eq. (1) (a hexagonal layout for equal radii), the small-gap rules (b)-(d),
/// and the slide of eq. (2) when a new centre falls inside an existing disk; the new
/// surfels are back-projected onto the MLS surface of the INPUT points (APSS,
/// field/point_set_surface.hpp; kd-tree and a UniformGrid on the input, a BucketGrid on the output) and
/// processed in turn, in parallel over cells far enough apart (deterministic: see
/// detail::surfel_fill::run). Rounds repeat over the surfels whose placed disks leave
/// part of their boundary open until a round finds no gap; the surfels whose last fill dropped a placement are
/// then tested again against their present neighbours, and those still showing an
/// uncovered arc are listed (uncovered_surfels; coverage_verified when none). Curvature-adaptive radius: r = ε_r / √κ (κ the largest
/// |principal curvature| of a jet fit of the input), r_new computed at p_i and replaced
/// by r' of a new centre when r_new / r' exceeds the threshold. Levels of detail:
/// fill, halve every radius, fill again..., the surfels stored coarse to fine.
/// Departures (docs/methods/surfel_upsampling.md): gap detection takes the union of
/// all intersecting neighbours' arcs (the paper checks j - 1 and j + 2 only), so a gap
/// covered by j - 2 is not filled twice; a new surfel whose back-projection lands farther
/// than max_distance_rel from every input point (an open border, not a hole) is not
/// placed, and the surfels left open there are listed in uncovered_surfels. Costs are
/// bounded: the radius is at most the diagonal, input radii count at most 4x the
/// radius in the neighbour searches, the output at most max_output_surfels.
/// Licence: Eigen and nanoflann only.

#include <kintsugi/adapters/indexed_mesh.hpp>  // PointCloud, the result's layout
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>
#include <kintsugi/core/surfel_input.hpp>
#include <kintsugi/upsample/detail/surfel_fill_impl.hpp>  // field/, spatial/, core/control

#include <numeric>
#include <string>

namespace kintsugi {

/// Parameters of fill_surfel_gaps (aggregate; field order is API, append only).
struct SurfelFillParams {
    /// Radius of the new surfels (and of input points that have none), in model units.
    /// In (0, bounding-box diagonal], or 0 to use radius_rel instead (exactly one of the
    /// two is given). With epsilon_r > 0 it is the largest radius.
    Scalar radius = 0;
    /// The same as a fraction of the input's bounding-box diagonal (the paper's unit:
    /// 0.018 on its sphere, 0.0012 on igea). > 0, or 0 when radius is given.
    Scalar radius_rel = 0;
    /// Curvature-adaptive radii r = epsilon_r / √κ (units^½; on a sphere of radius R:
    /// r = epsilon_r √R), clamped to [min_radius_fraction · radius, radius]; also
    /// replaces the input radii. 0 (default): every new surfel has `radius`.
    Scalar epsilon_r = 0;
    /// Levels of detail, >= 1: level l has radii 2^-l of level 0's. Default 1.
    std::size_t levels = 1;
    /// Most rounds per level (a round processes every surfel that added disks in the
    /// previous one). >= 1; default 16: the measured runs end in 2-4 rounds.
    std::size_t max_iterations = 16;
    /// r_new / r' above this redoes a surfel's fill with r' (adaptive radii only).
    /// > 1; default 1.5: radii within 50 % of each other keep the layout of eq. (1).
    Scalar radius_ratio_threshold = 1.5;
    /// Smallest adaptive radius as a fraction of radius, in (0, 1]; default 0.125 (a
    /// sharp crease or noise would otherwise ask for ever smaller disks).
    Scalar min_radius_fraction = 0.125;
    /// Samples in the MLS kernel (PointSetSurfaceParams::k), >= 4 (lowered to the
    /// number of input points). Default 20: new surfels within 0.02 % of the diagonal
    /// of the bunny, at half the cost of 40.
    std::size_t mls_k = 20;
    /// Input points in each curvature jet fit (degree 2), >= 6. Default 20.
    std::size_t curvature_k = 20;
    /// A new surfel is placed only within this fraction of the diagonal from some
    /// input point (holes are filled up to twice as wide; an open border is not
    /// extended without end). > 0; default 0.1.
    Scalar max_distance_rel = 0.1;
    RunControl control{};
    /// The MLS support reaches at least this times the distance to the nearest input
    /// point (PointSetSurfaceParams::min_support_factor): in a hole the fit then takes
    /// the whole rim, not its nearest arc. 0 (off) or in [1, 8]; default 2 (1.5-4 give
    /// the same accuracy on the bunny's holes; each query gathers factor^2 more points).
    Scalar mls_support_factor = 2;
    /// Most surfels in the output (input included). A radius much smaller than the
    /// input's spacing asks for a number of disks growing as 1/r²: the request is
    /// refused upfront (invalid_input naming the expected count, from the surface area
    /// estimated on a coarse grid over the hexagonal cover's 2.6 r² per disk and
    /// level), and a fill that passes the cap anyway stops with invalid_input. >= 1;
    /// default 20,000,000 (about 2 GB while filling).
    std::size_t max_output_surfels = 20'000'000;
};

/// Outcome of fill_surfel_gaps.
struct SurfelFillResult {
    Status status = Status::ok;
    /// The input surfels (exact duplicates removed) then the new ones, coarse to fine;
    /// radii are those of the finest level. Empty when cancelled.
    PointCloud surfels;
    /// level_counts[l]: surfels [0, level_counts[l]) form level l, drawn with the
    /// stored radii times 2^(levels - 1 - l). The last entry is surfels.size().
    std::vector<std::size_t> level_counts;
    std::size_t input_surfels = 0;       ///< input points used (after duplicates)
    std::size_t duplicates_removed = 0;  ///< input surfels at exactly the position of an earlier one
    std::size_t gaps_filled = 0;         ///< uncovered boundary arcs found and filled
    std::size_t rounds = 0;              ///< rounds over all levels
    std::size_t radius_redos = 0;        ///< fills redone with r' (adaptive radii)
    std::size_t not_placed = 0;          ///< new surfels beyond max_distance_rel or whose projection failed
    /// True when, at the end of every level, every surfel's boundary is covered by its
    /// neighbours' disks projected onto its tangent plane: no hole at the given radius.
    bool coverage_verified = false;
    /// The surfels (indices into `surfels`) whose boundary keeps an uncovered arc at
    /// the end of their level, increasing: where a new disk could not be placed (an
    /// open border beyond max_distance_rel, a rim whose disk would land on an existing
    /// centre) or max_iterations ran out. Empty exactly when coverage_verified.
    std::vector<std::size_t> uncovered_surfels;
    Scalar radius = 0;                   ///< the level-0 radius used (model units)
    std::vector<StageTiming> timings;    ///< "prepare", "fill level 0", ...
};

namespace detail::surfel_fill {

struct Config {
    Scalar radius = 0, epsilon = 0, min_fraction = 0, ratio = 0, max_distance = 0;
    std::size_t levels = 1, rounds = 1, curvature_k = 20, max_output = 0;
    ScaleFrame frame;
};

/// Upper bound of SurfelFillParams::mls_support_factor.
constexpr Scalar max_support_factor = 8;
/// Input radii above this times the fill radius count as this in the gap tests (a
/// smaller circle only makes the test stricter), so that one huge input disk cannot
/// widen every neighbour search to the whole model (quadratic cost).
constexpr Scalar max_input_radius_factor = 4;

/// About how many surfels a hexagonal cover of the input's surface at `radius` needs
/// over `levels` levels (each halving the radius): the surface area estimated as the
/// occupied cells of a grid coarse enough to hold several input points per cell
/// (area ~ cells x side^2 / 1.5, the mean of |n_x| + |n_y| + |n_z| for a random
/// orientation), over 2.6 r^2 per disk. An order of magnitude, for refusing a radius
/// far below the spacing before the fill runs.
inline double expected_output(const std::vector<Vec3>& P, Scalar diag, Scalar radius, std::size_t levels) {
    if (!(diag > 0) || P.empty()) return static_cast<double>(P.size());
    BoundingBox box;
    for (const Vec3& p : P) box.extend(p);
    std::vector<std::uint64_t> keys(P.size());
    double area = 0;
    for (Scalar cell = diag / 256;; cell *= 2) {
        for (std::size_t i = 0; i < P.size(); ++i) {
            const Vec3 t = (P[i] - box.min) / cell;
            keys[i] = (static_cast<std::uint64_t>(t.x()) << 42) | (static_cast<std::uint64_t>(t.y()) << 21) |
                      static_cast<std::uint64_t>(t.z());
        }
        std::sort(keys.begin(), keys.end());
        const auto cells = static_cast<double>(std::unique(keys.begin(), keys.end()) - keys.begin());
        area = cells * cell * cell / 1.5;
        if (static_cast<double>(P.size()) >= 4 * cells || cell >= diag / 4) break;
    }
    double per_level = area / (2.6 * radius * radius), total = 0;
    for (std::size_t l = 0; l < levels; ++l, per_level *= 4) total += per_level;
    return std::max(total, static_cast<double>(P.size()));
}

/// Convergence tolerance of the back-projection (PointSetSurfaceParams::tolerance: a
/// step below this times the kernel radius ends it). The first step from i's tangent
/// plane is mostly below 0.01 h, so one fit suffices where 1e-4 took two: on bunny00
/// 134K the new surfels stay within 1.6e-7 of the diagonal (99th percentile) of the
/// converged surface, their mean distance to the mesh 0.0020 % either way.
constexpr Scalar projection_tolerance = 0.01;
/// A back-projection that moves a new centre farther than this many of its radii has jumped
/// to another sheet of the MLS surface: the disk is not placed. 4, not 1: on the kitten scan
/// (5K points, radius 0.01 of the diagonal) projections moved disks by 1-4 r and 1 r left a
/// gap open. Both those moves and the 20-320 r jumps seen on bunny00 134K came before the
/// projection's fix of 2026-12-06 (a nearly flat fit rounded points far away); since then
/// the kitten's largest move is 1.01 r and bunny00 has none over 4 r. Kept as a safety net.
constexpr Scalar jump_radii = 4;
/// Most tiles one parallel pass takes before its new surfels are merged and progress
/// (and cancellation) is reported: bounds the time between two reports.
constexpr std::size_t tiles_per_pass = 2048;

/// What the surfels of one tile added during one pass: the new surfels (level-0 radius
/// r, adaptive radius rn0 or NaN, bound reach_in on the distance to the nearest input
/// point), the surfels that added some, and the counters.
struct TileOutput {
    std::vector<Vec3> p, n;
    std::vector<Scalar> r, rn0, reach_in;
    std::vector<Index> again;
    std::size_t gaps = 0, not_placed = 0, redos = 0;
    void clear() {
        p.clear();
        n.clear();
        r.clear();
        rn0.clear();
        reach_in.clear();
        again.clear();
        gaps = not_placed = redos = 0;
    }
};

/// Per-thread scratch of one surfel's fill.
struct FillScratch {
    detail::pss::LocalSamples local;  ///< the input samples around the surfel being filled
    std::vector<Circle> circles;
    PlaneFill pf;
    std::vector<Vec3> newp, newn;
    std::vector<Scalar> newr, new_reach;
};

/// The whole fill on local-frame copies: P, N (unit), R (level-0 radii) in; res filled.
///
/// Order of work, deterministic whatever the thread count: a round processes its queue
/// in waves (the queue, then the surfels the previous wave added, ...). A wave's surfels
/// are grouped by tile (a cell of the surfels' BucketGrid, 6 r_max wide) and the tiles by colour (the
/// parities of their three coordinates): tiles of one colour are at least 6 r_max apart,
/// farther than one surfel's reads (r_i + r_new + r_max <= 3 r_max) and another's writes
/// (within r_i + r_new <= 2 r_max of it, plus the back-projection's small move) reach
/// together, so they are filled in parallel, each tile's surfels in index order seeing
/// the tile's own new surfels at once. After each pass over (at most tiles_per_pass)
/// tiles of a colour, the new surfels are appended in tile order. A far back-projection
/// could bring two tiles' disks near each other; each tile reads only what was merged
/// before the pass and its own disks, so the result stays one (at worst a gap is filled
/// from both sides). A surfel whose placed disks (back-projected: moved and tilted)
/// cover its boundary is done; the others are filled again in the next round.
inline void run(std::vector<Vec3> P, std::vector<Vec3> N, std::vector<Scalar> R, const PointSetSurface& mls,
                const Config& cfg, Progress& progress, SurfelFillResult& res) {
    const KdTree& tree = mls.tree();
    const std::size_t nin = P.size();
    // Adaptive radius at x (level 0): ε / √κ, clamped.
    auto adaptive_radius = [&](const Vec3& x) {
        thread_local std::vector<Neighbor> nn;
        tree.knn(x, cfg.curvature_k, nn);
        const JetFit j = detail::fit_jet([&](std::size_t k) -> const Vec3& { return tree.point(nn[k].index); },
                                         nn.size(), x, 2, true);
        Scalar r = cfg.radius;
        if (j.valid) {
            const Scalar kappa_world = cfg.frame.to_local(std::max(std::abs(j.k1), std::abs(j.k2)));  // 1/len scales up
            if (kappa_world > 0) r = cfg.frame.to_local(cfg.epsilon / std::sqrt(kappa_world));
        }
        return std::clamp(r, cfg.min_fraction * cfg.radius, cfg.radius);
    };
    const bool adaptive = cfg.epsilon > 0;
    // rn0[i]: level-0 radius of the surfels added around i (NaN until needed).
    std::vector<Scalar> rn0(nin, std::numeric_limits<Scalar>::quiet_NaN());
    if (adaptive) {
        parallel_for(0, nin, [&](std::size_t i) { rn0[i] = adaptive_radius(P[i]); }, 64);
        R = rn0;
    }
    // The input radii as given (the output keeps them); in the gap tests they count
    // at most max_input_radius_factor x radius, which bounds the neighbour searches.
    std::vector<Scalar> R_given = adaptive ? std::vector<Scalar>{} : R;
    for (Scalar& r : R) r = std::min(r, max_input_radius_factor * cfg.radius);
    Scalar rmax0 = cfg.radius;
    for (Scalar r : R) rmax0 = std::max(rmax0, r);
    BoundingBox box;
    for (const Vec3& p : P) box.extend(p);
    // The input in the order of level 0's first wave (by tile, see above): the surfels
    // processed one after the other, and their neighbours, then lie near each other in
    // memory. perm[k]: the input index of internal surfel k; the output keeps the input order.
    // The input samples gathered around each surfel before its new disks are projected:
    // enough that the MLS supports at the new centres (about r_i + r_new away) usually
    // lie inside (the projection takes the tree otherwise), from the median k-th
    // neighbour distance of a subsample of the input.
    Scalar dk_typ = 0;
    {
        std::vector<Scalar> dk;
        thread_local std::vector<Neighbor> nn;
        for (std::size_t j = 0; j < nin; j += std::max<std::size_t>(1, nin / 512)) {
            tree.knn(P[j], mls.params().k, nn);
            dk.push_back(std::sqrt(nn.back().squared_distance));
        }
        std::nth_element(dk.begin(), dk.begin() + static_cast<std::ptrdiff_t>(dk.size() / 2), dk.end());
        dk_typ = dk[dk.size() / 2];
    }
    std::vector<Index> perm(nin);
    {
        const BucketGrid<SurfelRest> cells(box.min, box.max, 6 * rmax0);
        std::vector<std::pair<std::uint64_t, Index>> order(nin);
        parallel_for(0, nin, [&](std::size_t i) { order[i] = {coloured_tile(cells, P[i]), i}; }, 4096);
        detail::sort_maybe_parallel(order);
        for (std::size_t k = 0; k < nin; ++k) perm[k] = order[k].second;
        auto permute = [&](auto& v) {
            if (v.size() != nin) return;
            auto copy = v;
            for (std::size_t k = 0; k < nin; ++k) v[k] = copy[perm[k]];
        };
        permute(P);
        permute(N);
        permute(R);
        permute(rn0);
        permute(R_given);
    }
    // reach_in[i] >= the distance from surfel i to the nearest input point (0 for the
    // input): a new centre x with |x - p_i| + reach_in[i] within max_distance passes the
    // max_distance test without a kd-tree query (the triangle inequality: the query
    // could only confirm it).
    std::vector<Scalar> reach_in(nin, 0);
    std::vector<std::size_t> uncovered;
    for (std::size_t level = 0; level < cfg.levels; ++level) {
        const Scalar scale = std::ldexp(Scalar(1), -static_cast<int>(level));
        progress.stage("fill level " + std::to_string(level), 0.1 + 0.9 * double(level) / double(cfg.levels),
                       0.1 + 0.9 * double(level + 1) / double(cfg.levels));
        const Scalar rmax = rmax0 * scale;
        // Cells twice as wide as the widest query (r_i + r_new + r_max <= 3 r_max).
        BucketGrid<SurfelRest> cells(box.min, box.max, 6 * rmax);
        for (std::size_t i = 0; i < P.size(); ++i) cells.insert(P[i], {N[i], R[i], i});
        // New centres lie about r_i + r_new from p_i: a ball of dk_typ + 1.5 (2 r) holds
        // the supports of 97 % of the fits on bunny00 134K (2 r: 99 %, no faster).
        const Scalar local_radius = dk_typ + 3 * cfg.radius * scale;
        const InputSamples input(mls, local_radius);
        // open[i]: the last fill of i left part of a gap unfilled (a placement dropped).
        std::vector<unsigned char> open(P.size(), 0);
        auto new_radius = [&](Index i) {
            if (!adaptive) return cfg.radius * scale;
            return (std::isnan(rn0[i]) ? adaptive_radius(P[i]) : rn0[i]) * scale;
        };
        // The neighbours of surfel i projected onto its tangent plane (e1, e2): every
        // disk that can meet i or a new disk of radius rn around it, merged ones in the
        // cells' order, then the tile's own new ones (`local`, may be null).
        auto gather_circles = [&](Index i, Scalar ri, Scalar rn, const Vec3& e1, const Vec3& e2,
                                  const TileOutput* local, std::vector<Circle>& circles) {
            const Vec3 pi = P[i], ni = N[i];
            const Scalar reach = ri + rn + rmax;
            circles.clear();
            auto add = [&](const Vec3& p, const Vec3& n, Scalar r) {
                const Scalar rho = std::max(Scalar(0), n.dot(ni)) * r * scale;
                const Vec3 d = p - pi;
                if (rho > 0) circles.push_back({Vec2(d.dot(e1), d.dot(e2)), rho});
            };
            cells.for_each_in_ball(pi, reach, [&](const Vec3& p, const SurfelRest& e) {
                if (e.i != i) add(p, e.n, e.r);
            });
            if (local)
                for (std::size_t k = 0; k < local->p.size(); ++k)
                    if ((local->p[k] - pi).squaredNorm() <= reach * reach) add(local->p[k], local->n[k], local->r[k]);
        };
        // One surfel's fill (§3.2): its gaps, the new surfels back-projected, checked and
        // kept in `out` (which later surfels of the same tile see).
        auto fill_surfel = [&](Index i, TileOutput& out, FillScratch& s) {
            const Vec3 pi = P[i];
            const Scalar ri = R[i] * scale;
            if (adaptive && std::isnan(rn0[i])) rn0[i] = adaptive_radius(pi);
            Scalar rn = new_radius(i);
            Vec3 e1, e2;
            tangent_basis(N[i], e1, e2);
            gather_circles(i, ri, rn, e1, e2, &out, s.circles);
            const std::size_t nc = s.circles.size();
            std::size_t dropped = 0;
            for (int attempt = 0;; ++attempt) {
                s.circles.resize(nc);
                fill_plane(ri, rn, s.circles, s.pf);
                s.newp.clear();
                s.newn.clear();
                s.newr.clear();
                s.new_reach.clear();
                dropped = 0;
                Scalar rmin_new = std::numeric_limits<Scalar>::infinity();
                if (!s.pf.centres.empty() && attempt == 0) input.gather(pi, local_radius, s.local);
                for (const Vec2& c : s.pf.centres) {
                    const Vec3 x = pi + c.x() * e1 + c.y() * e2;
                    const SurfaceProjection pr = mls.project_unchecked(x, &s.local, projection_tolerance);
                    // A disk moved farther than jump_radii radii by the projection, or turned
                    // away from i, no longer meets the gap it was placed for: the MLS
                    // surface jumped to another sheet (thin parts, creases; seen 300 r
                    // away on bunny00). Not placed; i stays listed as open.
                    if (!pr.point.allFinite() || !(pr.normal.squaredNorm() > 0.5) ||
                        !((pr.point - x).squaredNorm() <= jump_radii * jump_radii * rn * rn) || !(pr.normal.dot(N[i]) > 0)) {
                        ++dropped;
                        continue;
                    }
                    Scalar to_input = (pr.point - pi).norm() + reach_in[i];
                    if (!(to_input <= cfg.max_distance)) {
                        to_input = std::sqrt(tree.nearest(pr.point).squared_distance);
                        if (to_input > cfg.max_distance) {
                            ++dropped;
                            continue;
                        }
                    }
                    // A disk landing on an existing centre adds nothing: the surface bends
                    // too fast for i's tangent plane here (a rim, an open border).
                    const Scalar near = redundant_fraction * rn, near2 = near * near;
                    bool redundant = cells.any_in_ball(pr.point, near);
                    for (const Vec3& q : out.p) redundant = redundant || (q - pr.point).squaredNorm() <= near2;
                    for (const Vec3& q : s.newp) redundant = redundant || (q - pr.point).squaredNorm() <= near2;
                    if (redundant) {
                        ++dropped;
                        continue;
                    }
                    s.newp.push_back(pr.point);
                    s.newn.push_back(pr.normal);
                    s.new_reach.push_back(to_input);
                    if (adaptive) {
                        s.newr.push_back(adaptive_radius(pr.point));
                        rmin_new = std::min(rmin_new, s.newr.back() * scale);
                    }
                }
                if (adaptive && attempt < 2 && !s.newp.empty() && rn / rmin_new > cfg.ratio) {
                    rn = rmin_new;  // curvature changes fast here: redo with r'
                    ++out.redos;
                    continue;
                }
                break;
            }
            out.not_placed += dropped;
            open[i] = dropped > 0;
            if (s.pf.centres.empty()) return;
            out.gaps += s.pf.gaps;
            if (s.newp.empty()) return;  // nothing could be placed: not retried
            // The disks as placed (back-projected: moved off i's plane, tilted) may leave
            // a sliver of i's boundary open: i is filled again in the next round only
            // then (disks added later can only cover more of it).
            s.circles.resize(nc);
            for (std::size_t k = 0; k < s.newp.size(); ++k) {
                const Vec3 d = s.newp[k] - pi;
                const Scalar rho = std::max(Scalar(0), s.newn[k].dot(N[i])) * rn;
                if (rho > 0) s.circles.push_back({Vec2(d.dot(e1), d.dot(e2)), rho});
            }
            find_gaps(ri, s.circles, s.pf.arcs, s.pf.gap_list);
            if (s.pf.gap_list.empty())
                open[i] = 0;
            else
                out.again.push_back(i);
            for (std::size_t k = 0; k < s.newp.size(); ++k) {
                out.p.push_back(s.newp[k]);
                out.n.push_back(s.newn[k]);
                out.r.push_back(rn / scale);  // stored as a level-0 radius
                out.rn0.push_back(adaptive ? s.newr[k] : std::numeric_limits<Scalar>::quiet_NaN());
                out.reach_in.push_back(s.new_reach[k]);
            }
        };

        std::vector<Index> queue(P.size());
        std::iota(queue.begin(), queue.end(), Index{0});
        bool verified = false;
        std::size_t done_total = 0;
        std::vector<Index> again, next;
        // (colour, tile, surfel): colour in the top 3 bits, the tile's packed coordinates below.
        std::vector<std::pair<std::uint64_t, Index>> order;
        std::vector<std::size_t> tile_start, tile_first;
        std::vector<TileOutput> outs;
        for (std::size_t round = 0; round < cfg.rounds; ++round) {
            ++res.rounds;
            again.clear();
            std::vector<Index> wave = queue;
            while (!wave.empty()) {
                order.resize(wave.size());
                parallel_for(0, wave.size(), [&](std::size_t k) { order[k] = {coloured_tile(cells, P[wave[k]]), wave[k]}; },
                             4096);
                detail::sort_maybe_parallel(order);
                tile_start.clear();
                for (std::size_t k = 0; k < order.size(); ++k)
                    if (k == 0 || order[k].first != order[k - 1].first) tile_start.push_back(k);
                tile_start.push_back(order.size());
                next.clear();
                // Passes: runs of tiles of one colour, at most tiles_per_pass each.
                for (std::size_t t0 = 0; t0 + 1 < tile_start.size();) {
                    const std::uint64_t colour = order[tile_start[t0]].first >> 61;
                    std::size_t t1 = t0 + 1;
                    while (t1 + 1 < tile_start.size() && t1 - t0 < tiles_per_pass &&
                           order[tile_start[t1]].first >> 61 == colour)
                        ++t1;
                    if (outs.size() < t1 - t0) outs.resize(t1 - t0);
                    parallel_for(t0, t1, [&](std::size_t t) {
                        thread_local FillScratch scratch;
                        TileOutput& out = outs[t - t0];
                        out.clear();
                        for (std::size_t k = tile_start[t]; k < tile_start[t + 1]; ++k)
                            fill_surfel(order[k].second, out, scratch);
                    }, 1);
                    // Merge in tile order: counters and offsets first, then the arrays
                    // filled in parallel (each tile its own slots), the cells serially.
                    const std::size_t first_new = P.size();
                    std::size_t added = 0;
                    for (std::size_t t = t0; t < t1; ++t) {
                        const TileOutput& out = outs[t - t0];
                        res.gaps_filled += out.gaps;
                        res.not_placed += out.not_placed;
                        res.radius_redos += out.redos;
                        again.insert(again.end(), out.again.begin(), out.again.end());
                        if (first_new + added + out.p.size() > cfg.max_output)
                            throw invalid_input(
                                "kintsugi::fill_surfel_gaps: the fill reached params.max_output_surfels = " +
                                std::to_string(cfg.max_output) + " surfels at level " + std::to_string(level) +
                                "; pass a larger radius or raise the cap");
                        added += out.p.size();
                    }
                    const std::size_t total = first_new + added;
                    for (auto* v : {&P, &N}) v->resize(total);
                    for (auto* v : {&R, &rn0, &reach_in}) v->resize(total);
                    open.resize(total, 0);
                    tile_first.resize(t1 - t0 + 1);
                    tile_first[0] = first_new;
                    for (std::size_t t = t0; t < t1; ++t) tile_first[t - t0 + 1] = tile_first[t - t0] + outs[t - t0].p.size();
                    parallel_for(t0, t1, [&](std::size_t t) {
                        const TileOutput& out = outs[t - t0];
                        const std::size_t base = tile_first[t - t0];
                        std::copy(out.p.begin(), out.p.end(), P.begin() + static_cast<std::ptrdiff_t>(base));
                        std::copy(out.n.begin(), out.n.end(), N.begin() + static_cast<std::ptrdiff_t>(base));
                        std::copy(out.r.begin(), out.r.end(), R.begin() + static_cast<std::ptrdiff_t>(base));
                        std::copy(out.rn0.begin(), out.rn0.end(), rn0.begin() + static_cast<std::ptrdiff_t>(base));
                        std::copy(out.reach_in.begin(), out.reach_in.end(), reach_in.begin() + static_cast<std::ptrdiff_t>(base));
                    }, 64);
                    for (std::size_t id = first_new; id < total; ++id) {
                        cells.insert(P[id], {N[id], R[id], id});
                        next.push_back(id);
                    }
                    done_total += tile_start[t1] - tile_start[t0];
                    progress.update(0.9 * double(done_total) /
                                    double(done_total + (order.size() - tile_start[t1]) + next.size()));
                    t0 = t1;
                }
                wave.swap(next);
            }
            if (again.empty()) {
                verified = true;
                break;
            }
            std::sort(again.begin(), again.end());
            queue = again;
        }
        // What is left open: the surfels whose last fill dropped a placement, and (when
        // the rounds ran out) those that added disks in the last round. Each is tested
        // again against its present neighbours: a gap may have been closed since.
        std::vector<Index> suspects;
        for (std::size_t i = 0; i < open.size(); ++i)
            if (open[i]) suspects.push_back(static_cast<Index>(i));
        if (!verified) suspects.insert(suspects.end(), again.begin(), again.end());
        std::sort(suspects.begin(), suspects.end());
        suspects.erase(std::unique(suspects.begin(), suspects.end()), suspects.end());
        std::vector<unsigned char> still_open(suspects.size(), 0);
        parallel_for(0, suspects.size(), [&](std::size_t k) {
            thread_local FillScratch s;
            const Index i = suspects[k];
            Vec3 e1, e2;
            tangent_basis(N[i], e1, e2);
            const Scalar ri = R[i] * scale, rn = new_radius(i);
            gather_circles(i, ri, rn, e1, e2, nullptr, s.circles);
            fill_plane(ri, rn, s.circles, s.pf);
            still_open[k] = !s.pf.centres.empty();
        }, 16);
        for (std::size_t k = 0; k < suspects.size(); ++k)
            if (still_open[k]) uncovered.push_back(suspects[k]);
        res.level_counts.push_back(P.size());
    }
    // Output: the input in its own order, then the new surfels; world frame, radii of
    // the finest level.
    auto out_index = [&](std::size_t k) { return k < nin ? perm[k] : k; };
    for (std::size_t& i : uncovered) i = out_index(i);
    std::sort(uncovered.begin(), uncovered.end());
    uncovered.erase(std::unique(uncovered.begin(), uncovered.end()), uncovered.end());
    res.uncovered_surfels = std::move(uncovered);
    res.coverage_verified = res.uncovered_surfels.empty();
    const Scalar fine = std::ldexp(Scalar(1), -static_cast<int>(cfg.levels - 1));
    res.surfels.points.resize(P.size());
    res.surfels.normals.resize(P.size());
    res.surfels.radii.resize(P.size());
    parallel_for(0, P.size(), [&](std::size_t k) {
        const std::size_t i = out_index(k);
        res.surfels.points[i] = cfg.frame.to_world(P[k]);
        res.surfels.normals[i] = N[k];
        res.surfels.radii[i] = cfg.frame.to_world((k < R_given.size() ? R_given[k] : R[k]) * fine);
    }, 4096);
}

}  // namespace detail::surfel_fill

/// @brief Fills every gap between surfels at the given radius with as few new surfels
/// as possible (Kanamori, Takahashi & Nishita 2007; see the file comment).
/// @tparam S an OrientedPointSet: surfels (a SurfelSet with radii: PointCloud with
///         radii, project_surfels view) or plain oriented points (with_normals view,
///         PointCloud without radii, CGAL::Point_set_3), which take `radius` each.
/// @param surfels centres in any unit, normals pointing outward (any non-zero length);
///        the surface they sample should be closed (an open border stops at max_distance_rel).
/// @param params radius or radius_rel (exactly one), epsilon_r, levels, max_iterations, control.
/// @pre at least one surfel; finite coordinates, non-zero normals, radii finite and > 0.
/// @throws invalid_input (naming the function and the element) for no surfels, missing
///         normals, a NaN/Inf coordinate or normal, a zero normal, a radius that is not
///         finite and > 0 (input or params), a radius above the bounding-box
///         diagonal, an expected output above max_output_surfels (the message names
///         the expected count; also thrown when a fill passes the cap), or a parameter
///         out of range.
/// @return status ok: the filled surfels (identical whatever the thread count);
///         cancelled: surfels and level_counts empty. The input is never modified.
template <OrientedPointSet S>
[[nodiscard]] SurfelFillResult fill_surfel_gaps(const S& surfels, const SurfelFillParams& params = {}) {
    const std::string fn = "kintsugi::fill_surfel_gaps";
    const bool given_r = params.radius != 0, given_rel = params.radius_rel != 0;
    if (given_r == given_rel)
        throw invalid_input(fn + ": pass exactly one of params.radius (model units) and params.radius_rel (fraction of "
                                 "the bounding-box diagonal), > 0; got radius = " + detail::format_number(params.radius) +
                            ", radius_rel = " + detail::format_number(params.radius_rel));
    if (given_r && (!(params.radius > 0) || !std::isfinite(params.radius)))
        throw invalid_input(fn + ": params.radius = " + detail::format_number(params.radius) + "; it must be finite and > 0");
    if (given_rel && (!(params.radius_rel > 0) || !(params.radius_rel <= 1)))
        throw invalid_input(fn + ": params.radius_rel = " + detail::format_number(params.radius_rel) +
                            "; it must be in (0, 1] (a fraction of the diagonal)");
    if (!(params.epsilon_r >= 0) || !std::isfinite(params.epsilon_r))
        throw invalid_input(fn + ": params.epsilon_r = " + detail::format_number(params.epsilon_r) +
                            "; pass 0 (constant radius) or a finite number > 0");
    if (params.levels < 1 || params.levels > 16)
        throw invalid_input(fn + ": params.levels = " + std::to_string(params.levels) + "; pass 1 to 16");
    if (params.max_iterations < 1) throw invalid_input(fn + ": params.max_iterations is 0; pass at least 1 (default 16)");
    if (!(params.radius_ratio_threshold > 1) || !std::isfinite(params.radius_ratio_threshold))
        throw invalid_input(fn + ": params.radius_ratio_threshold must be finite and > 1 (default 1.5)");
    if (!(params.min_radius_fraction > 0) || !(params.min_radius_fraction <= 1))
        throw invalid_input(fn + ": params.min_radius_fraction must be in (0, 1] (default 0.125)");
    if (params.mls_k < 4) throw invalid_input(fn + ": params.mls_k must be at least 4 (default 20)");
    if (params.curvature_k < 6) throw invalid_input(fn + ": params.curvature_k must be at least 6 (default 20)");
    if (!(params.max_distance_rel > 0) || !std::isfinite(params.max_distance_rel))
        throw invalid_input(fn + ": params.max_distance_rel must be finite and > 0 (default 0.1)");
    if (!(params.mls_support_factor == 0 ||
          (params.mls_support_factor >= 1 && params.mls_support_factor <= detail::surfel_fill::max_support_factor)))
        throw invalid_input(fn + ": params.mls_support_factor = " + detail::format_number(params.mls_support_factor) +
                            "; pass 0 (off) or a number in [1, 8] (default 2): a wider support makes every "
                            "projection query gather (factor)^2 times more points");
    if (params.max_output_surfels < 1) throw invalid_input(fn + ": params.max_output_surfels is 0; pass at least 1");

    detail::SurfelInput in = detail::gather_surfels(surfels, fn, false);
    const std::size_t n = in.points.size();
    std::vector<Vec3>& P = in.points;
    std::vector<Vec3>& N = in.normals;
    std::vector<Scalar>& R = in.radii;
    const bool own_radii = !R.empty();
    BoundingBox box;
    for (const Vec3& p : P) box.extend(p);
    Scalar diag = box.diagonal();
    if (!std::isfinite(diag)) diag = (box.max / 2 - box.min / 2).norm() * 2;
    const Scalar radius = given_r ? params.radius : params.radius_rel * diag;
    if (!(radius > 0) || !std::isfinite(radius))
        throw invalid_input(fn + ": the radius is " + detail::format_number(radius) +
                            " (radius_rel of a zero diagonal: the points coincide); pass params.radius");
    if (diag > 0 && radius > diag)
        throw invalid_input(fn + ": params.radius = " + detail::format_number(radius) +
                            " is larger than the input's bounding-box diagonal " + detail::format_number(diag) +
                            "; one disk would cover the whole model (and every neighbour search would see every surfel)");
    {
        const double expected = detail::surfel_fill::expected_output(P, diag, radius, params.levels);
        if (expected > static_cast<double>(params.max_output_surfels))
            throw invalid_input(fn + ": radius " + detail::format_number(radius) + " (" +
                                detail::format_number(radius / diag) + " of the diagonal) asks for about " +
                                detail::format_number(expected) + " surfels over " + std::to_string(params.levels) +
                                " level(s), more than params.max_output_surfels = " +
                                std::to_string(params.max_output_surfels) + "; pass a larger radius or raise the cap");
    }
    if (params.epsilon_r > 0 && n < params.curvature_k)
        throw invalid_input(fn + ": adaptive radii need at least params.curvature_k = " + std::to_string(params.curvature_k) +
                            " input points; there are " + std::to_string(n));
    SurfelFillResult res;
    res.radius = radius;
    detail::Progress progress(params.control);
    try {
        progress.stage("prepare", 0.0, 0.1);
        // Exact duplicates: the first of equal positions is kept.
        std::vector<Index> order(n);
        std::iota(order.begin(), order.end(), Index{0});
        std::sort(order.begin(), order.end(), [&](Index a, Index b) {
            if (P[a].x() != P[b].x()) return P[a].x() < P[b].x();
            if (P[a].y() != P[b].y()) return P[a].y() < P[b].y();
            if (P[a].z() != P[b].z()) return P[a].z() < P[b].z();
            return a < b;
        });
        std::vector<unsigned char> keep(n, 1);
        for (std::size_t k = 1; k < n; ++k)
            if (P[order[k]] == P[order[k - 1]]) keep[order[k]] = 0;
        std::vector<Vec3> P1, N1;
        std::vector<Scalar> R1;
        for (std::size_t i = 0; i < n; ++i)
            if (keep[i]) {
                P1.push_back(P[i]);
                N1.push_back(N[i]);
                R1.push_back(own_radii ? R[i] : radius);
            }
        if (P1.size() < 4)
            throw invalid_input(fn + ": " + std::to_string(P1.size()) +
                                " distinct surfel position(s); the MLS surface the new surfels are projected onto "
                                "needs at least 4");
        res.duplicates_removed = n - P1.size();
        res.input_surfels = P1.size();
        detail::surfel_fill::Config cfg;
        cfg.frame = detail::scale_frame(P1);
        cfg.frame.to_local(P1);
        for (Scalar& r : R1) r = cfg.frame.to_local(r);
        cfg.radius = cfg.frame.to_local(radius);
        cfg.epsilon = params.epsilon_r;
        cfg.min_fraction = params.min_radius_fraction;
        cfg.ratio = params.radius_ratio_threshold;
        cfg.max_distance = cfg.frame.to_local(params.max_distance_rel * diag);
        cfg.levels = params.levels;
        cfg.rounds = params.max_iterations;
        cfg.curvature_k = params.curvature_k;
        cfg.max_output = params.max_output_surfels;
        PointCloud input{P1, N1, {}};
        const PointSetSurface mls(input, {.k = std::min(params.mls_k, P1.size()),
                                          .max_iterations = 10,
                                          .min_support_factor = params.mls_support_factor});
        detail::surfel_fill::run(std::move(P1), std::move(N1), std::move(R1), mls, cfg, progress, res);
        res.timings = progress.finish();
    } catch (const detail::cancelled_exception&) {
        res = {};
        res.status = Status::cancelled;
    }
    return res;
}

}  // namespace kintsugi
