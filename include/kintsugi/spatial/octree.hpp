// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file octree.hpp
/// @brief A linear (Morton-ordered) octree over a bounding cube: per-cell point
/// lists, 2:1 balance, face/edge/vertex neighbours, cell corners, point location.
///
/// @code
/// kintsugi::Octree tree(points, {.max_level = 8});      // any PointSet
/// for (kintsugi::Index c = 0; c < tree.size(); ++c) {
///     kintsugi::Vec3 centre = tree.cell_center(c);
///     for (kintsugi::Index p : tree.cell_points(c)) { ... }  // original point indices
/// }
/// std::vector<kintsugi::Index> nb;
/// tree.neighbors(c, kintsugi::Adjacency::face, nb);
/// kintsugi::Index leaf = tree.locate(q);               // Octree::npos outside the cube
/// @endcode
///
/// Only the leaves are stored ("cells"): they tile the bounding cube without
/// overlap and are sorted by the Morton code of their minimum corner, so every
/// aligned block of space is a contiguous range of cells and point location is a
/// binary search. Each cell's points are a contiguous range of one permuted index
/// array (linear memory). Integer coordinates ("anchors") are in units of the
/// finest grid, 2^-max_level of the cube side.
///
/// Subdivision rule (Nagai, Ohtake, Suzuki 2011, §2.1.2, after MPU): every cell
/// that holds a point is split until the max level, so every input point lies in a
/// cell of the max level; with `max_points_per_cell = n > 0` a cell is split only
/// while it holds more than n points (the octree-RBF rule). Balance: neighbouring
/// cells (sharing a face, an edge or a vertex) differ by at most one level.
///
/// The tree is immutable after construction; every query is const and thread-safe.
/// Construction is deterministic whatever the thread count.

#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/frame.hpp>
#include <kintsugi/core/memory.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/spatial/morton.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

/// Options of the Octree (aggregate; field order is API).
struct OctreeParams {
    /// Deepest level, in [1, 12]; the finest cells have side cube_side / 2^max_level.
    int max_level = 8;
    /// 0 (default, the PU paper's rule): split every cell that holds a point down to
    /// max_level. n > 0: split a cell only while it holds more than n points.
    std::size_t max_points_per_cell = 0;
    /// 2:1 balance across faces, edges and vertices (the PU paper's requirement).
    bool balance = true;
    /// Side of the bounding cube, in the points' units. 0 (default): the longest side
    /// of the points' bounding box (1 if all points coincide), centred on the box.
    Scalar cube_side = 0;
    /// Minimum corner of the bounding cube; used only when cube_side > 0.
    Vec3 cube_min = Vec3::Zero();
};

/// How two cells touch: through a face patch, only along an edge segment, or only
/// at a corner point. `any` means any of the three (the 26-neighbourhood).
enum class Adjacency { face, edge, vertex, any };

/// One leaf of the Octree (Octree::cell; the octree stores its fields as arrays).
struct OctreeCell {
    std::uint64_t code = 0;   ///< Morton code of the minimum corner in the finest grid
    /// First position of its points in Octree::point_indices() (an octree holds fewer
    /// than 2^32 points).
    std::uint32_t point_begin = 0;
    std::uint32_t point_end = 0;  ///< one past the last
    std::uint32_t level = 0;  ///< 0 = the whole cube, max_level = finest
};


/// Linear octree over a bounding cube (see the file comment).
class Octree {
public:
    /// Returned by locate() for a point outside the cube.
    static constexpr Index npos = std::numeric_limits<Index>::max();

    Octree() = default;

    /// Builds the octree over any PointSet.
    /// @tparam P a PointSet (read once into a contiguous copy)
    /// @param points the input; coordinates in any unit
    /// @param params max_level in [1, 12], subdivision rule, balance, optional cube
    /// @pre points non-empty and finite; with an explicit cube, every point inside it
    /// @throws invalid_input on an empty set (or 2^32 - 1 points or more), a NaN/Inf coordinate, max_level outside
    ///         [1, 12], a negative/NaN cube_side, or a point outside the given cube
    template <PointSet P>
    explicit Octree(const P& points, const OctreeParams& params = {}) {
        build(kintsugi::gather_points(points), params);
    }
    /// Same over positions already in the internal layout.
    explicit Octree(const std::vector<Vec3>& points, const OctreeParams& params = {}) { build(points, params); }

    // ------------------------------------------------------------ global data
    /// Number of cells (leaves).
    [[nodiscard]] std::size_t size() const { return codes_.size(); }
    /// Cell c (cells are sorted by Morton code). Returned by value: the octree stores its
    /// cells as separate arrays of codes, levels and point starts (13 bytes a cell
    /// instead of 33 with a cell array beside the descents' compact copies: 240 MB less
    /// for the 12M cells of 2M points with 10 % outliers at level 9).
    [[nodiscard]] OctreeCell cell(Index c) const {
        return OctreeCell{codes_[c], begins_[c], begins_[c + 1], levels_[c]};
    }
    /// Level of cell c (0 = the whole cube, max_level() = finest).
    [[nodiscard]] std::uint32_t cell_level(Index c) const { return levels_[c]; }
    [[nodiscard]] int max_level() const { return max_level_; }
    /// Minimum corner of the bounding cube (input units).
    [[nodiscard]] const Vec3& cube_min() const { return cube_min_; }
    /// Side of the bounding cube (input units).
    [[nodiscard]] Scalar cube_side() const { return side_; }
    /// Number of indexed points.
    [[nodiscard]] std::size_t num_points() const { return order_.size(); }
    /// All point indices, grouped by cell (cell c owns [point_begin, point_end)).
    [[nodiscard]] const std::vector<Index>& point_indices() const { return order_; }
    /// Indices (into the input) of the points inside cell c.
    [[nodiscard]] std::span<const Index> cell_points(Index c) const {
        return {order_.data() + begins_[c], begins_[c + 1] - begins_[c]};
    }
    /// Number of cells at each level 0..max_level.
    [[nodiscard]] std::vector<std::size_t> cells_per_level() const {
        std::vector<std::size_t> n(static_cast<std::size_t>(max_level_) + 1, 0);
        for (const std::uint8_t l : levels_) ++n[l];
        return n;
    }

    // ------------------------------------------------------------ cell geometry
    /// Minimum corner of cell c in finest-grid integer units.
    [[nodiscard]] std::array<std::uint32_t, 3> cell_anchor(Index c) const { return morton_decode(codes_[c]); }
    /// Side of cell c in finest-grid units (2^(max_level - level)).
    [[nodiscard]] std::uint32_t cell_extent(Index c) const { return 1u << (max_level_ - static_cast<int>(levels_[c])); }
    /// Side length of cell c (input units).
    [[nodiscard]] Scalar cell_side(Index c) const { return side_ / static_cast<Scalar>(1u << levels_[c]); }
    /// Minimum corner of cell c (input units).
    [[nodiscard]] Vec3 cell_min(Index c) const {
        const auto a = cell_anchor(c);
        return cube_min_ + unit_ * Vec3(a[0], a[1], a[2]);
    }
    /// Maximum corner of cell c (input units).
    [[nodiscard]] Vec3 cell_max(Index c) const { return cell_min(c) + Vec3::Constant(cell_side(c)); }
    /// Centre of cell c (input units).
    [[nodiscard]] Vec3 cell_center(Index c) const { return cell_min(c) + Vec3::Constant(cell_side(c) / 2); }
    /// Length of the diagonal of cell c (input units).
    [[nodiscard]] Scalar cell_diagonal(Index c) const { return cell_side(c) * std::sqrt(Scalar(3)); }
    /// The 8 corners of cell c; corner k has offset ((k&1), (k>>1)&1, (k>>2)&1) x side.
    [[nodiscard]] std::array<Vec3, 8> cell_corners(Index c) const {
        const Vec3 lo = cell_min(c);
        const Scalar s = cell_side(c);
        std::array<Vec3, 8> out;
        for (int k = 0; k < 8; ++k) out[static_cast<std::size_t>(k)] = lo + s * Vec3(k & 1, (k >> 1) & 1, (k >> 2) & 1);
        return out;
    }

    // ------------------------------------------------------------ queries
    /// The cell containing q (closed cube: points on the upper faces belong to the
    /// last cell), or npos when q is outside the cube or not finite.
    [[nodiscard]] Index locate(const Vec3& q) const {
        if (codes_.empty() || !q.allFinite()) return npos;
        const Vec3 t = (q - cube_min_) / unit_;
        const Scalar n = static_cast<Scalar>(1u << max_level_);
        if ((t.array() < 0).any() || (t.array() > n).any()) return npos;
        const std::uint32_t top = (1u << max_level_) - 1;
        std::array<std::uint32_t, 3> g{};
        for (int k = 0; k < 3; ++k) g[k] = std::min(top, static_cast<std::uint32_t>(t[k]));
        return locate_code(morton_encode(g[0], g[1], g[2]));
    }

    /// The cell containing the finest-grid cell with Morton code `code`.
    [[nodiscard]] Index locate_code(std::uint64_t code) const {
        // A table over a coarse grid narrows the binary search to one block.
        const auto [lo, hi] = block_cells(code);
        auto it = std::upper_bound(codes_.begin() + static_cast<std::ptrdiff_t>(lo),
                                   codes_.begin() + static_cast<std::ptrdiff_t>(hi), code);
        return static_cast<Index>(it - codes_.begin()) - 1;
    }

    /// The cells touching cell c with the given kind of contact, sorted by index.
    /// face: share a 2D patch of a face; edge: touch only along a segment;
    /// vertex: touch only at a point; any: all of them.
    void neighbors(Index c, Adjacency kind, std::vector<Index>& out) const {
        out.clear();
        const auto a = cell_anchor(c);
        const std::int64_t s = cell_extent(c);
        const std::int64_t n = std::int64_t{1} << max_level_;
        const std::uint32_t level = levels_[c];
        for (int dz = -1; dz <= 1; ++dz)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    if (dx == 0 && dy == 0 && dz == 0) continue;
                    const std::int64_t qx = a[0] + dx * s, qy = a[1] + dy * s, qz = a[2] + dz * s;
                    if (qx < 0 || qy < 0 || qz < 0 || qx >= n || qy >= n || qz >= n) continue;
                    // Same-size region Q next to c; its cells are one Morton range.
                    const std::uint64_t q0 = morton_encode(static_cast<std::uint32_t>(qx),
                                                                   static_cast<std::uint32_t>(qy),
                                                                   static_cast<std::uint32_t>(qz));
                    const Index first = locate_code(q0);
                    if (levels_[first] <= level) {
                        push_if(c, first, kind, out);
                        continue;
                    }
                    const std::uint64_t q1 = q0 + (std::uint64_t{1} << (3 * (max_level_ - static_cast<int>(level))));
                    const auto last = static_cast<Index>(std::lower_bound(codes_.begin() + static_cast<std::ptrdiff_t>(first),
                                                                          codes_.end(), q1) -
                                                         codes_.begin());
                    for (Index j = first; j < last; ++j) push_if(c, j, kind, out);
                }
        std::sort(out.begin(), out.end());
        out.erase(std::unique(out.begin(), out.end()), out.end());
    }
    /// Convenience overload returning a new vector.
    [[nodiscard]] std::vector<Index> neighbors(Index c, Adjacency kind = Adjacency::any) const {
        std::vector<Index> out;
        neighbors(c, kind, out);
        return out;
    }

    /// How cells a and b touch: 2 = face patch, 1 = edge segment, 0 = corner point,
    /// -1 = they do not touch (or a == b).
    [[nodiscard]] int contact_dimension(Index a, Index b) const {
        if (a == b) return -1;
        const auto pa = cell_anchor(a), pb = cell_anchor(b);
        const std::int64_t sa = cell_extent(a), sb = cell_extent(b);
        int dim = 0;
        for (int k = 0; k < 3; ++k) {
            const std::int64_t lo = std::max<std::int64_t>(pa[k], pb[k]);
            const std::int64_t hi = std::min<std::int64_t>(pa[k] + sa, pb[k] + sb);
            if (hi < lo) return -1;
            if (hi > lo) ++dim;
        }
        return dim == 3 ? -1 : dim;
    }

    /// Visits cells by descending the implicit tree. `classify(lo, hi)` is called on
    /// nodes (boxes in input units) and returns 0 (or false) when no wanted cell lies
    /// in the box, 2 when every cell in the box is wanted (they are then visited
    /// without further calls), and 1 (or true) otherwise. `visit(c)` is called once
    /// per wanted cell, in Morton order; a cell reached through "1" is visited when
    /// classify on its own box returned non-zero.
    template <class Classify, class Visit>
    void visit_cells(Classify&& classify, Visit&& visit) const {
        if (codes_.empty()) return;
        auto every = [](Index first, Index) { return first; };
        const BoxClasses<Classify> classes{classify};
        auto visit_wanted = [&](Index c, int) { visit(c); };
        descend(0, 0, 0, codes_.size(), classes, visit_wanted, every);
    }

    /// Same as visit_cells(classify, visit), restricted to the cells that meet the box
    /// [lo, hi] (input units): the descent starts at the at most 8 nodes of the
    /// level whose side fits the box, instead of the root, which is much faster for
    /// boxes that are small compared with the cube. Cells are visited once, in Morton order.
    template <class Classify, class Visit>
    void visit_cells(const Vec3& lo, const Vec3& hi, Classify&& classify, Visit&& visit) const {
        visit_cells(lo, hi, classify, visit, [](Index, Index) { return false; });
    }

    /// Same, with `skip(first, last)`: called on nodes holding more than one cell
    /// (cells [first, last) in Morton order) before `classify`, and on the remaining
    /// cells of a node classified 2; returning true prunes them (e.g. when none of
    /// them is still of interest).
    template <class Classify, class Visit, class Skip>
    void visit_cells(const Vec3& lo, const Vec3& hi, Classify&& classify, Visit&& visit, Skip&& skip) const {
        visit_cells_sparse(lo, hi, classify, visit,
                           [&](Index first, Index last) { return last - first > 1 && skip(first, last) ? last : first; });
    }

    /// Same, for a sparse set of wanted cells: `next(first, last)` returns the first
    /// cell index in [first, last) that may still be wanted, or `last` when none is.
    /// Nodes with none are pruned before `classify`, and the cells of a node classified
    /// 2 are enumerated through `next`, so the cost follows the wanted cells rather than
    /// all cells (e.g. with a hierarchical bit set of the cells still of interest).
    /// Nodes for which `next` offers no cell are pruned; `visit` may still see cells that
    /// `next` would not offer (single-cell nodes and leaf children are visited without it).
    template <class Classify, class Visit, class Next>
    void visit_cells_sparse(const Vec3& lo, const Vec3& hi, Classify&& classify, Visit&& visit, Next&& next) const {
        const BoxClasses<Classify> classes{classify};
        auto visit_wanted = [&](Index c, int) { visit(c); };
        visit_from_start_nodes(lo, hi, classes, visit_wanted, next);
    }

    /// The cells whose closed box lies in the open ball (c, r), that is whose 8 corners
    /// are closer than r to c, in Morton order, each once. `next` prunes as in
    /// visit_cells_sparse (nodes for which it offers no cell are skipped; `visit` may still
    /// see a cell it would not offer, so the caller filters). r <= 0 or NaN visits nothing.
    /// The support cover's query (which cells a new support covers): the 8 children of a
    /// node are classified together from per-axis terms (each child's squared distances
    /// are sums of one term per axis), with the same arithmetic as classifying each box alone.
    template <class Visit, class Next>
    void visit_cells_in_ball(const Vec3& c, Scalar r, Visit&& visit, Next&& next) const {
        // A cell in the ball has its centre closer than r - (its half diagonal) to c, and
        // no cell is smaller than the finest one: nodes farther than r_in from c hold none.
        const Scalar half_diag_min =
            Scalar(0.5) * std::sqrt(Scalar(3)) * side_ / static_cast<Scalar>(1u << max_level_);
        const Scalar r_in = std::max(Scalar(0), r - half_diag_min);
        const BallClasses classes{c, r_in * r_in, r * r};
        auto visit_inside = [&](Index cell, int cls) {
            if (cls == 2) visit(cell);
        };
        visit_from_start_nodes(c - Vec3::Constant(r_in), c + Vec3::Constant(r_in), classes, visit_inside, next);
    }

    /// The cells whose closed box intersects the closed box [lo, hi] (input units),
    /// in Morton order.
    void cells_in_box(const Vec3& lo, const Vec3& hi, std::vector<Index>& out) const {
        out.clear();
        visit_cells(lo, hi,
            [&](const Vec3& a, const Vec3& b) { return (a.array() <= hi.array()).all() && (lo.array() <= b.array()).all(); },
            [&](Index c) { out.push_back(c); });
    }

private:
    void build(const std::vector<Vec3>& pts, const OctreeParams& params) {
        const char* fn = "kintsugi::Octree";
        if (params.max_level < 1 || params.max_level > 12)
            throw invalid_input(std::string(fn) + ": max_level = " + std::to_string(params.max_level) +
                                " is outside [1, 12]; pick a level between 1 and 12");
        if (pts.empty()) throw invalid_input(std::string(fn) + ": the point set is empty; pass at least one point");
        if (pts.size() >= std::size_t{std::numeric_limits<std::uint32_t>::max()})
            throw invalid_input(std::string(fn) + ": " + std::to_string(pts.size()) +
                                " points; an octree holds at most 4,294,967,294 (split the input)");
        BoundingBox box;
        for (std::size_t i = 0; i < pts.size(); ++i) {
            if (!pts[i].allFinite())
                throw invalid_input(std::string(fn) + ": point " + std::to_string(i) +
                                    " has a NaN or infinite coordinate; remove it first");
            box.extend(pts[i]);
        }
        if (params.cube_side > 0 && std::isfinite(params.cube_side) && params.cube_min.allFinite()) {
            side_ = params.cube_side;
            cube_min_ = params.cube_min;
            const Scalar tol = side_ * 1e-12;
            if ((box.min.array() < cube_min_.array() - tol).any() ||
                (box.max.array() > cube_min_.array() + side_ + tol).any())
                throw invalid_input(std::string(fn) +
                                    ": a point lies outside the given cube (cube_min, cube_side); enlarge the cube "
                                    "or leave cube_side = 0");
        } else if (params.cube_side == 0) {
            side_ = box.extent().maxCoeff();
            if (std::isinf(side_))
                throw invalid_input(std::string(fn) + ": the points span more than the largest double (" +
                                    detail::format_number(box.min.minCoeff()) + " to " +
                                    detail::format_number(box.max.maxCoeff()) +
                                    "); scale them down, e.g. by 2^-10, first");
            if (!(side_ > 0)) side_ = 1;
            // (min + max) / 2 overflows for two points near DBL_MAX: then halve first.
            const Vec3 centre = box.center().allFinite() ? box.center() : Vec3(box.min / 2 + box.max / 2);
            cube_min_ = centre - Vec3::Constant(side_ / 2);
        } else {
            throw invalid_input(std::string(fn) + ": cube_side must be 0 (automatic) or a positive finite length, "
                                "with a finite cube_min");
        }
        max_level_ = params.max_level;
        const int L = max_level_;
        const std::uint32_t n = 1u << L;
        unit_ = side_ / static_cast<Scalar>(n);

        // 1. Morton codes of the finest cells holding each point, sorted.
        auto keyed = detail::huge_vector<std::pair<std::uint64_t, Index>>(pts.size());
        parallel_for(0, pts.size(), [&](std::size_t i) {
            const Vec3 t = (pts[i] - cube_min_) / unit_;
            std::array<std::uint32_t, 3> g{};
            for (int k = 0; k < 3; ++k) {
                const Scalar v = std::floor(t[k]);
                g[k] = v <= 0 ? 0u : (v >= static_cast<Scalar>(n - 1) ? n - 1 : static_cast<std::uint32_t>(v));
            }
            keyed[i] = {morton_encode(g[0], g[1], g[2]), i};
        }, 4096);
        detail::sort_maybe_parallel(keyed);

        // 2. Internal nodes per level (Morton codes at that level's resolution).
        std::vector<std::vector<std::uint64_t>> internal(static_cast<std::size_t>(L));
        {
            const std::size_t thr = params.max_points_per_cell;
            std::vector<std::pair<std::uint64_t, std::size_t>> runs, next;  // (prefix, count) at level m
            // level L-1 from the sorted codes
            for (const auto& [code, idx] : keyed) {
                const std::uint64_t p = code >> 3;
                if (!runs.empty() && runs.back().first == p)
                    ++runs.back().second;
                else
                    runs.push_back({p, 1});
            }
            for (int m = L - 1; m >= 0; --m) {
                auto& I = internal[static_cast<std::size_t>(m)];
                for (const auto& [p, cnt] : runs)
                    if (cnt > thr) I.push_back(p);
                if (m == 0) break;
                next.clear();
                for (const auto& [p, cnt] : runs) {
                    const std::uint64_t q = p >> 3;
                    if (!next.empty() && next.back().first == q)
                        next.back().second += cnt;
                    else
                        next.push_back({q, cnt});
                }
                runs.swap(next);
            }
        }

        // 3. 2:1 balance over the 26-neighbourhood: for every internal node P at level
        //    m >= 1, the same-size neighbours of P must exist, i.e. their parents (at
        //    level m-1) must be internal. Processed from fine to coarse so that
        //    additions propagate.
        if (params.balance) {
            for (int m = L - 1; m >= 1; --m) {
                const auto& I = internal[static_cast<std::size_t>(m)];
                auto& J = internal[static_cast<std::size_t>(m - 1)];
                const std::int64_t np = std::int64_t{1} << (m - 1);
                // The nodes to add, merged into J: on a bit map of level m-1's grid when it
                // has at most 2^27 nodes (16 MB; a scan of its words gives J in Morton
                // order) and no more words than 8 x the codes a list would hold, else
                // listed, sorted and merged. (The list held about 27 codes per parent before
                // its duplicates went: sorting it was 0.3 s of the octree's 0.8 s at 2M points.)
                const std::size_t words = 3 * (m - 1) <= 27 ? ((std::size_t{1} << (3 * (m - 1))) + 63) / 64 : 0;
                const bool on_bits = words > 0 && words <= 8 * (J.size() + 27 * I.size());
                std::vector<std::uint64_t> bits, add;
                if (on_bits) {
                    bits.assign(words, 0);
                    for (const std::uint64_t c : J) bits[c >> 6] |= std::uint64_t{1} << (c & 63);
                } else {
                    add.reserve(I.size() * 2);
                }
                // Siblings share a parent: gather the needed offsets of each parent
                // in a 3x3x3 mask first, so each candidate is emitted once per parent.
                for (std::size_t i = 0; i < I.size();) {
                    const std::uint64_t parent = I[i] >> 3;
                    std::uint32_t mask = 0;
                    for (; i < I.size() && (I[i] >> 3) == parent; ++i) {
                        const std::uint64_t k = I[i] & 7;  // child position: x bit 0, y bit 1, z bit 2
                        const int ox = (k & 1) ? 1 : -1, oy = (k & 2) ? 1 : -1, oz = (k & 4) ? 1 : -1;
                        for (int b = 0; b < 8; ++b)
                            mask |= 1u << ((((b & 1) ? ox : 0) + 1) + 3 * (((b & 2) ? oy : 0) + 1) +
                                           9 * (((b & 4) ? oz : 0) + 1));
                    }
                    const auto x = morton_decode(parent);
                    for (int bit = 0; bit < 27; ++bit) {
                        if (!(mask & (1u << bit))) continue;
                        const std::int64_t cx = std::int64_t{x[0]} + bit % 3 - 1, cy = std::int64_t{x[1]} + (bit / 3) % 3 - 1,
                                           cz = std::int64_t{x[2]} + bit / 9 - 1;
                        if (cx < 0 || cy < 0 || cz < 0 || cx >= np || cy >= np || cz >= np) continue;
                        const std::uint64_t c = morton_encode(static_cast<std::uint32_t>(cx),
                                                              static_cast<std::uint32_t>(cy),
                                                              static_cast<std::uint32_t>(cz));
                        if (on_bits) bits[c >> 6] |= std::uint64_t{1} << (c & 63);
                        else add.push_back(c);
                    }
                }
                if (on_bits) {
                    J.clear();
                    for (std::size_t w = 0; w < bits.size(); ++w)
                        for (std::uint64_t b = bits[w]; b != 0; b &= b - 1)
                            J.push_back((std::uint64_t{w} << 6) | static_cast<std::uint64_t>(std::countr_zero(b)));
                    continue;
                }
                detail::sort_maybe_parallel(add);
                add.erase(std::unique(add.begin(), add.end()), add.end());
                std::vector<std::uint64_t> merged;
                merged.reserve(J.size() + add.size());
                std::set_union(J.begin(), J.end(), add.begin(), add.end(), std::back_inserter(merged));
                J.swap(merged);
            }
        }

        // 4. Leaves: children of internal nodes that are not internal themselves, emitted
        //    in Morton order by one depth-first walk. Every internal node's parent is
        //    internal (runs of points; the balance adds each parent with its neighbours),
        //    and the walk meets the internal nodes of each level in increasing order, so
        //    one cursor per level answers "is this child internal" in O(1). (Merging the
        //    levels' leaf lists one level at a time copied all cells once per level: 2M
        //    points with 10 % outliers at level 9, 12M cells, took 5.5 s.)
        codes_.clear();
        levels_.clear();
        if (internal[0].empty()) {
            codes_.push_back(0);
            levels_.push_back(0);
        } else {
            std::size_t total = 0;
            for (int m = 0; m < L; ++m)
                total += 8 * internal[static_cast<std::size_t>(m)].size() -
                         (m + 1 < L ? internal[static_cast<std::size_t>(m + 1)].size() : 0);
            detail::reserve_huge(codes_, total);
            detail::reserve_huge(levels_, total);
            std::vector<std::size_t> cursor(static_cast<std::size_t>(L), 0);
            struct Frame {
                std::uint64_t node;
                int level;
                int next_child;
            };
            std::vector<Frame> stack;
            stack.reserve(static_cast<std::size_t>(L) + 1);
            stack.push_back({internal[0].front(), 0, 0});
            cursor[0] = 1;
            while (!stack.empty()) {
                Frame& fr = stack.back();
                if (fr.next_child == 8) {
                    stack.pop_back();
                    continue;
                }
                const int m = fr.level;
                const std::uint64_t child = (fr.node << 3) | static_cast<std::uint64_t>(fr.next_child++);
                if (m + 1 < L) {
                    const auto& C = internal[static_cast<std::size_t>(m + 1)];
                    std::size_t& at = cursor[static_cast<std::size_t>(m + 1)];
                    if (at < C.size() && C[at] == child) {
                        ++at;
                        stack.push_back({child, m + 1, 0});
                        continue;
                    }
                }
                codes_.push_back(child << (3 * (L - m - 1)));
                levels_.push_back(static_cast<std::uint8_t>(m + 1));
            }
            for (int m = 0; m < L; ++m)
                if (cursor[static_cast<std::size_t>(m)] != internal[static_cast<std::size_t>(m)].size())
                    throw std::logic_error("kintsugi::Octree: an internal node without an internal parent");
        }
        std::vector<std::vector<std::uint64_t>>().swap(internal);

        // Lookup table: for each block of a coarse grid, the cell holding its corner.
        {
            const int k = std::min(L, 6);
            block_shift_ = 3 * (L - k);
            block_start_.resize(std::size_t{1} << (3 * k));
            std::size_t j = 0;
            for (std::size_t b = 0; b < block_start_.size(); ++b) {
                const std::uint64_t code = std::uint64_t{b} << block_shift_;
                while (j + 1 < codes_.size() && codes_[j + 1] <= code) ++j;
                block_start_[b] = static_cast<Index>(j);
            }
        }

        // 5. Point ranges: both sequences are in Morton order.
        order_ = detail::huge_vector<Index>(keyed.size());
        for (std::size_t i = 0; i < keyed.size(); ++i) order_[i] = keyed[i].second;
        std::size_t p = 0;
        begins_ = detail::huge_vector<std::uint32_t>(codes_.size() + 1);
        for (std::size_t c = 0; c < codes_.size(); ++c) {
            const std::uint64_t end = c + 1 < codes_.size() ? codes_[c + 1] : std::numeric_limits<std::uint64_t>::max();
            begins_[c] = static_cast<std::uint32_t>(p);
            while (p < keyed.size() && keyed[p].first < end) ++p;
        }
        begins_[codes_.size()] = static_cast<std::uint32_t>(p);
    }

    void push_if(Index c, Index j, Adjacency kind, std::vector<Index>& out) const {
        const int d = contact_dimension(c, j);
        if (d < 0) return;
        if (kind == Adjacency::any || (kind == Adjacency::face && d == 2) || (kind == Adjacency::edge && d == 1) ||
            (kind == Adjacency::vertex && d == 0))
            out.push_back(j);
    }

    // How the descents classify boxes: box(lo, hi) one box (0: no wanted cell in it,
    // 2: every cell in it wanted, 1: otherwise); children(lo, hi, out) the 8 children of
    // a node, child k spanning [lo[a][(k >> a) & 1], hi[a][(k >> a) & 1]] on axis a.
    template <class Classify>
    struct BoxClasses {
        Classify& f;
        int box(const Vec3& lo, const Vec3& hi) const { return static_cast<int>(f(lo, hi)); }
        void children(const Scalar (&lo)[3][2], const Scalar (&hi)[3][2], int (&out)[8]) const {
            for (int k = 0; k < 8; ++k) {
                const int bx = k & 1, by = (k >> 1) & 1, bz = k >> 2;
                out[k] = box(Vec3(lo[0][bx], lo[1][by], lo[2][bz]), Vec3(hi[0][bx], hi[1][by], hi[2][bz]));
            }
        }
    };
    // The ball (c, r): 0 when the box is at least r_in from c, 2 when its farthest corner
    // is closer than r, 1 otherwise. Squared distances summed axis by axis in order x, y, z
    // (the same sums whether a box is classified alone or with its siblings).
    struct BallClasses {
        Vec3 c;
        Scalar r_in2, r2;
        static Scalar near_term(Scalar c, Scalar lo, Scalar hi) {
            const Scalar t = c < lo ? lo - c : (c > hi ? c - hi : Scalar(0));
            return t * t;
        }
        static Scalar far_term(Scalar c, Scalar lo, Scalar hi) {
            const Scalar a = std::max(std::abs(c - lo), std::abs(c - hi));
            return a * a;
        }
        // The class from the squared near and far distances.
        int of(Scalar n, Scalar f) const { return !(n < r_in2) ? 0 : (f < r2 ? 2 : 1); }
        int box(const Vec3& lo, const Vec3& hi) const {
            return of(near_term(c[0], lo[0], hi[0]) + near_term(c[1], lo[1], hi[1]) + near_term(c[2], lo[2], hi[2]),
                      far_term(c[0], lo[0], hi[0]) + far_term(c[1], lo[1], hi[1]) + far_term(c[2], lo[2], hi[2]));
        }
        void children(const Scalar (&lo)[3][2], const Scalar (&hi)[3][2], int (&out)[8]) const {
            Scalar n[3][2], f[3][2];
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 2; ++b) {
                    n[a][b] = near_term(c[a], lo[a][b], hi[a][b]);
                    f[a][b] = far_term(c[a], lo[a][b], hi[a][b]);
                }
            for (int k = 0; k < 8; ++k) {
                const int bx = k & 1, by = (k >> 1) & 1, bz = k >> 2;
                out[k] = of(n[0][bx] + n[1][by] + n[2][bz], f[0][bx] + f[1][by] + f[2][bz]);
            }
        }
    };

    // The descent over the nodes that meet the box [lo, hi] (input units): it starts at
    // the at most 8 nodes of the level whose side fits the box. visit(c, cls) gets each
    // cell reached with a non-zero class (its own box's, or 2 from a node holding it),
    // once, in Morton order.
    template <class Classes, class Visit, class Next>
    void visit_from_start_nodes(const Vec3& lo, const Vec3& hi, const Classes& classes, Visit& visit,
                                Next& next) const {
        if (codes_.empty()) return;
        const Scalar n = static_cast<Scalar>(std::uint64_t{1} << max_level_);
        std::array<std::int64_t, 3> a{}, b{};
        for (int k = 0; k < 3; ++k) {
            const Scalar tl = std::floor((lo[k] - cube_min_[k]) / unit_);
            const Scalar th = std::floor((hi[k] - cube_min_[k]) / unit_);
            if (!(th >= 0) || !(tl < n)) return;  // disjoint from the cube (or NaN)
            a[k] = tl <= 0 ? 0 : static_cast<std::int64_t>(tl);
            b[k] = th >= n - 1 ? static_cast<std::int64_t>(n) - 1 : static_cast<std::int64_t>(th);
        }
        // Deepest level m whose nodes are at least as large as the box's extent.
        const std::int64_t ext = std::max({b[0] - a[0], b[1] - a[1], b[2] - a[2]}) + 1;
        int m = max_level_;
        while (m > 0 && (std::int64_t{1} << (max_level_ - m)) < ext) --m;
        const int sh = max_level_ - m;
        Index last_visited = npos;
        auto visit_once = [&](Index c, int cls) {
            // a coarse cell can contain several start nodes: visit it once
            if (c == last_visited) return;
            last_visited = c;
            visit(c, cls);
        };
        // Start nodes in Morton order (their codes at level m, sorted).
        std::array<std::uint64_t, 8> starts{};
        int ns = 0;
        for (std::int64_t z = a[2] >> sh; z <= (b[2] >> sh); ++z)
            for (std::int64_t y = a[1] >> sh; y <= (b[1] >> sh); ++y)
                for (std::int64_t x = a[0] >> sh; x <= (b[0] >> sh); ++x)
                    starts[static_cast<std::size_t>(ns++)] =
                        morton_encode(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                                              static_cast<std::uint32_t>(z)) << (3 * sh);
        for (int i = 1; i < ns; ++i)  // insertion sort of at most 8 codes
            for (int j = i; j > 0 && starts[static_cast<std::size_t>(j)] < starts[static_cast<std::size_t>(j - 1)]; --j)
                std::swap(starts[static_cast<std::size_t>(j)], starts[static_cast<std::size_t>(j - 1)]);
        for (int i = 0; i < ns; ++i) {
            const std::uint64_t code = starts[static_cast<std::size_t>(i)];
            const Index first = locate_code(code);
            if (levels_[first] <= static_cast<std::uint32_t>(m)) {
                // the node lies inside one cell
                if (first == last_visited) continue;
                const Vec3 cl = cell_min(first);
                const int cls = classes.box(cl, Vec3(cl + Vec3::Constant(cell_side(first))));
                if (cls != 0) visit_once(first, cls);
                continue;
            }
            // the node holds whole cells (it is not inside one): its last cell is the one
            // holding its last finest-grid cell (a table-narrowed search, not one over
            // every cell after `first`)
            const Index last = locate_code(code + (std::uint64_t{1} << (3 * sh)) - 1) + 1;
            descend(static_cast<std::uint32_t>(m), code, first, last, classes, visit_once, next);
        }
    }

    // Node (level, code) covering cells [first, last): pruned when `next` offers none of
    // its cells, else classified, then handed to descend_classified.
    template <class Classes, class Visit, class Next>
    void descend(std::uint32_t level, std::uint64_t code, Index first, Index last, const Classes& classes,
                 Visit& visit, Next& next) const {
        if (last - first > 1 && next(first, last) >= last) return;
        const auto a = morton_decode(code);
        const Scalar s = unit_ * static_cast<Scalar>(std::uint32_t{1} << (max_level_ - static_cast<int>(level)));
        const Vec3 lo(cube_min_[0] + unit_ * a[0], cube_min_[1] + unit_ * a[1], cube_min_[2] + unit_ * a[2]);
        const int cls = classes.box(lo, Vec3(lo[0] + s, lo[1] + s, lo[2] + s));
        if (cls == 0) return;
        descend_classified(level, code, a[0], a[1], a[2], first, last, cls, classes, visit, next);
    }

    // The cells [first, last) that can hold code or start at it: from the cell holding the
    // corner of code's block (the lookup table) to the one after the cell holding the next
    // block's corner.
    [[nodiscard]] std::pair<Index, Index> block_cells(std::uint64_t code) const {
        const std::uint64_t blk = code >> block_shift_;
        return {block_start_[blk], blk + 1 < block_start_.size() ? block_start_[blk + 1] + 1 : codes_.size()};
    }

    // First index in [b, e) whose code is >= code (e when there is none), for b <= e.
    // Over a large range the block table narrows the search first (block_cells: the
    // answer lies within those cells). A binary search over a node's whole range
    // missed the cache at every step (30 % of the descents' time in the support cover).
    [[nodiscard]] Index find_code(Index b, Index e, std::uint64_t code) const {
        if (e - b > 32) {
            const auto [lo, hi] = block_cells(code);
            b = std::min(std::max(b, lo), e);
            e = std::max(b, std::min(e, hi));
        }
        if (e - b <= 32) {
            while (b < e && codes_[b] < code) ++b;
            return b;
        }
        // Galloping from b: a child's first cell is often just after the previous one's,
        // whose memory was just read.
        if (codes_[b] >= code) return b;
        Index lo = b;  // codes_[lo] < code
        for (Index step = 1;; step *= 2) {
            const Index p = lo + step;
            if (p >= e) break;
            if (codes_[p] >= code) {
                e = p + 1;
                break;
            }
            lo = p;
        }
        return static_cast<Index>(std::lower_bound(codes_.begin() + static_cast<std::ptrdiff_t>(lo + 1),
                                                   codes_.begin() + static_cast<std::ptrdiff_t>(e), code) -
                                  codes_.begin());
    }

    // Node (level, code, minimum corner (x, y, z) in finest units) covering cells
    // [first, last), just classified `cls` != 0. Its 8 children are classified together,
    // and their cell ranges looked up only when needed: the leaves tile the node, so child
    // k's first cell has exactly the child's code, and a leaf child needs no search for
    // its end.
    template <class Classes, class Visit, class Next>
    void descend_classified(std::uint32_t level, std::uint64_t code, std::uint32_t x, std::uint32_t y,
                            std::uint32_t z, Index first, Index last, int cls, const Classes& classes,
                            Visit& visit, Next& next) const {
        if (levels_[first] <= level) {
            visit(first, cls);
            return;
        }
        if (cls >= 2) {
            // every cell is wanted: enumerate those `next` still offers
            for (Index c = next(first, last); c < last; c = next(c + 1, last)) visit(c, 2);
            return;
        }
        const int shift = 3 * (max_level_ - static_cast<int>(level) - 1);
        const std::uint32_t half = std::uint32_t{1} << (max_level_ - static_cast<int>(level) - 1);
        const Scalar hs = unit_ * static_cast<Scalar>(half);
        const std::uint32_t corner[3] = {x, y, z};
        Scalar lo[3][2], hi[3][2];
        for (int a = 0; a < 3; ++a)
            for (int h = 0; h < 2; ++h) {
                lo[a][h] = cube_min_[a] + unit_ * (corner[a] + (h ? half : 0));
                hi[a][h] = lo[a][h] + hs;
            }
        int child_cls[8];
        classes.children(lo, hi, child_cls);
        const bool eight_leaves = last - first == 8;  // then cell first + k is child k
        Index b = first;  // no child examined later starts before b
        for (std::uint32_t k = 0; k < 8; ++k) {
            const int ccls = child_cls[k];
            if (ccls == 0) continue;
            if (eight_leaves) {
                visit(first + k, ccls);
                continue;
            }
            const std::uint64_t child = code + (std::uint64_t{k} << shift);
            const Index cb = find_code(b, last, child);
            if (levels_[cb] <= level + 1) {  // the child is a leaf
                visit(cb, ccls);
                b = cb + 1;
                continue;
            }
            const Index ce = k == 7 ? last : find_code(cb + 1, last, child + (std::uint64_t{1} << shift));
            b = ce;
            if (next(cb, ce) >= ce) continue;
            const std::uint32_t cx = x + ((k & 1) ? half : 0), cy = y + ((k & 2) ? half : 0),
                                cz = z + ((k & 4) ? half : 0);
            descend_classified(level + 1, child, cx, cy, cz, cb, ce, ccls, classes, visit, next);
        }
    }

    int max_level_ = 0;
    Vec3 cube_min_ = Vec3::Zero();
    Scalar side_ = 0;
    Scalar unit_ = 0;  // side of a finest cell
    // The cells, sorted by Morton code: code, level and first point of cell c (point
    // begins_[c + 1] ends it; begins_ has one more entry).
    std::vector<std::uint64_t> codes_;
    std::vector<std::uint8_t> levels_;
    std::vector<std::uint32_t> begins_;
    std::vector<Index> order_;
    std::vector<Index> block_start_;  // see locate_code
    int block_shift_ = 0;
};

}  // namespace kintsugi
