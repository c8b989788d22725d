// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file uniform_grid.hpp
/// @brief A uniform grid over a point set: every point within an axis-aligned cube
/// or a ball around a query, for neighbourhoods of one fixed size.
///
/// @code
/// kintsugi::UniformGrid grid(points, h);          // any PointSet; cell side h
/// grid.for_each_in_cube(q, h, [&](kintsugi::Index i, kintsugi::Scalar d2) { ... });
/// grid.for_each_in_ball(q, r, [&](kintsugi::Index i, kintsugi::Scalar d2) { ... });
/// std::vector<kintsugi::Neighbor> nn;
/// grid.radius_search_squared(q, r * r, nn);        // sorted, as KdTree's
/// grid.knn(q, 8, nn);                               // a SpatialIndex, as KdTree
/// kintsugi::UniformGrid out(h);                     // empty, cell side h
/// kintsugi::Index i = out.append(p);                // grows: for outputs built point by point
/// for (std::size_t s = 0; s < grid.size(); ++s)      // the caller's data in the grid's
///     mine[s] = data[grid.slot_index(s)];            // storage order (slots), then
/// grid.for_each_slot_in_ball(q, r, [&](std::size_t s, kintsugi::Scalar d2) { use(mine[s]); });
/// @endcode
///
/// Cells of side `cell` (best: the usual query half side or radius, so that a query
/// visits at most 3×3×3 cells) are keyed by their integer coordinates and found
/// through an open-addressing hash table, so memory is linear in the points whatever
/// the extent. The points are stored sorted by cell and, within a cell, by index: a
/// query visits its neighbours in an order fixed by the points alone (no sort per
/// query; results independent of the thread count). Queries are const and
/// thread-safe. It models SpatialIndex. Against KdTree: cheaper to build and to
/// query when every query has the same small size (the smoothing filters' cubes), and
/// it grows (append); but not adaptive: a query much larger than a cell visits many
/// cells, and a k-nearest query far from every point is slow.

#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/spatial/bucket_grid.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#include <xmmintrin.h>
#endif


#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <optional>
#include <utility>
#include <vector>

namespace kintsugi {

/// Uniform grid over a copy of a point set, for cube and ball queries of a fixed
/// size. See the file comment.
class UniformGrid {
public:
    UniformGrid() = default;
    /// An empty grid with cells of side `cell`, to be filled with append().
    /// @throws invalid_input if cell is not a finite number > 0.
    explicit UniformGrid(Scalar cell) { build(std::vector<Vec3>{}, cell); }

    /// Builds the grid over any PointSet (positions copied).
    /// @param cell cell side, in the points' units (> 0; enlarged when the extent
    ///        would need more than 2^20 cells per axis)
    /// @throws invalid_input if a coordinate is NaN or infinite, or cell is not > 0.
    template <PointSet P>
    UniformGrid(const P& points, Scalar cell) {
        build(kintsugi::gather_points(points), cell);
    }
    /// Builds the grid over positions.
    UniformGrid(const std::vector<Vec3>& points, Scalar cell) { build(points, cell); }
    /// Builds the grid over the points i of `points` with keep(i) true (the others are
    /// left out of every query but keep their index).
    template <class Keep>
    UniformGrid(const std::vector<Vec3>& points, Scalar cell, Keep&& keep) {
        build(points, cell, std::forward<Keep>(keep));
    }

    /// (Re)builds the grid over `pts` (indices = positions in pts), reusing the memory
    /// of an earlier build; see the constructors.
    void build(const std::vector<Vec3>& pts, Scalar cell) {
        build(pts, cell, [](std::size_t) { return true; });
    }
    /// (Re)builds the grid over the points i of `pts` with keep(i) true (keep is
    /// called once per point, possibly from several threads).
    template <class Keep>
    void build(const std::vector<Vec3>& pts, Scalar cell, Keep&& keep) {

        const std::size_t n = pts.size();
        validate(pts, cell);
        requested_cell_ = cell;
        count_ = n;
        extra_point_.clear();
        extra_index_.clear();
        lo_ = Vec3::Constant(std::numeric_limits<Scalar>::max());
        Vec3 hi = Vec3::Constant(std::numeric_limits<Scalar>::lowest());
        for (std::size_t i = 0; i < n; ++i) {
            lo_ = lo_.cwiseMin(pts[i]);
            hi = hi.cwiseMax(pts[i]);
        }
        if (n == 0) lo_ = hi = Vec3::Zero();
        // 21 bits per axis in the key: enlarge the cells if the extent needs more.
        const Scalar extent = (hi - lo_).maxCoeff();
        cell_ = std::max({cell, extent / Scalar((1 << 20) - 2), std::numeric_limits<Scalar>::min()});
        inv_ = 1 / cell_;
        // (cell key, index) of every kept point; left-out points get the key empty_
        // (above every real key: 63 bits) and are cut off after sorting.
        auto& order = order_;
        order.resize(n);
        parallel_for(0, n, [&](std::size_t i) {
            order[i] = {keep(i) ? key(coord(pts[i])) : empty_, static_cast<std::uint32_t>(i)};
        }, 4096);
        detail::sort_maybe_parallel(order);  // unique (key, index) pairs: one result
        order.resize(static_cast<std::size_t>(
            std::lower_bound(order.begin(), order.end(), std::pair<std::uint64_t, std::uint32_t>{empty_, 0}) -
            order.begin()));
        index_.resize(order.size());
        point_.resize(order.size());
        parallel_for(0, order.size(), [&](std::size_t k) {
            index_[k] = order[k].second;
            point_[k] = pts[order[k].second];
        }, 4096);
        start_.clear();
        auto& keys = keys_;
        keys.clear();
        for (std::size_t k = 0; k < order.size(); ++k)
            if (k == 0 || order[k].first != order[k - 1].first) {
                keys.push_back(order[k].first);
                start_.push_back(static_cast<std::uint32_t>(k));
            }
        start_.push_back(static_cast<std::uint32_t>(order.size()));
        // Single-precision columns relative to lo_, each cell padded to a multiple of 4
        // with points at infinity (never inside a cube), for gather().
        const std::size_t ncell = keys.size();
        pad_start_.resize(ncell + 1);
        pad_start_[0] = 0;
        for (std::size_t c = 0; c < ncell; ++c) pad_start_[c + 1] = pad_start_[c] + (start_[c + 1] - start_[c] + 3) / 4 * 4;
        px_.resize(pad_start_[ncell]);
        py_.resize(pad_start_[ncell]);
        pz_.resize(pad_start_[ncell]);
        pidx_.resize(pad_start_[ncell]);
        parallel_for(0, ncell, [&](std::size_t c) {
            std::uint32_t out = pad_start_[c];
            for (std::uint32_t j = start_[c]; j < start_[c + 1]; ++j, ++out) {
                const Eigen::Vector3f q = (point_[j] - lo_).cast<float>();
                px_[out] = q.x();
                py_[out] = q.y();
                pz_[out] = q.z();
                pidx_[out] = index_[j];
            }
            for (; out < pad_start_[c + 1]; ++out) {
                px_[out] = py_[out] = pz_[out] = std::numeric_limits<float>::infinity();
                pidx_[out] = 0;
            }
        }, 1024);
        table_.reset(keys.size());
        for (std::size_t c = 0; c < keys.size(); ++c) (void)table_.find_or_insert(keys[c], static_cast<std::uint32_t>(c));
        // Appended points wait in buckets reaching 2^20 cells beyond lo_ on every side.
        Vec3 extra_origin = lo_ - Vec3::Constant(std::ldexp(cell_, 20));
        if (!extra_origin.allFinite()) extra_origin = lo_;  // near the largest doubles: only above lo_
        extra_cells_.emplace(extra_origin, cell_);
        // The non-empty cells among the 3×3×3 around each cell, in (z, y, x) order: a
        // query of half side ≤ cell from a point inside a cell visits only those. The
        // keys are sorted and adding a fixed offset keeps them sorted, so each of the 27
        // offsets is one forward walk over the keys (no hash look-ups), in chunks.
        const std::size_t nc = keys.size();
        auto& nbr = nbr_scratch_;
        auto& count = count_scratch_;
        nbr.resize(nc);
        count.assign(nc, 0);
        constexpr std::size_t walk = 4096;
        parallel_for(0, (nc + walk - 1) / walk, [&](std::size_t chunk) {
            const std::size_t first = chunk * walk, last = std::min(nc, first + walk);
            for (std::int64_t dz = -1; dz <= 1; ++dz)
                for (std::int64_t dy = -1; dy <= 1; ++dy)
                    for (std::int64_t dx = -1; dx <= 1; ++dx) {
                        const std::int64_t off = dx + dy * (std::int64_t{1} << 21) + dz * (std::int64_t{1} << 42);
                        auto at = keys.begin();
                        bool started = false;
                        for (std::size_t c = first; c < last; ++c) {
                            const std::int64_t x = static_cast<std::int64_t>(keys[c] & mask21_) + dx,
                                               y = static_cast<std::int64_t>((keys[c] >> 21) & mask21_) + dy,
                                               z = static_cast<std::int64_t>(keys[c] >> 42) + dz;
                            if (x < 0 || y < 0 || z < 0 || x > max_coord_ || y > max_coord_ || z > max_coord_) continue;
                            const std::uint64_t want = static_cast<std::uint64_t>(static_cast<std::int64_t>(keys[c]) + off);
                            if (!started) {
                                at = std::lower_bound(keys.begin(), keys.end(), want);
                                started = true;
                            }
                            while (at != keys.end() && *at < want) ++at;
                            if (at != keys.end() && *at == want)
                                nbr[c][count[c]++] = static_cast<std::uint32_t>(at - keys.begin());
                        }
                    }
        }, 1);
        nbr_start_.assign(nc + 1, 0);
        for (std::size_t c = 0; c < nc; ++c) nbr_start_[c + 1] = nbr_start_[c] + count[c];
        nbr_cell_.resize(nbr_start_[nc]);
        parallel_for(0, nc, [&](std::size_t c) {
            std::copy_n(nbr[c].begin(), count[c], nbr_cell_.begin() + nbr_start_[c]);
        }, 256);
    }

    /// Number of points in the grid (left-out points not counted).
    [[nodiscard]] std::size_t size() const { return index_.size() + extra_index_.size(); }
    /// The cell side in use (the one asked for, or larger for a very wide extent).
    [[nodiscard]] Scalar cell_size() const { return cell_; }

    /// Adds a point and returns its index (the number of indices given so far: the
    /// built points' count plus the earlier appends). Appended points are held apart,
    /// hashed by cell, until they are as many as the points merged so far (at least
    /// 1024); then the grid is rebuilt over all of them, so n appends cost
    /// O(n log n) in all. Queries see every point at once; the points not yet merged
    /// come after the others, by cell in (z, y, x) order and by index within a cell.
    /// Not thread-safe with concurrent queries.
    /// @throws invalid_input if p has a NaN or infinite coordinate, or the grid was
    ///   default-constructed (no cell side).
    Index append(const Vec3& p) {
        if (!p.allFinite())
            throw invalid_input("kintsugi::UniformGrid::append: the point has a NaN or infinite coordinate");
        if (!(requested_cell_ > 0))
            throw invalid_input("kintsugi::UniformGrid::append: the grid has no cell side; construct it with one "
                                "(UniformGrid(cell) or UniformGrid(points, cell))");
        if (count_ + 1 >= none_)
            throw invalid_input("kintsugi::UniformGrid::append: at most 2^32 - 2 points are supported");
        const Index id = count_++;
        extra_point_.push_back(p);
        extra_index_.push_back(static_cast<std::uint32_t>(id));
        if (extra_point_.size() >= std::max<std::size_t>(1024, index_.size()) || !extra_cells_->in_range(p))
            merge();
        else
            extra_cells_->insert(p, static_cast<std::uint32_t>(extra_point_.size() - 1));
        return id;
    }

    /// Calls f(index, squared distance) for every point in the cube of half side h
    /// centred at c (boundary included), in the grid's order (see the file comment).
    /// @param max_candidates at most this many points are tested: when the cells the
    ///        cube overlaps hold more, an evenly strided subset of them (in the grid's
    ///        order) is, so that one query costs O(max_candidates) however dense the
    ///        points. Default: no limit.
    /// @throws invalid_input if c has a NaN or infinite coordinate or h is NaN.
    template <class F>
    void for_each_in_cube(const Vec3& c, Scalar h, F&& f, std::size_t max_candidates = no_limit) const {
        require_query(c, h, "for_each_in_cube");
        auto test = [&](Index i, const Vec3& p) {
            const Vec3 d = p - c;
            if (d.cwiseAbs().maxCoeff() <= h) f(i, d.squaredNorm());
        };
        if (max_candidates != no_limit && candidates(c, h, start_) > max_candidates) {
            for_each_sampled(c, h, start_, max_candidates,
                             [&](std::size_t j) { test(static_cast<Index>(index_[j]), point_[j]); });
            if (!extra_point_.empty()) for_each_extra(c, h, test);  // appended points: all tested
            return;
        }
        for_each_candidate(c, h, test);
    }

    /// No limit on the points a query tests (see for_each_in_cube and gather).
    static constexpr std::size_t no_limit = ~std::size_t{0};

    /// Calls f(index, squared distance) for every point at distance at most r from c,
    /// in the grid's order.
    /// @throws invalid_input if c has a NaN or infinite coordinate or r is NaN.
    template <class F>
    void for_each_in_ball(const Vec3& c, Scalar r, F&& f) const {
        require_query(c, r, "for_each_in_ball");
        const Scalar r2 = r * r;
        for_each_candidate(c, r, [&](Index i, const Vec3& p) {
            const Scalar d2 = (p - c).squaredNorm();
            if (d2 <= r2) f(i, d2);
        });
    }

    /// Slots: the grid stores its points in slots 0 .. size() - 1, in the grid's order
    /// (by cell in (z, y, x) order, by index within a cell; the appended points not
    /// merged yet after the others, in append order). A caller can keep data of its own
    /// per point in slot order, so that a query's results (for_each_slot_in_ball) read
    /// it from a few contiguous runs of memory instead of at scattered indices. Slots are
    /// renumbered by build() and by an append() that merges (the point count reaches
    /// twice the merged count, or at least 1024 appended points).
    /// The index of the point in slot s (s < size()).
    [[nodiscard]] Index slot_index(std::size_t s) const {
        return static_cast<Index>(s < index_.size() ? index_[s] : extra_index_[s - index_.size()]);
    }
    /// The position of the point in slot s (s < size()).
    [[nodiscard]] const Vec3& slot_point(std::size_t s) const {
        return s < point_.size() ? point_[s] : extra_point_[s - point_.size()];
    }
    /// Calls f(slot, squared distance) for every point at distance at most r from c,
    /// in the grid's order (the same points and order as for_each_in_ball).
    /// @throws invalid_input if c has a NaN or infinite coordinate or r is NaN.
    template <class F>
    void for_each_slot_in_ball(const Vec3& c, Scalar r, F&& f) const {
        require_query(c, r, "for_each_slot_in_ball");
        const Scalar r2 = r * r;
        for_each_candidate_slot(c, r, [&](std::size_t s, const Vec3& p) {
            const Scalar d2 = (p - c).squaredNorm();
            if (d2 <= r2) f(s, d2);
        });
    }

    /// All points whose squared distance to q is at most `squared_radius` (a negative
    /// radius finds nothing), as KdTree::radius_search_squared.
    /// @param sorted true: by increasing distance, ties by index; false: the grid's order
    /// @throws invalid_input if q has a NaN or infinite coordinate or the radius is NaN.
    void radius_search_squared(const Vec3& q, Scalar squared_radius, std::vector<Neighbor>& out,
                               bool sorted = true) const {
        out.clear();
        if (std::isnan(squared_radius))
            throw invalid_input("kintsugi::UniformGrid::radius_search_squared: the squared radius is NaN");
        require_query(q, 0, "radius_search_squared");
        if (squared_radius < 0) return;
        for_each_candidate(q, std::sqrt(squared_radius), [&](Index i, const Vec3& p) {
            const Scalar d2 = (p - q).squaredNorm();
            if (d2 <= squared_radius) out.push_back({i, d2});
        });
        if (sorted) detail::sort_neighbors(out);
    }

    /// The min(k, size()) nearest points to q, by increasing distance, ties by index
    /// (the same answer as KdTree::knn). The search grows a cube from one cell until it
    /// holds the k-th nearest point's ball: cheap when the k nearest lie within a few
    /// cells, slow for a query far from every point.
    /// @throws invalid_input if q has a NaN or infinite coordinate.
    void knn(const Vec3& q, std::size_t k, std::vector<Neighbor>& out) const {
        out.clear();
        require_query(q, 0, "knn");
        k = std::min(k, size());
        if (k == 0) return;
        for (Scalar h = cell_;; h *= 2) {
            out.clear();
            for_each_candidate(q, h, [&](Index i, const Vec3& p) {
                const Vec3 d = p - q;
                if (d.cwiseAbs().maxCoeff() <= h) out.push_back({i, d.squaredNorm()});
            });
            // Done when the cube holds the ball through the k-th point (then every point
            // at most that far is in out) or holds every point.
            if (out.size() < k) continue;
            detail::sort_neighbors(out);
            if (out[k - 1].squared_distance <= h * h || out.size() == size()) break;
        }
        out.resize(k);
    }
    /// Convenience overload returning a new vector.
    [[nodiscard]] std::vector<Neighbor> knn(const Vec3& q, std::size_t k) const {
        std::vector<Neighbor> out;
        knn(q, k, out);
        return out;
    }

    /// The nearest point to q (ties by index).
    /// @throws invalid_input if the grid is empty or q has a NaN or infinite coordinate.
    [[nodiscard]] Neighbor nearest(const Vec3& q) const {
        if (size() == 0) throw invalid_input("kintsugi::UniformGrid::nearest: the grid is empty");
        std::vector<Neighbor> nn;
        knn(q, 1, nn);
        return nn.front();
    }

    /// The points in the cube of half side h centred at c (boundary included), in the
    /// same order as for_each_in_cube: indices into `index`, squared distances into
    /// `dist2` (both overwritten). The fast path of the fixed-size neighbourhoods: the
    /// cube test and the distances are computed in single precision relative to the
    /// grid's corner (a point within ~1e-7 of the extent from the cube's boundary may
    /// fall either side), on the cells' padded columns four points at a time (SSE2),
    /// with no branch on which points fall inside (that is as good as random, and
    /// mispredicted branches cost more than the test).
    /// @param max_candidates as for for_each_in_cube: at most this many points tested
    ///        (an evenly strided subset when the cells hold more); default no limit.
    /// @throws invalid_input if c has a NaN or infinite coordinate or h is NaN.
    void gather(const Vec3& c, Scalar h, std::vector<std::uint32_t>& index, std::vector<Scalar>& dist2,
                std::size_t max_candidates = no_limit) const {
        index.clear();
        dist2.clear();
        require_query(c, h, "gather");
        std::size_t n = 0;
        const Eigen::Vector3f q = (c - lo_).cast<float>();
        const float hf = static_cast<float>(h);
        if (max_candidates != no_limit && candidates(c, h, pad_start_) > max_candidates) {
            index.resize(max_candidates);
            dist2.resize(max_candidates);
            for_each_sampled(c, h, pad_start_, max_candidates, [&](std::size_t j) {
                const float dx = px_[j] - q.x(), dy = py_[j] - q.y(), dz = pz_[j] - q.z();
                if (std::abs(dx) <= hf && std::abs(dy) <= hf && std::abs(dz) <= hf) {
                    index[n] = pidx_[j];
                    dist2[n++] = dx * dx + dy * dy + dz * dz;
                }
            });
            index.resize(n);
            dist2.resize(n);
            append_extras(c, h, index, dist2);  // appended points: all tested
            return;
        }
#if defined(__SSE2__)
        const __m128 qx = _mm_set1_ps(q.x()), qy = _mm_set1_ps(q.y()), qz = _mm_set1_ps(q.z()), vh = _mm_set1_ps(hf);
        const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
        alignas(16) float d2[4];
#endif
        for_each_cell(c, h, [&](std::uint32_t cell) {
            const std::size_t first = pad_start_[cell], last = pad_start_[cell + 1];
            if (index.size() < n + (last - first)) {  // every slot is written before it is kept
                index.resize(2 * (n + (last - first)));
                dist2.resize(index.size());
            }
            std::uint32_t* out_i = index.data();
            Scalar* out_d = dist2.data();
#if defined(__SSE2__)
            for (std::size_t j = first; j < last; j += 4) {
                const __m128 dx = _mm_sub_ps(_mm_loadu_ps(px_.data() + j), qx);
                const __m128 dy = _mm_sub_ps(_mm_loadu_ps(py_.data() + j), qy);
                const __m128 dz = _mm_sub_ps(_mm_loadu_ps(pz_.data() + j), qz);
                const __m128 in = _mm_and_ps(_mm_and_ps(_mm_cmple_ps(_mm_and_ps(dx, abs_mask), vh),
                                                        _mm_cmple_ps(_mm_and_ps(dy, abs_mask), vh)),
                                             _mm_cmple_ps(_mm_and_ps(dz, abs_mask), vh));
                const int bits = _mm_movemask_ps(in);
                _mm_store_ps(d2, _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz)));
                for (int b = 0; b < 4; ++b) {
                    out_i[n] = pidx_[j + b];
                    out_d[n] = d2[b];
                    n += static_cast<std::size_t>((bits >> b) & 1);
                }
            }
#else
            for (std::size_t j = first; j < last; ++j) {
                const float dx = px_[j] - q.x(), dy = py_[j] - q.y(), dz = pz_[j] - q.z();
                out_i[n] = pidx_[j];
                out_d[n] = dx * dx + dy * dy + dz * dz;
                n += static_cast<std::size_t>((std::abs(dx) <= hf) & (std::abs(dy) <= hf) & (std::abs(dz) <= hf));
            }
#endif
        });
        index.resize(n);
        dist2.resize(n);
        append_extras(c, h, index, dist2);
    }

private:
    void validate(const std::vector<Vec3>& pts, Scalar cell) const {
        if (!(cell > 0) || !std::isfinite(cell))
            throw invalid_input("kintsugi::UniformGrid: the cell side is " + std::to_string(cell) +
                                "; pass a finite cell side > 0 (e.g. the query radius)");
        if (pts.size() >= none_)
            throw invalid_input("kintsugi::UniformGrid: " + std::to_string(pts.size()) +
                                " points; at most 2^32 - 2 are supported");
        detail::check_finite_points(pts, "kintsugi::UniformGrid: point ");
    }
    /// gather() on the appended points not merged yet (double precision).
    void append_extras(const Vec3& c, Scalar h, std::vector<std::uint32_t>& index, std::vector<Scalar>& dist2) const {
        if (extra_point_.empty()) return;
        for_each_extra(c, h, [&](Index i, const Vec3& p) {
            const Vec3 d = p - c;
            if (d.cwiseAbs().maxCoeff() <= h) {
                index.push_back(static_cast<std::uint32_t>(i));
                dist2.push_back(d.squaredNorm());
            }
        });
    }
    /// Calls visit(index, position) for every point of the cells that may hold points
    /// of the cube of half side h centred at c: merged points, then appended ones.
    template <class Visit>
    void for_each_candidate(const Vec3& c, Scalar h, Visit&& visit) const {
        for_each_candidate_slot(c, h, [&](std::size_t s, const Vec3& p) { visit(slot_index(s), p); });
    }
    /// for_each_candidate by slot (see slot_index): visit(slot, position).
    template <class Visit>
    void for_each_candidate_slot(const Vec3& c, Scalar h, Visit&& visit) const {
        for_each_cell(c, h, [&](std::uint32_t cidx) {
            for (std::size_t j = start_[cidx]; j < start_[cidx + 1]; ++j) visit(j, point_[j]);
        });
        if (!extra_point_.empty())
            for_each_extra_slot(c, h, [&](std::size_t j) { visit(index_.size() + j, extra_point_[j]); });
    }
    /// for_each_extra_slot with visit(index, position).
    template <class Visit>
    void for_each_extra(const Vec3& c, Scalar h, Visit&& visit) const {
        for_each_extra_slot(c, h, [&](std::size_t j) { visit(static_cast<Index>(extra_index_[j]), extra_point_[j]); });
    }
    /// Calls visit(j) for the appended points not merged yet (j: their place in
    /// extra_point_) of the cells that meet the cube: by cell in (z, y, x) order, then
    /// by index; all of them in index order when the cube spans more cells than they fill.
    template <class Visit>
    void for_each_extra_slot(const Vec3& c, Scalar h, Visit&& visit) const {
        if (!(extra_cells_->cells_in_cube(c, h) <= static_cast<double>(extra_cells_->cell_count()))) {
            for (std::size_t j = 0; j < extra_point_.size(); ++j) visit(j);
            return;
        }
        (void)extra_cells_->visit_cells(c, h, [&](const std::vector<Vec3>&, const std::vector<std::uint32_t>& slots) {
            for (std::uint32_t j : slots) visit(std::size_t{j});
            return false;
        });
    }
    /// Rebuilds the grid over the merged and the appended points (indices kept; the
    /// points the keep filter left out stay out).
    void merge() {
        std::vector<Vec3> all(count_, Vec3::Zero());
        std::vector<unsigned char> present(count_, 0);
        for (std::size_t j = 0; j < index_.size(); ++j) {
            all[index_[j]] = point_[j];
            present[index_[j]] = 1;
        }
        for (std::size_t j = 0; j < extra_point_.size(); ++j) {
            all[extra_index_[j]] = extra_point_[j];
            present[extra_index_[j]] = 1;
        }
        build(all, requested_cell_, [&present](std::size_t i) { return present[i] != 0; });
    }
    static void require_query(const Vec3& c, Scalar size, const char* fn) {
        if (!c.allFinite() || std::isnan(size))
            throw invalid_input(std::string("kintsugi::UniformGrid::") + fn +
                                ": the query point or size has a NaN or infinite value");
    }

    /// Number of slots (first[cell] .. first[cell + 1]) in the cells a query visits.
    std::size_t candidates(const Vec3& c, Scalar h, const std::vector<std::uint32_t>& first) const {
        std::size_t total = 0;
        for_each_cell(c, h, [&](std::uint32_t cell) { total += first[cell + 1] - first[cell]; });
        return total;
    }
    /// Calls test(slot) for `max` slots evenly strided over the slots of the cells a
    /// query visits (taken in the order of for_each_cell): slot k·total/max for k < max.
    template <class Test>
    void for_each_sampled(const Vec3& c, Scalar h, const std::vector<std::uint32_t>& first, std::size_t max,
                          Test&& test) const {
        const std::size_t total = candidates(c, h, first);
        const double step = static_cast<double>(total) / static_cast<double>(max);  // > 1
        std::size_t base = 0, k = 0;
        for_each_cell(c, h, [&](std::uint32_t cell) {
            const std::size_t count = first[cell + 1] - first[cell];
            for (; k < max; ++k) {
                const std::size_t pos = static_cast<std::size_t>(static_cast<double>(k) * step);
                if (pos >= base + count) break;
                test(first[cell] + (pos - base));
            }
            base += count;
        });
    }

    /// Calls visit(cell) for every non-empty cell that may hold points of the cube of
    /// half side h centred at c, in (z, y, x) order.
    template <class Visit>
    void for_each_cell(const Vec3& c, Scalar h, Visit&& visit) const {
        if (index_.empty()) return;
        const Vec3 a = (c - lo_) * inv_;
        const Scalar r = h * inv_;
        std::array<std::int64_t, 3> l{}, u{};
        const Scalar top = static_cast<Scalar>(max_coord_);
        for (int k = 0; k < 3; ++k) {
            const Scalar lo = a[k] - r, hi = a[k] + r;
            if (!(hi >= 0) || !(lo <= top)) return;  // outside the grid (or NaN): no point
            l[k] = static_cast<std::int64_t>(std::floor(std::max(lo, Scalar(0))));
            u[k] = static_cast<std::int64_t>(std::floor(std::min(hi, top)));
        }
        // Usual case: the query point lies in a non-empty cell and h ≤ cell, so the cube
        // is covered by that cell's precomputed neighbours (one hash look-up).
        if (h <= cell_ && a.minCoeff() >= 0 && a.maxCoeff() < static_cast<Scalar>(max_coord_)) {
            const std::uint32_t home = find(coord(c));
            if (home != none_) {
                for (std::size_t k = nbr_start_[home]; k < nbr_start_[home + 1]; ++k) visit(nbr_cell_[k]);
                return;
            }
        }
        // A query box with more cells than the grid holds: walk the non-empty cells
        // (their keys are sorted, so this is the same (z, y, x) order).
        const double box_cells = double(u[0] - l[0] + 1) * double(u[1] - l[1] + 1) * double(u[2] - l[2] + 1);
        if (box_cells > static_cast<double>(keys_.size())) {
            for (std::size_t cidx = 0; cidx < keys_.size(); ++cidx) {
                const std::int64_t x = static_cast<std::int64_t>(keys_[cidx] & mask21_),
                                   y = static_cast<std::int64_t>((keys_[cidx] >> 21) & mask21_),
                                   z = static_cast<std::int64_t>(keys_[cidx] >> 42);
                if (x >= l[0] && x <= u[0] && y >= l[1] && y <= u[1] && z >= l[2] && z <= u[2])
                    visit(static_cast<std::uint32_t>(cidx));
            }
            return;
        }
        for (std::int64_t z = l[2]; z <= u[2]; ++z)
            for (std::int64_t y = l[1]; y <= u[1]; ++y)
                for (std::int64_t x = l[0]; x <= u[0]; ++x) {
                    const std::uint32_t cidx = find({x, y, z});
                    if (cidx != none_) visit(cidx);
                }
    }

    static constexpr std::uint64_t empty_ = detail::CellTable::empty;
    static constexpr std::uint32_t none_ = detail::CellTable::none;
    static constexpr std::uint64_t mask21_ = (std::uint64_t{1} << 21) - 1;
    std::uint32_t find(const std::array<std::int64_t, 3>& g) const { return table_.find(key(g)); }
    static constexpr std::int64_t max_coord_ = detail::cell_coord_max;
    std::array<std::int64_t, 3> coord(const Vec3& p) const {
        const Vec3 a = (p - lo_) * inv_;
        std::array<std::int64_t, 3> g{};
        for (int k = 0; k < 3; ++k)
            g[k] = static_cast<std::int64_t>(std::floor(std::clamp(a[k], Scalar(0), static_cast<Scalar>(max_coord_))));
        return g;
    }
    static std::uint64_t key(const std::array<std::int64_t, 3>& g) { return detail::pack_cell(g); }
    Vec3 lo_ = Vec3::Zero();
    Scalar cell_ = 1, inv_ = 1;
    Scalar requested_cell_ = 0;  // the cell side asked for (0: none yet)
    std::size_t count_ = 0;      // indices given: built points + appends
    // Appended points not merged yet: positions, indices, and their places in those
    // two arrays bucketed by cell (set by build()).
    std::vector<Vec3> extra_point_;
    std::vector<std::uint32_t> extra_index_;
    std::optional<BucketGrid<std::uint32_t>> extra_cells_;
    detail::CellTable table_;  // cell key -> cell (the merged points' runs)
    std::vector<std::uint32_t> index_, start_, nbr_cell_;
    std::vector<std::size_t> nbr_start_;
    std::vector<Vec3> point_;
    // gather(): point_ − lo_ in single precision and the indices, by cell, each cell
    // padded to a multiple of 4 (pad_start_: the cells' first slots)
    std::vector<float> px_, py_, pz_;
    std::vector<std::uint32_t> pidx_, pad_start_;
    // Scratch of build(), kept so that rebuilding a grid allocates nothing new.
    std::vector<std::pair<std::uint64_t, std::uint32_t>> order_;
    std::vector<std::uint64_t> keys_;
    std::vector<std::array<std::uint32_t, 27>> nbr_scratch_;
    std::vector<std::uint8_t> count_scratch_;
};

static_assert(SpatialIndex<UniformGrid>);

}  // namespace kintsugi
