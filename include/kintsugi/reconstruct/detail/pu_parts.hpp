// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file pu_parts.hpp
/// @brief Internal to the PU + graph-cut reconstruction: the parts of a point set
/// separated by empty slabs (each gets its own octree cube, so a far outlier or a far
/// second object cannot blow the cube up), and the recentred, power-of-two-scaled
/// frame a part is reconstructed in (finite coordinates of any magnitude).

#include <kintsugi/core/types.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <vector>

namespace kintsugi::detail {

/// Whether `h` (half coordinates) may hold an empty slab wider than `fraction` x the
/// longest side of its box. Linear: each axis is cut into bins at most a third of
/// that width, and such a slab contains a whole bin with a margin, so a set whose
/// bins are all occupied on every axis has none (every scan of one object).
inline bool pu_may_have_gap(const std::vector<Vec3>& h, Scalar fraction) {
    Vec3 lo = Vec3::Constant(std::numeric_limits<Scalar>::infinity()), hi = -lo;
    for (const Vec3& p : h) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    const Vec3 span = hi - lo;
    const Scalar L = span.maxCoeff();
    if (!(L > 0)) return false;
    for (int a = 0; a < 3; ++a) {
        if (!(span[a] > fraction * L)) continue;  // no gap that wide fits on this axis
        const Scalar bins_real = std::ceil(3 * span[a] / (fraction * L));
        if (!(bins_real <= 4096)) return true;  // a tiny fraction: no shortcut
        const auto bins = static_cast<std::size_t>(bins_real);
        std::vector<std::uint8_t> seen(bins, 0);
        for (const Vec3& p : h) {
            const Scalar t = (p[a] - lo[a]) / span[a] * static_cast<Scalar>(bins);
            seen[std::min(bins - 1, static_cast<std::size_t>(std::max(Scalar(0), t)))] = 1;
        }
        if (std::find(seen.begin(), seen.end(), 0) != seen.end()) return true;
    }
    return false;
}

/// @brief The parts of a point set separated by empty slabs: a part is split, recursively,
/// at a gap between consecutive coordinates along x, y or z wider than `fraction` x
/// the longest side of the part's bounding box (fraction > 0; 0 or less: one part).
///
/// Returns the parts as increasing index lists, ordered by their smallest index. The
/// result depends only on the coordinates (ties broken by index). Overflow-free for any
/// finite coordinates (works on halves). Cost O(n log n) for a set with no such slab
/// (the usual case, decided in O(n) by pu_may_have_gap), O(n log² n) in the worst case
/// (linked lists per axis, lazily updated max-heaps of gaps, the smaller side moved).
inline std::vector<std::vector<Index>> pu_separated_parts(const std::vector<Vec3>& pts, Scalar fraction) {
    const std::size_t n = pts.size();
    std::vector<std::vector<Index>> out;
    std::vector<Index> all(n);
    std::iota(all.begin(), all.end(), Index{0});
    if (n < 2 || !(fraction > 0)) {
        out.push_back(std::move(all));
        return out;
    }
    std::vector<Vec3> h(n);
    for (std::size_t i = 0; i < n; ++i) h[i] = Scalar(0.5) * pts[i];
    if (!pu_may_have_gap(h, fraction)) {
        out.push_back(std::move(all));
        return out;
    }
    constexpr Index none = std::numeric_limits<Index>::max();
    std::array<std::vector<Index>, 3> next, prev;
    for (int a = 0; a < 3; ++a) {
        next[a].assign(n, none);
        prev[a].assign(n, none);
    }
    std::vector<std::size_t> part_of(n, 0);
    struct Gap {
        Scalar width;
        Index left;  ///< the gap lies between left and next[axis][left]
    };
    // Max-heap on width; equal widths: the smaller left index first (deterministic).
    auto gap_less = [](const Gap& x, const Gap& y) { return x.width < y.width || (x.width == y.width && x.left > y.left); };
    struct Part {
        std::array<Index, 3> head{}, tail{};
        std::array<std::vector<Gap>, 3> heap;
    };
    std::vector<Part> parts;
    auto make_part = [&](std::vector<Index>& members) {
        const std::size_t id = parts.size();
        parts.emplace_back();
        for (const Index i : members) part_of[i] = id;
        for (int a = 0; a < 3; ++a) {
            std::sort(members.begin(), members.end(),
                      [&](Index x, Index y) { return h[x][a] < h[y][a] || (h[x][a] == h[y][a] && x < y); });
            Part& P = parts[id];
            P.head[a] = members.front();
            P.tail[a] = members.back();
            prev[a][members.front()] = none;
            next[a][members.back()] = none;
            auto& H = P.heap[a];
            H.reserve(members.size());
            for (std::size_t k = 0; k + 1 < members.size(); ++k) {
                next[a][members[k]] = members[k + 1];
                prev[a][members[k + 1]] = members[k];
                H.push_back({h[members[k + 1]][a] - h[members[k]][a], members[k]});
            }
            std::make_heap(H.begin(), H.end(), gap_less);
        }
        return id;
    };
    auto unlink = [&](std::size_t p, Index x) {
        for (int b = 0; b < 3; ++b) {
            const Index pv = prev[b][x], nx = next[b][x];
            if (pv != none) next[b][pv] = nx;
            else parts[p].head[b] = nx;
            if (nx != none) prev[b][nx] = pv;
            else parts[p].tail[b] = pv;
            if (pv != none && nx != none) {
                auto& H = parts[p].heap[b];
                H.push_back({h[nx][b] - h[pv][b], pv});
                std::push_heap(H.begin(), H.end(), gap_less);
            }
        }
    };
    make_part(all);
    std::vector<std::size_t> work{0};
    std::vector<Index> side;
    while (!work.empty()) {
        const std::size_t p = work.back();
        Scalar L = 0;
        for (int a = 0; a < 3; ++a) L = std::max(L, h[parts[p].tail[a]][a] - h[parts[p].head[a]][a]);
        bool split = false;
        for (int a = 0; a < 3 && !split; ++a) {
            auto& H = parts[p].heap[a];
            while (!H.empty()) {  // drop entries of gaps that changed since
                const Gap& g = H.front();
                const Index r = next[a][g.left];
                if (part_of[g.left] == p && r != none && h[r][a] - h[g.left][a] == g.width) break;
                std::pop_heap(H.begin(), H.end(), gap_less);
                H.pop_back();
            }
            if (H.empty() || !(H.front().width > fraction * L)) continue;
            // Split between left and right; walk from both ends to find the smaller side
            // in time proportional to it.
            const Index left = H.front().left, right = next[a][left];
            Index f = parts[p].head[a], b = parts[p].tail[a];
            bool forward = false;
            for (;;) {
                if (f == left) {
                    forward = true;
                    break;
                }
                if (b == right) break;
                f = next[a][f];
                b = prev[a][b];
            }
            side.clear();
            if (forward)
                for (Index x = parts[p].head[a];; x = next[a][x]) {
                    side.push_back(x);
                    if (x == left) break;
                }
            else
                for (Index x = right; x != none; x = next[a][x]) side.push_back(x);
            for (const Index x : side) unlink(p, x);
            std::vector<Index> members(side);
            work.push_back(make_part(members));
            split = true;
        }
        if (!split) work.pop_back();  // p is final (it is always the last pending part)
    }
    for (std::size_t p = 0; p < parts.size(); ++p) {
        std::vector<Index> members;
        for (Index x = parts[p].head[0]; x != none; x = next[0][x]) members.push_back(x);
        std::sort(members.begin(), members.end());
        out.push_back(std::move(members));
    }
    std::sort(out.begin(), out.end(), [](const auto& x, const auto& y) { return x.front() < y.front(); });
    return out;
}

/// The frame a part is reconstructed in: x' = (x - center) 2^exponent, with the box's
/// longest side in [1, 2) and its centre at 0; or the caller's own coordinates
/// (identity) when they are safe: longest side at least 2^-32 and every coordinate at
/// most 2^32 in magnitude, so that squared distances and CGAL's predicates stay far
/// from overflow and underflow. The identity keeps ordinary inputs bit for bit as
/// before; any other frame maps back with one power-of-two product and one sum.
struct PUFrame {
    bool identity = true;
    Vec3 center = Vec3::Zero();
    int exponent = 0;

    [[nodiscard]] Vec3 to_frame(const Vec3& x) const {
        if (identity) return x;
        // Halves first: x - center cannot overflow.
        const Vec3 d = Scalar(0.5) * x - Scalar(0.5) * center;
        return {std::ldexp(d.x(), exponent + 1), std::ldexp(d.y(), exponent + 1), std::ldexp(d.z(), exponent + 1)};
    }
    [[nodiscard]] Vec3 from_frame(const Vec3& y) const {
        if (identity) return y;
        return Vec3(std::ldexp(y.x(), -exponent), std::ldexp(y.y(), -exponent), std::ldexp(y.z(), -exponent)) + center;
    }

    /// The frame of the points pts[i], i in `ids` (all finite).
    [[nodiscard]] static PUFrame of(const std::vector<Vec3>& pts, const std::vector<Index>& ids) {
        Vec3 lo = Vec3::Constant(std::numeric_limits<Scalar>::infinity()), hi = -lo;
        for (const Index i : ids) {
            const Vec3 h = Scalar(0.5) * pts[i];
            lo = lo.cwiseMin(h);
            hi = hi.cwiseMax(h);
        }
        PUFrame f;
        if (ids.empty()) return f;
        const Scalar half_side = (hi - lo).maxCoeff();               // longest side / 2
        const Scalar half_reach = lo.cwiseAbs().cwiseMax(hi.cwiseAbs()).maxCoeff();  // max |x| / 2
        constexpr Scalar small = 0x1p-33, large = 0x1p31;            // 2^-32 and 2^32, halved
        if ((half_side >= small && half_reach <= large) || !(half_side > 0)) return f;
        f.identity = false;
        f.center = lo + hi;  // (min + max) / 2
        f.exponent = -(std::ilogb(half_side) + 1);
        return f;
    }
};

/// Rescales by a power of two (exactly) every normal whose length is too small or too
/// large to normalise without underflow or overflow; the others stay bit for bit.
inline void pu_safe_normals(std::vector<Vec3>& nrm) {
    for (Vec3& n : nrm) {
        const Scalar a = n.cwiseAbs().maxCoeff();
        if (a > 0 && (a < 0x1p-400 || a > 0x1p400)) n *= std::ldexp(Scalar(1), -std::ilogb(a));
    }
}

}  // namespace kintsugi::detail
