// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file pu_cover.hpp
/// @brief Internal: the support cover of the PU field (Nagai, Ohtake, Suzuki 2011,
/// §2.1): local linear fits (eq. 2-5), radius by bisection to the error ε (eq. 6),
/// candidate removal by the 8-corner rule, in random order until no candidate is left.
///
/// Everything here works in the normalised frame: the data are scaled so that the
/// bounding box's longest side is 1, and the octree's cube is that unit cube.

#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/field/partition_of_unity.hpp>
#include <kintsugi/spatial/kd_tree.hpp>
#include <kintsugi/spatial/octree.hpp>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace kintsugi::detail {

/// One support in the normalised frame: g(x) = m·(x - d) on the open ball (c, r).
struct PUSupportData {
    Vec3 c = Vec3::Zero();
    Scalar r = 0;
    Vec3 m = Vec3::Zero();  ///< unit, pointing into the object (f > 0 inside)
    Vec3 d = Vec3::Zero();
    std::size_t count = 0;   ///< input points with |p - c| < r
    /// |Σ w_j n_j| / Σ w_j over those points, in [0, 1]: 1 when their normals agree
    /// (a surface patch), about 1/sqrt(count) when they point anywhere (outliers).
    Scalar coherence = 0;
    std::uint32_t level = 0; ///< level of the octree cell the centre came from
    bool fallback = false;   ///< no usable fit: tangent plane of the nearest input point
};

/// Inputs of the cover, all in the normalised frame.
struct PUCoverInput {
    const std::vector<Vec3>* points = nullptr;
    const std::vector<Vec3>* normals = nullptr;  ///< unit, pointing INTO the object
    const KdTree* tree = nullptr;                ///< over *points
    const Octree* octree = nullptr;              ///< over *points, unit cube
    Scalar epsilon = 4e-3;
    std::uint64_t seed = 0;
};

/// Result of a fit on the points within radius r (a prefix of the sorted neighbours).
struct PUFitState {
    Vec3 m = Vec3::Zero(), d = Vec3::Zero();
    std::size_t count = 0;
    Scalar coherence = 0;  ///< |Σ w n| / Σ w
    bool valid = false;  ///< at least one point and a non-degenerate normal sum
};

/// Weighted linear fit (eq. 3, weights eq. 4) over the neighbours closer than r.
/// `dist` holds their distances, increasing; `idx` their indices.
inline PUFitState pu_fit(const PUCoverInput& in, const Vec3& c, Scalar r, const std::vector<Index>& idx,
                         const std::vector<Scalar>& dist) {
    (void)c;
    PUFitState s;
    const auto& P = *in.points;
    const auto& N = *in.normals;
    const std::size_t k = static_cast<std::size_t>(std::lower_bound(dist.begin(), dist.end(), r) - dist.begin());
    s.count = k;
    if (k == 0) return s;
    Scalar sw = 0;
    Vec3 sn = Vec3::Zero(), sp = Vec3::Zero();
    const Scalar inv = Scalar(1.5) / r;
    for (std::size_t j = 0; j < k; ++j) {
        const Scalar w = b2_weight(dist[j] * inv);
        sw += w;
        sn += w * N[idx[j]];
        sp += w * P[idx[j]];
    }
    const Scalar len = sn.norm();
    if (sw > 0) s.coherence = len / sw;
    if (!(sw > 0) || !(len > Scalar(1e-9) * sw)) return s;
    s.m = sn / len;
    s.d = sp / sw;
    s.valid = true;
    return s;
}

/// Eq. (6) test: whether the fit at radius r keeps max |g(p_j)| <= ε over the points
/// closer than r. An empty ball passes (error 0); a degenerate fit fails.
inline bool pu_radius_ok(const PUCoverInput& in, const Vec3& c, Scalar r, const std::vector<Index>& idx,
                         const std::vector<Scalar>& dist) {
    const PUFitState s = pu_fit(in, c, r, idx, dist);
    if (s.count == 0) return true;
    if (!s.valid) return false;
    const auto& P = *in.points;
    const Scalar md = s.m.dot(s.d);
    for (std::size_t j = 0; j < s.count; ++j)
        if (std::abs(s.m.dot(P[idx[j]]) - md) > in.epsilon) return false;
    return true;
}

/// Computes the support of candidate cell `cell`: radius by bisection on eq. (6),
/// never below 0.75 x the cell diagonal, then the fit at that radius. A pure
/// function of the cell (thread-safe), so candidates can be computed speculatively.
inline PUSupportData pu_compute_support(const PUCoverInput& in, Index cell) {
    const Octree& oct = *in.octree;
    PUSupportData out;
    out.c = oct.cell_center(cell);
    out.level = oct.cell_level(cell);
    const Scalar r_min = Scalar(0.75) * oct.cell_diagonal(cell);
    // A ball of this radius around any point of the cube holds the whole cube.
    const Scalar r_cap = std::max(r_min, Scalar(2) * std::sqrt(Scalar(3)) * oct.cube_side());
    const int bisection_steps = 30;
    const Scalar bisection_tolerance = 2e-3;  // relative width of the final bracket

    thread_local std::vector<Neighbor> nb;
    thread_local std::vector<Index> idx;
    thread_local std::vector<Scalar> dist;
    // The sorted neighbours of the last search; the bisection tests read prefixes of
    // the largest one (the points closer than the tested radius, in the same order a
    // search of that radius would give). Searching ahead (one search at 1.5 or 2.25 x
    // the radius for several growth steps) measured slower: the search's cost follows
    // the points it returns, and most candidates stop at r_min or 1.5 r_min.
    auto query = [&](Scalar R) {
        // Slightly larger than R so that every point with distance < R is included.
        in.tree->radius_search_squared(out.c, R * R * (1 + 1e-12), nb);
        idx.resize(nb.size());
        dist.resize(nb.size());
        for (std::size_t j = 0; j < nb.size(); ++j) {
            idx[j] = nb[j].index;
            dist[j] = std::sqrt(nb[j].squared_distance);
        }
    };
    // The nearest input point to c: the head of the list when it holds any point.
    auto nearest = [&]() { return nb.empty() ? in.tree->nearest(out.c) : nb.front(); };

    // Every ball smaller than the distance to the nearest point is empty and passes
    // eq. (6) trivially, so the search starts there (far from the data this saves
    // the queries that would return nothing, then everything).
    Scalar r = r_min;
    query(r_min);
    if (pu_radius_ok(in, out.c, r_min, idx, dist)) {
        // (only needed when the ball of radius r_min is empty)
        const Scalar d0 = nb.empty() ? std::sqrt(nearest().squared_distance) : Scalar(0);
        Scalar lo = std::max(r_min, std::min(d0, r_cap)), hi = lo;
        bool bracketed = false;
        while (hi < r_cap) {
            // Grow by 1.5 (a surface ball then holds ~2.25x the points: the largest
            // query stays close to the final radius).
            hi = std::min(Scalar(1.5) * hi, r_cap);
            query(hi);
            if (!pu_radius_ok(in, out.c, hi, idx, dist)) {
                bracketed = true;
                break;
            }
            lo = hi;
        }
        if (bracketed) {
            for (int it = 0; it < bisection_steps && hi - lo > bisection_tolerance * lo; ++it) {
                const Scalar mid = (lo + hi) / 2;
                if (pu_radius_ok(in, out.c, mid, idx, dist))
                    lo = mid;
                else
                    hi = mid;
            }
        }
        r = lo;
    }
    out.r = r;
    const PUFitState s = pu_fit(in, out.c, r, idx, dist);
    out.count = s.count;
    out.coherence = s.coherence;
    if (s.valid) {
        out.m = s.m;
        out.d = s.d;
    } else {
        // No point in the ball (far from the data) or normals cancelling out: use the
        // tangent plane of the nearest input point, which has the right sign far away.
        const Neighbor nn = nearest();
        out.m = (*in.normals)[nn.index];
        out.d = (*in.points)[nn.index];
        out.fallback = true;
    }
    return out;
}

/// The seeded random order of the candidates (Fisher-Yates on mt19937_64, whose
/// output sequence is fixed by the standard, so the order is portable). 32-bit: the
/// shuffle's swaps miss the cache, and half the bytes took 12M cells from 0.51 to 0.36 s.
/// @throws invalid_input when n >= 2^32 (an octree that large is not supported)
inline std::vector<std::uint32_t> pu_random_order(std::size_t n, std::uint64_t seed) {
    if (n > std::numeric_limits<std::uint32_t>::max())
        throw invalid_input("kintsugi::PUField: the octree has " + std::to_string(n) +
                            " cells; at most 4,294,967,295 are supported (lower max_level)");
    std::vector<std::uint32_t> order(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<std::uint32_t>(i);
    std::mt19937_64 rng(seed);
    for (std::size_t i = n; i > 1; --i) {
        const std::size_t j = static_cast<std::size_t>(rng() % i);
        std::swap(order[i - 1], order[j]);
    }
    return order;
}

/// The candidate cells not covered yet: a 64-ary hierarchical bit set (bit i of a
/// word one level up says whether word i below has a bit set), so that the next
/// uncovered cell from any position is found in a few word operations and fully
/// covered octree nodes are pruned at once.
///
/// One thread may erase while others read (pu_cover overlaps a batch's acceptance with
/// the next batch's searches): the words are accessed atomically (relaxed; plain moves
/// on x86-64), and a reader sees every element that is in the set throughout its call.
/// Elements erased meanwhile may or may not be seen.
class PUCellSet {
public:
    static constexpr std::size_t npos = static_cast<std::size_t>(-1);

    /// All of 0..n-1.
    explicit PUCellSet(std::size_t n) {
        std::size_t bits = n;
        do {
            const std::size_t words = (bits + 63) / 64;
            std::vector<std::uint64_t> w(words, ~std::uint64_t{0});
            if (bits % 64 != 0) w.back() = (std::uint64_t{1} << (bits % 64)) - 1;
            levels_.push_back(std::move(w));
            bits = words;
        } while (bits > 1);
    }
    [[nodiscard]] bool contains(std::size_t i) const { return (load(levels_[0][i >> 6]) >> (i & 63)) & 1u; }
    /// Removes i. One thread at a time.
    void erase(std::size_t i) {
        for (auto& level : levels_) {
            std::uint64_t& w = level[i >> 6];
            const std::uint64_t v = load(w) & ~(std::uint64_t{1} << (i & 63));
            std::atomic_ref<std::uint64_t>(w).store(v, std::memory_order_relaxed);
            if (v != 0) return;
            i >>= 6;
        }
    }
    /// The first element in [first, last), or last when there is none.
    [[nodiscard]] std::size_t next(std::size_t first, std::size_t last) const {
        if (first >= last) return last;
        const std::size_t r = find(0, first);
        return r < last ? r : last;
    }

private:
    static std::uint64_t load(const std::uint64_t& w) {
        return std::atomic_ref<std::uint64_t>(const_cast<std::uint64_t&>(w)).load(std::memory_order_relaxed);
    }
    // First set bit at position >= pos of level `lev`, or npos.
    [[nodiscard]] std::size_t find(std::size_t lev, std::size_t pos) const {
        const auto& W = levels_[lev];
        for (;;) {
            const std::size_t w = pos >> 6;
            if (w >= W.size()) return npos;
            const std::uint64_t b = load(W[w]) & (~std::uint64_t{0} << (pos & 63));
            if (b != 0) return (w << 6) | static_cast<std::size_t>(std::countr_zero(b));
            if (lev + 1 == levels_.size()) return npos;  // the top level is a single word
            const std::size_t nw = find(lev + 1, w + 1);
            if (nw == npos) return npos;
            const std::uint64_t c = load(W[nw]);
            if (c != 0) return (nw << 6) | static_cast<std::size_t>(std::countr_zero(c));
            pos = (nw + 1) << 6;  // emptied since the level above was read: look further
        }
    }
    std::vector<std::vector<std::uint64_t>> levels_;
};

/// Statistics of the cover.
struct PUCoverStats {
    std::size_t candidates = 0;       ///< octree cells (= initial candidates)
    std::size_t evaluated = 0;        ///< supports computed, including discarded speculative ones
    std::size_t fallback = 0;         ///< supports with no usable fit
};

/// The cover loop of §2.1.2: pick the next uncovered candidate in random order,
/// compute its support, remove every candidate whose cell has its 8 corners inside.
/// Supports are computed speculatively in parallel batches and accepted in order,
/// so the result is exactly that of the sequential loop, whatever the thread count.
/// `progress` is called on the calling thread between batches with a fraction in [0,1].
/// `order`: the candidates' order (pu_random_order(octree size, in.seed)), made by the
/// caller beside other work, or empty to make it here.
///
/// Cost (bunny00 with 10 % outliers, 1 thread, 2026-11-23): 2M points at level 9
/// (12M cells, 609K supports) 18.7 s, of which about 40 % finding the cells inside
/// each ball (now Octree::visit_cells_in_ball over the uncovered set) and 35 % the
/// radius searches and fits; 100K at level 8 (1.1M cells) ~1.4 s. The uncovered set as a
/// hierarchical bit set (instead of per-64-cell counters) and children classified
/// before their cell ranges are searched took 2M from 28.2 s to 18.7 s, same supports.
template <class ProgressFn>
std::vector<PUSupportData> pu_cover(const PUCoverInput& in, PUCoverStats& stats, ProgressFn&& progress,
                                    std::vector<std::uint32_t> order = {}) {
    const Octree& oct = *in.octree;
    const std::size_t n = oct.size();
    stats.candidates = n;
    if (order.size() != n) order = pu_random_order(n, in.seed);  // (which refuses n >= 2^32)
    // Uncovered cells: octree nodes whose cells are all covered already are pruned
    // from the covering queries, and the cells of nodes inside a ball are enumerated
    // among the uncovered ones only.
    PUCellSet uncovered(n);
    auto next_uncovered = [&](Index first, Index last) { return uncovered.next(first, last); };
    std::vector<PUSupportData> supports;
    std::size_t remaining = n;
    std::size_t pos = 0;
    // Batch size only changes how much speculative work is wasted, never the result:
    // it shrinks when many candidates of a batch end up covered by earlier ones (and
    // reacts one batch late, as the next batch is selected before this one is accepted).
    // stats.evaluated counts the candidates selected, covered ones included.
    std::size_t batch_size = 64;
    // Two batches in flight: while one is accepted (its cells erased from `uncovered`,
    // sequentially), the next one's supports and cells are computed. A candidate of the
    // next batch that the accepted one covers is skipped at its own acceptance, and its
    // list of cells is filtered then, so erasures that its search saw or missed change
    // nothing: the supports are those of the sequential loop. (Accepting the 2M bench
    // input's batches took 0.43 s of the cover's 6.9 s, sequentially.)
    struct Batch {
        std::vector<Index> cand;
        std::vector<PUSupportData> fits;
        std::vector<std::vector<Index>> inside;  // per fit: the cells with 8 corners in its ball
    };
    Batch cur, nxt;
    auto select = [&](Batch& b) {
        b.cand.clear();
        while (pos < n && b.cand.size() < batch_size) {
            if (uncovered.contains(order[pos])) b.cand.push_back(order[pos]);
            ++pos;
        }
        stats.evaluated += b.cand.size();
    };
    // Speculative and parallel: the support and the cells it would cover are pure
    // functions of the candidate cell.
    auto compute = [&](Batch& b) {
        b.fits.resize(b.cand.size());
        b.inside.resize(b.cand.size());
        parallel_for(0, b.cand.size(), [&](std::size_t k) {
            b.fits[k] = pu_compute_support(in, b.cand[k]);
            const PUSupportData& s = b.fits[k];
            auto& list = b.inside[k];
            list.clear();
            // the cells with their 8 corners in the ball, among the uncovered ones
            oct.visit_cells_in_ball(s.c, s.r, [&](Index c) {
                if (uncovered.contains(c)) list.push_back(c);
            }, next_uncovered);
        }, 1);
    };
    auto accept = [&](const Batch& b) {
        std::size_t accepted = 0;
        for (std::size_t k = 0; k < b.cand.size(); ++k) {
            if (!uncovered.contains(b.cand[k])) continue;  // covered by an earlier support
            ++accepted;
            const PUSupportData& s = b.fits[k];
            for (const Index c : b.inside[k])
                if (uncovered.contains(c)) {
                    uncovered.erase(c);
                    --remaining;
                }
            if (s.fallback) ++stats.fallback;
            supports.push_back(s);
        }
        if (accepted * 4 >= b.cand.size() * 3)
            batch_size = std::min<std::size_t>(batch_size * 2, 1024);
        else if (accepted * 2 < b.cand.size())
            batch_size = std::max<std::size_t>(batch_size / 2, 8);
    };
    select(cur);
    compute(cur);
    while (!cur.cand.empty()) {
        select(nxt);  // before cur's acceptance: candidates it covers are skipped later
        if (nxt.cand.empty()) {
            accept(cur);
        } else {
            // compute(nxt) writes only nxt, and reads `uncovered` while accept(cur) erases
            // from it (relaxed atomics, PUCellSet): a search misses no cell that stays
            // uncovered, and accept(nxt) filters out what cur covers. accept(cur) alone
            // writes `supports`, `remaining`, `batch_size` and stats.fallback.
            parallel_invoke([&] { compute(nxt); }, [&] { accept(cur); });
        }
        progress(1.0 - static_cast<double>(remaining) / static_cast<double>(n));
        std::swap(cur, nxt);
        nxt.cand.clear();
    }
    return supports;
}

}  // namespace kintsugi::detail
