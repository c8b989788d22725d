// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file bucket_grid.hpp
/// @brief A growing uniform grid of buckets: points inserted one at a time, each with a
/// value of the caller's, found by ball queries at once. For outputs built point by
/// point (the surfel fill's disks, the RBF fit's kept points, UniformGrid's appends).
///
/// @code
/// struct Disk { kintsugi::Vec3 n; double r; };
/// kintsugi::BucketGrid<Disk> grid(lo, hi, 2 * r_max);   // cells of side 2 r_max over [lo, hi]
/// grid.insert(p, Disk{n, r});                             // O(1)
/// grid.for_each_in_ball(q, r_max, [&](const kintsugi::Vec3& p, const Disk& d) { ... });
/// bool taken = grid.any_in_ball(q, eps);
/// @endcode
///
/// Cells of a fixed side are keyed by their integer coordinates (21 bits per axis) and
/// found through an open-addressing hash table (detail::CellTable, the one UniformGrid
/// uses), so memory is linear in the points whatever the extent. A cell keeps its
/// positions in one array and the values in another: a query's distance tests read
/// only positions, from a few contiguous runs. A query visits the cells its cube meets
/// in (z, y, x) order and each cell's points in insertion order, so the order of its
/// results depends on the insertions alone. Against UniformGrid: inserting is O(1) and
/// a point is found at once with its value; no k-nearest search, no single-precision
/// gathers, and a query much wider than a cell visits many cells (take the cell side
/// about the usual query radius, or twice it: a query then meets at most 2 x 2 x 2 cells).

#include <kintsugi/core/error.hpp>
#include <kintsugi/core/types.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

namespace detail {

/// Integer cell coordinates, each in [0, cell_coord_max].
using CellCoord = std::array<std::int64_t, 3>;
/// The largest cell coordinate on an axis (21 bits).
inline constexpr std::int64_t cell_coord_max = (std::int64_t{1} << 21) - 1;
/// Packs three coordinates in [0, 2^21) into one key: x | y << 21 | z << 42. Keys in
/// increasing order are the cells in (z, y, x) order; a key is below 2^63.
inline std::uint64_t pack_cell(const CellCoord& g) {
    return static_cast<std::uint64_t>(g[0]) | (static_cast<std::uint64_t>(g[1]) << 21) |
           (static_cast<std::uint64_t>(g[2]) << 42);
}
/// The coordinates of a packed key.
inline CellCoord unpack_cell(std::uint64_t k) {
    constexpr std::uint64_t m = (std::uint64_t{1} << 21) - 1;
    return {static_cast<std::int64_t>(k & m), static_cast<std::int64_t>((k >> 21) & m),
            static_cast<std::int64_t>(k >> 42)};
}

/// Open-addressing hash table (linear probing, at most half full) from packed cell keys
/// to 32-bit ids: the cell look-up of UniformGrid and BucketGrid.
class CellTable {
public:
    static constexpr std::uint64_t empty = ~std::uint64_t{0};  ///< never a packed key
    static constexpr std::uint32_t none = ~std::uint32_t{0};   ///< find(): not present
    CellTable() { reset(0); }
    /// Empties the table, sized for `expected` keys.
    void reset(std::size_t expected) {
        std::size_t cap = 16;
        while (cap < 2 * expected) cap *= 2;
        keys_.assign(cap, empty);
        ids_.assign(cap, 0);
        mask_ = cap - 1;
        size_ = 0;
    }
    /// The id of key k, or none.
    [[nodiscard]] std::uint32_t find(std::uint64_t k) const {
        for (std::size_t s = slot(k);; s = (s + 1) & mask_) {
            if (keys_[s] == k) return ids_[s];
            if (keys_[s] == empty) return none;
        }
    }
    /// The id of key k; when k is new, it is inserted with id `fresh` first.
    /// Returns (id, inserted).
    std::pair<std::uint32_t, bool> find_or_insert(std::uint64_t k, std::uint32_t fresh) {
        std::size_t s = slot(k);
        for (; keys_[s] != empty; s = (s + 1) & mask_)
            if (keys_[s] == k) return {ids_[s], false};
        keys_[s] = k;
        ids_[s] = fresh;
        if (2 * ++size_ > keys_.size()) grow();
        return {fresh, true};
    }
    /// Number of keys.
    [[nodiscard]] std::size_t size() const { return size_; }

private:
    [[nodiscard]] std::size_t slot(std::uint64_t k) const {
        return static_cast<std::size_t>((k * 0x9E3779B97F4A7C15ull) >> 20) & mask_;
    }
    void grow() {
        std::vector<std::uint64_t> keys(2 * keys_.size(), empty);
        std::vector<std::uint32_t> ids(keys.size(), 0);
        keys_.swap(keys);
        ids_.swap(ids);
        mask_ = keys_.size() - 1;
        for (std::size_t s = 0; s < keys.size(); ++s) {
            if (keys[s] == empty) continue;
            std::size_t t = slot(keys[s]);
            while (keys_[t] != empty) t = (t + 1) & mask_;
            keys_[t] = keys[s];
            ids_[t] = ids[s];
        }
    }
    std::vector<std::uint64_t> keys_;
    std::vector<std::uint32_t> ids_;
    std::size_t mask_ = 0, size_ = 0;
};

}  // namespace detail

/// A growing uniform grid of buckets holding (position, value) pairs; see the file
/// comment. T: any copyable type (use an index into the caller's arrays, or the few
/// fields a query needs, to keep them next to the positions).
template <class T>
class BucketGrid {
public:
    /// Cells [origin + side·g, origin + side·(g + 1)) for integer g in [0, 2^21) per axis;
    /// a point outside that range is kept in the border cell nearest to it (still found
    /// by every query, whose exact distance test decides; only slower when many are).
    /// @param side cell side, finite and > 0 (and not so small that 1 / side overflows)
    /// @throws invalid_input if origin has a NaN or infinite coordinate or side is not
    ///   as above.
    BucketGrid(const Vec3& origin, Scalar side) { init(origin, side); }
    /// Cells of side at least `side` over the box [lo, hi] with a margin of one box
    /// diagonal plus one cell on every side (for points that stray out of the box a
    /// little); the side is enlarged when the whole would need more than 2^21 cells per
    /// axis.
    /// @throws invalid_input if lo or hi has a NaN or infinite coordinate, lo > hi on an
    ///   axis, or side is not finite and > 0.
    BucketGrid(const Vec3& lo, const Vec3& hi, Scalar side) {
        if (!lo.allFinite() || !hi.allFinite() || (hi - lo).minCoeff() < 0)
            throw invalid_input("kintsugi::BucketGrid: the box is empty or not finite; pass lo <= hi, finite");
        check_side(side);
        constexpr auto n = static_cast<Scalar>(detail::cell_coord_max - 1);
        Scalar pad = (hi - lo).norm() + side;
        Vec3 origin = lo - Vec3::Constant(pad);
        if (!std::isfinite(pad) || !origin.allFinite()) {  // near the largest doubles: no margin
            pad = 0;
            origin = lo;
        }
        Scalar need = ((hi - lo).maxCoeff() + 2 * pad) / n;
        if (!std::isfinite(need)) need = (hi / n - origin / n).maxCoeff() + pad / n;  // the same, without overflow
        init(origin, std::max(side, need));
    }

    /// The cell side in use.
    [[nodiscard]] Scalar cell_size() const { return side_; }
    /// The corner of cell (0, 0, 0).
    [[nodiscard]] const Vec3& origin() const { return origin_; }
    /// Number of points inserted.
    [[nodiscard]] std::size_t size() const { return size_; }
    /// Number of non-empty cells.
    [[nodiscard]] std::size_t cell_count() const { return cells_.size(); }

    /// The integer coordinates of the cell that holds p (clamped to the grid's range).
    [[nodiscard]] detail::CellCoord coord(const Vec3& p) const {
        detail::CellCoord g{};
        for (int k = 0; k < 3; ++k) g[static_cast<std::size_t>(k)] = clamp_coord((p[k] - origin_[k]) * inv_);
        return g;
    }
    /// Whether p lies in the grid's range (its own cell, not a border cell it was
    /// clamped to).
    [[nodiscard]] bool in_range(const Vec3& p) const {
        for (int k = 0; k < 3; ++k) {
            const Scalar a = (p[k] - origin_[k]) * inv_;
            if (!(a >= 0 && a < static_cast<Scalar>(detail::cell_coord_max + 1))) return false;
        }
        return true;
    }
    /// The number of cells (empty or not) in the cube of half side h around c, or
    /// infinity when it reaches outside the grid's range: a caller can walk its points
    /// another way when the cube spans more cells than are filled.
    [[nodiscard]] double cells_in_cube(const Vec3& c, Scalar h) const {
        double n = 1;
        for (int k = 0; k < 3; ++k) {
            const Scalar l = std::floor((c[k] - h - origin_[k]) * inv_), u = std::floor((c[k] + h - origin_[k]) * inv_);
            if (!(l >= 0 && u <= static_cast<Scalar>(detail::cell_coord_max))) return std::numeric_limits<double>::infinity();
            n *= static_cast<double>(u - l + 1);
        }
        return n;
    }

    /// Adds the point p with its value.
    /// @throws invalid_input if p has a NaN or infinite coordinate, or the grid holds
    ///   2^32 - 2 cells.
    void insert(const Vec3& p, const T& value) {
        if (!p.allFinite())
            throw invalid_input("kintsugi::BucketGrid::insert: the point has a NaN or infinite coordinate");
        if (cells_.size() + 1 >= detail::CellTable::none)
            throw invalid_input("kintsugi::BucketGrid::insert: at most 2^32 - 2 cells are supported");
        const std::uint64_t key = detail::pack_cell(coord(p));
        const auto [id, fresh] = table_.find_or_insert(key, static_cast<std::uint32_t>(cells_.size()));
        if (fresh) cells_.push_back(Cell{{}, {}, key});
        Cell& cell = cells_[id];
        if (cell.p.empty()) {
            cell.p.reserve(8);
            cell.v.reserve(8);
        }
        cell.p.push_back(p);
        cell.v.push_back(value);
        ++size_;
    }

    /// Calls f(position, value) for every point at distance at most r from c, cells in
    /// (z, y, x) order, insertion order within a cell.
    template <class F>
    void for_each_in_ball(const Vec3& c, Scalar r, F&& f) const {
        const Scalar r2 = r * r;
        (void)visit_cells(c, r, [&](const std::vector<Vec3>& p, const std::vector<T>& v) {
            for (std::size_t k = 0; k < p.size(); ++k)
                if ((p[k] - c).squaredNorm() <= r2) f(p[k], v[k]);
            return false;
        });
    }
    /// Whether some point lies at distance at most r from c.
    [[nodiscard]] bool any_in_ball(const Vec3& c, Scalar r) const {
        const Scalar r2 = r * r;
        return visit_cells(c, r, [&](const std::vector<Vec3>& p, const std::vector<T>&) {
            for (const Vec3& q : p)
                if ((q - c).squaredNorm() <= r2) return true;
            return false;
        });
    }
    /// Calls visit(positions, values) for the non-empty cells that meet the cube of
    /// half side h around c, in (z, y, x) order, until one call returns true; returns
    /// whether one did. A NaN in c or h visits nothing. A cube spanning more cells than
    /// are filled costs O(filled cells), not O(its cells).
    template <class Visit>
    bool visit_cells(const Vec3& c, Scalar h, Visit&& visit) const {
        if (cells_.empty() || !c.allFinite() || std::isnan(h)) return false;
        detail::CellCoord l{}, u{};
        double box = 1;
        for (int k = 0; k < 3; ++k) {
            const auto a = static_cast<std::size_t>(k);
            l[a] = clamp_coord((c[k] - h - origin_[k]) * inv_);
            u[a] = clamp_coord((c[k] + h - origin_[k]) * inv_);
            box *= static_cast<double>(u[a] - l[a] + 1);
        }
        if (box > static_cast<double>(cells_.size())) {
            std::vector<std::pair<std::uint64_t, std::uint32_t>> in_box;  // (key, cell): sorted, (z, y, x) order
            for (std::size_t id = 0; id < cells_.size(); ++id) {
                const detail::CellCoord g = detail::unpack_cell(cells_[id].key);
                if (g[0] >= l[0] && g[0] <= u[0] && g[1] >= l[1] && g[1] <= u[1] && g[2] >= l[2] && g[2] <= u[2])
                    in_box.emplace_back(cells_[id].key, static_cast<std::uint32_t>(id));
            }
            std::sort(in_box.begin(), in_box.end());
            for (const auto& [key, id] : in_box)
                if (visit(cells_[id].p, cells_[id].v)) return true;
            return false;
        }
        for (std::int64_t z = l[2]; z <= u[2]; ++z)
            for (std::int64_t y = l[1]; y <= u[1]; ++y)
                for (std::int64_t x = l[0]; x <= u[0]; ++x) {
                    const std::uint32_t id = table_.find(detail::pack_cell({x, y, z}));
                    if (id != detail::CellTable::none && visit(cells_[id].p, cells_[id].v)) return true;
                }
        return false;
    }

private:
    static void check_side(Scalar side) {
        if (!(side > 0) || !std::isfinite(side) || !std::isfinite(1 / side))
            throw invalid_input("kintsugi::BucketGrid: the cell side is " + std::to_string(side) +
                                "; pass a finite cell side > 0 (e.g. the query radius)");
    }
    void init(const Vec3& origin, Scalar side) {
        if (!origin.allFinite()) throw invalid_input("kintsugi::BucketGrid: the origin has a NaN or infinite coordinate");
        check_side(side);
        origin_ = origin;
        side_ = side;
        inv_ = 1 / side;
    }
    static std::int64_t clamp_coord(Scalar a) {
        return static_cast<std::int64_t>(
            std::floor(std::clamp(a, Scalar(0), static_cast<Scalar>(detail::cell_coord_max))));
    }
    struct Cell {
        std::vector<Vec3> p;  // positions apart: all a distance test reads
        std::vector<T> v;
        std::uint64_t key = 0;
    };
    Vec3 origin_ = Vec3::Zero();
    Scalar side_ = 1, inv_ = 1;
    std::size_t size_ = 0;
    detail::CellTable table_;
    std::vector<Cell> cells_;
};

}  // namespace kintsugi
