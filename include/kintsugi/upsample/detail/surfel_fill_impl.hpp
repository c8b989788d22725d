// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file surfel_fill_impl.hpp
/// @brief Internal: the 2D gap detection and placement rules of Kanamori, Takahashi &
/// Nishita (2007) on one surfel's tangent plane, and the fill loop over all surfels.
/// Public entry point: kintsugi/upsample/surfel_fill.hpp.

#include <kintsugi/core/control.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/field/point_set_surface.hpp>
#include <kintsugi/spatial/bucket_grid.hpp>
#include <kintsugi/spatial/jet_fit.hpp>
#include <kintsugi/spatial/uniform_grid.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <vector>

namespace kintsugi::detail::surfel_fill {

using Vec2 = Eigen::Vector2d;
constexpr Scalar two_pi = 2 * std::numbers::pi_v<Scalar>;
/// Boundary arcs shorter than this (radians) count as covered: 1e-7 r is far below any
/// pixel, and ignoring it keeps rounding from adding surfels forever.
constexpr Scalar angle_tolerance = 1e-7;
/// A new surfel closer than this times its radius to an existing centre is not placed.
constexpr Scalar redundant_fraction = 0.1;

/// A disk projected onto the tangent plane of the surfel being processed (a circle).
struct Circle {
    Vec2 c = Vec2::Zero();
    Scalar rho = 0;
};

/// The arc [start, start + width] of the boundary of the circle (0, r) that `k` covers.
struct Arc {
    Scalar start = 0, width = 0;
    int circle = -1;  ///< index into the circle list
};

/// The arc of the boundary of circle (0, r) inside circle k: width 2π when k holds the
/// whole boundary, 0 when none of it.
inline Arc arc_on_boundary(Scalar r, const Circle& k) {
    const Scalar d = k.c.norm();
    if (d + r <= k.rho) return {0, two_pi};
    if (d >= r + k.rho || d + k.rho <= r || d == 0) return {0, 0};
    const Scalar cosa = std::clamp((r * r + d * d - k.rho * k.rho) / (2 * r * d), Scalar(-1), Scalar(1));
    const Scalar a = std::acos(cosa), theta = std::atan2(k.c.y(), k.c.x());
    return {theta - a, 2 * a};
}

/// Whether the arc `a` contains the angles [x, y] (y >= x, y - x < 2π), angles mod 2π.
inline bool arc_contains(const Arc& a, Scalar x, Scalar y) {
    if (a.width >= two_pi) return true;
    const Scalar off = std::fmod(std::fmod(x - a.start, two_pi) + two_pi, two_pi);
    return off + (y - x) <= a.width + 1e-12;
}

/// Eq. (1): the angle of surfel i's boundary one new surfel of radius rn covers, so that
/// with rn = ri the new centres form a hexagonal lattice (π/3).
inline Scalar delta_omega(Scalar rn, Scalar ri) {
    const Scalar s = (-rn * rn + rn * std::sqrt(rn * rn + 8 * ri * ri)) / (4 * ri * ri);
    return 2 * std::asin(std::clamp(s, Scalar(0), Scalar(1)));
}

/// Distance from p_i of the centre of a circle of radius rn that meets circle (0, ri) at
/// the angles ±h from its own direction; NaN when rn is too small for that.
inline Scalar centre_distance(Scalar ri, Scalar rn, Scalar h) {
    const Scalar s = std::sin(h), disc = rn * rn - ri * ri * s * s;
    if (disc < 0) return std::numeric_limits<Scalar>::quiet_NaN();
    return ri * std::cos(h) + std::sqrt(disc);
}

/// Orthocentre of the triangle (a, b, c); NaN when it is degenerate.
inline Vec2 orthocentre(const Vec2& a, const Vec2& b, const Vec2& c) {
    // Intersection of the altitude from a (perpendicular to bc) and from b (to ac).
    const Vec2 u = c - b, v = c - a;
    Eigen::Matrix2d m;
    m << u.x(), u.y(), v.x(), v.y();
    const Eigen::Vector2d rhs(u.dot(a), v.dot(b));
    const Scalar det = m.determinant();
    if (!(std::abs(det) > 1e-14 * (u.squaredNorm() + v.squaredNorm()))) return Vec2::Constant(std::numeric_limits<Scalar>::quiet_NaN());
    return m.inverse() * rhs;
}

/// A gap of surfel i's boundary: the angles [a, b], its left side ending at circle
/// `left`, its right side starting at circle `right` (-1: none).
struct Gap {
    Scalar a, b;
    int left, right;
};

/// What the 2D procedure of one surfel produced: the new centres (tangent-plane
/// coordinates) and how many gaps it found; `arcs` and `gap_list` are its scratch
/// (kept so that repeated calls allocate nothing).
struct PlaneFill {
    std::vector<Vec2> centres;
    std::size_t gaps = 0;
    std::size_t rule_b = 0, rule_c = 0, rule_d = 0, slides = 0;
    std::vector<Arc> arcs;
    std::vector<Gap> gap_list;
};

/// Whether the boundary of circle (0, r) is covered by `circles` with a margin, without
/// angles: the union of the covered arcs is the whole boundary exactly when each arc's
/// two ends lie inside another circle (a union of closed arcs without an end of its
/// own is the circle). Each end must lie inside by a relative 1e-9 of that circle's
/// radius, far above rounding, so true only where find_gaps' exact sweep (which also
/// forgives gaps below 1e-7 rad) finds none; false sends the call to that sweep. Most
/// surfels tested are covered: this replaces an acos and an atan2 per circle and the
/// sort with a few products. `ends` is scratch (x, y, circle).
inline bool covered_fast(Scalar r, const std::vector<Circle>& circles, std::vector<Arc>& ends) {
    ends.clear();
    const Scalar r2 = r * r;
    for (std::size_t k = 0; k < circles.size(); ++k) {
        const Circle& c = circles[k];
        const Scalar d2 = c.c.squaredNorm(), rho2 = c.rho * c.rho;
        // Leaving out a circle only makes this test stricter: the far ones go first,
        // without a square root or a division.
        if (d2 >= (r + c.rho) * (r + c.rho) || d2 == 0) continue;
        if (c.rho > r && std::sqrt(d2) + r <= c.rho) return true;  // the exact sweep stops there too
        // The two points of both boundaries: a c ± b c⊥ (none when one circle holds the other).
        const Scalar inv = 1 / d2, a = (r2 + d2 - rho2) * inv / 2, b2 = r2 * inv - a * a;
        if (!(b2 > 0)) continue;
        const Scalar b = std::sqrt(b2);
        const Scalar px = a * c.c.x(), py = a * c.c.y(), qx = -b * c.c.y(), qy = b * c.c.x();
        ends.push_back({px + qx, py + qy, static_cast<int>(k)});
        ends.push_back({px - qx, py - qy, static_cast<int>(k)});
    }
    if (ends.empty()) return false;
    // Each end against every other circle met, without early exits (branch-free and
    // vectorisable: most ends lie in one or two of about eight circles).
    const std::size_t na = ends.size() / 2;
    constexpr std::size_t stack = 64;
    std::array<Scalar, stack> cx, cy, lim;  // the first na are set below
    if (na > stack) return false;  // the exact sweep decides
    for (std::size_t m = 0; m < na; ++m) {
        const Circle& c = circles[static_cast<std::size_t>(ends[2 * m].circle)];
        cx[m] = c.c.x();
        cy[m] = c.c.y();
        lim[m] = c.rho * c.rho * (1 - 1e-9);
    }
    for (std::size_t e = 0; e < ends.size(); ++e) {
        const Scalar x = ends[e].start, y = ends[e].width;
        const std::size_t own = e / 2;
        bool inside = false;
        for (std::size_t m = 0; m < na; ++m) {
            const Scalar dx = x - cx[m], dy = y - cy[m];
            inside |= (m != own) & (dx * dx + dy * dy < lim[m]);
        }
        if (!inside) return false;
    }
    return true;
}

/// The uncovered arcs (gaps) of the boundary of circle (0, ri) among `circles`, each
/// with the circles bounding it; `gaps` is empty when the boundary is covered. `arcs`
/// is scratch.
inline void find_gaps(Scalar ri, const std::vector<Circle>& circles, std::vector<Arc>& arcs, std::vector<Gap>& gaps) {
    gaps.clear();
    if (covered_fast(ri, circles, arcs)) return;
    // Arcs of i's boundary covered by the neighbours that intersect it.
    arcs.clear();
    for (std::size_t k = 0; k < circles.size(); ++k) {
        Arc a = arc_on_boundary(ri, circles[k]);
        if (a.width >= two_pi) return;  // i lies inside one neighbour: nothing to fill
        if (a.width <= 0) continue;
        a.start = std::fmod(std::fmod(a.start, two_pi) + two_pi, two_pi);
        a.circle = static_cast<int>(k);
        arcs.push_back(a);
    }
    // Gaps: the complement of the arcs' union, with the circles bounding each gap (its
    // left side ends at `a`, its right side starts at `b`). ω = b - a (the angle
    // ∠ e_j p_i d_{j+1}); the union covers the paper's check of j - 1 and j + 2 and any
    // other neighbour that reaches into the gap.
    if (arcs.empty()) {
        gaps.push_back({0, two_pi, -1, -1});  // no neighbour: ω = 2π
        return;
    }
    std::sort(arcs.begin(), arcs.end(), [](const Arc& x, const Arc& y) {
        return x.start < y.start || (x.start == y.start && x.circle < y.circle);
    });
    const Scalar s0 = arcs.front().start;
    Scalar end = s0 + arcs.front().width;
    int end_circle = arcs.front().circle;
    for (const Arc& a : arcs)  // arcs that wrap past 2π cover the start of the sweep
        if (a.start + a.width - two_pi > end) {
            end = a.start + a.width - two_pi;
            end_circle = a.circle;
        }
    for (std::size_t k = 1; k < arcs.size(); ++k) {
        const Arc& a = arcs[k];
        if (a.start > end + angle_tolerance) gaps.push_back({end, a.start, end_circle, a.circle});
        if (a.start + a.width > end) {
            end = a.start + a.width;
            end_circle = a.circle;
        }
    }
    if (s0 + two_pi > end + angle_tolerance) gaps.push_back({end, s0 + two_pi, end_circle, arcs.front().circle});
}

/// Gap detection and filling on the tangent plane of surfel i (centre 0, radius ri)
/// among the projected neighbours `circles`, with new surfels of radius rn (§3.2.1).
/// New surfels are appended to `circles` as they are placed (later placements see them).
inline void fill_plane(Scalar ri, Scalar rn, std::vector<Circle>& circles, PlaneFill& out) {
    out.centres.clear();
    find_gaps(ri, circles, out.arcs, out.gap_list);
    const std::vector<Gap>& gaps = out.gap_list;
    out.gaps = gaps.size();
    const Scalar dw = delta_omega(rn, ri);

    // Eq. (2): a new centre inside an existing disk l slides towards p_i until
    // |q - p_i| / |q - p_l| = r_i / r_l; inside i itself, it goes back to i's boundary.
    auto slide = [&](Vec2 q) {
        int deepest = -1;
        Scalar depth = 1;
        for (std::size_t k = 0; k < circles.size(); ++k) {
            const Circle& l = circles[k];
            if (!(l.rho > 0)) continue;
            // Outside l with a margin: t >= 1 >= depth (skips the square root for most).
            const Scalar d2 = (q - l.c).squaredNorm();
            if (d2 > l.rho * l.rho * (1 + 1e-9)) continue;
            const Scalar t = std::sqrt(d2) / l.rho;
            if (t < depth) {
                depth = t;
                deepest = static_cast<int>(k);
            }
        }
        if (deepest < 0) return q;
        ++out.slides;
        const Circle& l = circles[static_cast<std::size_t>(deepest)];
        auto g = [&](Scalar t) {
            const Vec2 x = (1 - t) * q;
            return l.rho * x.norm() - ri * (x - l.c).norm();
        };
        Scalar lo = 0, hi = 1;
        if (g(lo) > 0 && g(hi) < 0) {
            for (int it = 0; it < 60; ++it) {
                const Scalar mid = (lo + hi) / 2;
                (g(mid) > 0 ? lo : hi) = mid;
            }
            q = (1 - lo) * q;
        }
        const Scalar d = q.norm();
        if (d < ri && d > 0) q *= ri / d;
        return q;
    };
    auto place = [&](const Vec2& q) {
        circles.push_back({q, rn});
        out.centres.push_back(q);
    };
    auto at_angle = [](Scalar angle, Scalar dist) { return Vec2(dist * std::cos(angle), dist * std::sin(angle)); };
    // A new disk near p_i or a neighbour's centre repeats that surfel: the fill drops a disk
    // that lands within redundant_fraction r_new of a centre and i stays open. Tested here at
    // twice that, since the back-projection moves a disk by a few hundredths of r: an
    // orthocentre 0.1002 r_new from a neighbour in the plane landed 0.099 r_new from it
    // (bunny00 134K, the one surfel left open).
    auto on_centre = [&](const Vec2& q) {
        constexpr Scalar near = 2 * redundant_fraction;
        if (q.norm() < near * rn) return true;
        for (const Circle& k : circles)
            if ((k.c - q).norm() < near * rn) return true;
        return false;
    };

    for (const Gap& gap : gaps) {
        Scalar cur = gap.a;
        int left = gap.left;
        const std::size_t first_new = circles.size();
        std::size_t placed = 0;
        for (int guard = 0; gap.b - cur > angle_tolerance && guard < 1000000; ++guard) {
            const Scalar omega = gap.b - cur;
            if (omega > dw) {
                // (a) one new surfel covering Δω of the boundary from `cur`.
                Vec2 q = slide(at_angle(cur + dw / 2, centre_distance(ri, rn, dw / 2)));
                place(q);
                ++placed;
                left = static_cast<int>(circles.size() - 1);
                const Arc a = arc_on_boundary(ri, circles.back());
                if (a.width >= two_pi) break;
                // The next one meets i and this one at one point: continue from this arc's end.
                Scalar end = a.start + a.width;
                end += two_pi * std::ceil((cur - end) / two_pi);  // the end nearest above cur
                if (!(end > cur + angle_tolerance)) end = cur + dw;  // cannot happen for a real cover; keep moving
                cur = end;
                continue;
            }
            // ω <= Δω: a small gap. Its two sides: the left circle and the right one (for a
            // full turn without neighbours, the first new surfel).
            const int right = gap.right >= 0 ? gap.right : (placed > 0 ? static_cast<int>(first_new) : -1);
            const bool sides_meet = left >= 0 && right >= 0 &&
                                    (circles[static_cast<std::size_t>(left)].c - circles[static_cast<std::size_t>(right)].c).norm() <
                                        circles[static_cast<std::size_t>(left)].rho + circles[static_cast<std::size_t>(right)].rho;
            if (sides_meet && placed > 0) {
                // (b) shift the last new surfel so that it reaches the gap's end.
                Circle& last = circles.back();
                const Arc a = arc_on_boundary(ri, last);
                Scalar start = a.start;
                start -= two_pi * std::floor((start - (cur - two_pi)) / two_pi);  // the start just below cur
                const Scalar h = (gap.b - start) / 2;
                const Scalar d = centre_distance(ri, rn, h);
                if (h < std::numbers::pi_v<Scalar> / 2 && std::isfinite(d)) {
                    const Vec2 q = slide(at_angle(start + h, d));
                    const Circle saved = last;
                    last.c = q;
                    if (arc_contains(arc_on_boundary(ri, last), start, gap.b)) {
                        out.centres.back() = q;
                        ++out.rule_b;
                        break;
                    }
                    last = saved;
                }
            } else if (sides_meet) {
                // (c) one new surfel at the orthocentre of the three centres.
                const Vec2 q0 = orthocentre(Vec2::Zero(), circles[static_cast<std::size_t>(left)].c,
                                            circles[static_cast<std::size_t>(right)].c);
                // A right angle at q_j or q_{j+1} puts the orthocentre on that centre, a
                // right angle at p_i on p_i itself (not in `circles`): a disk there would
                // repeat that surfel, so (d) is taken instead.
                if (q0.allFinite()) {
                    const Vec2 q = slide(q0);
                    if (!on_centre(q) && arc_contains(arc_on_boundary(ri, Circle{q, rn}), cur, gap.b)) {
                        place(q);
                        ++out.rule_c;
                        break;
                    }
                }
            }
            // (d) one new surfel that covers exactly what is left of the gap.
            const Scalar h = omega / 2;
            Vec2 q = at_angle(cur + h, centre_distance(ri, rn, h));
            const Vec2 qs = slide(q);
            if (arc_contains(arc_on_boundary(ri, Circle{qs, rn}), cur, gap.b)) q = qs;
            place(q);
            ++out.rule_d;
            break;
        }
    }
}

/// What a fill's neighbour query reads of a surfel besides its centre: unit normal,
/// level-0 radius, index. The surfels are kept in a BucketGrid<SurfelRest> with cells
/// twice as wide as the widest query, so a query meets at most 2 x 2 x 2 cells (8 hash
/// look-ups and cache misses instead of 27 with cells as wide as the query; on a surface
/// the candidates tested are about as many), and the cells are the tiles the fill works
/// on in parallel. The fill inserts in index order, so a query's results come in an
/// order that depends on the surfels alone. Why not UniformGrid: its appended points
/// wait apart until it rebuilds, and normal and radius would be read by index; the same
/// fill on UniformGrid (built, then appended to; same output bit for bit) took 25-30 %
/// more CPU on the 134K-point bench (docs/methods/surfel_upsampling.md, "The output grid").
struct SurfelRest {
    Vec3 n;
    Scalar r;
    Index i;
};

/// The tile of p in `cells` (its packed cell key) with the tile's colour (the parities
/// of its three coordinates: tiles of one colour are at least one cell apart) in the top
/// 3 bits: sorting by it groups a wave by colour, then by tile.
inline std::uint64_t coloured_tile(const BucketGrid<SurfelRest>& cells, const Vec3& p) {
    const detail::CellCoord g = cells.coord(p);
    std::uint64_t colour = 0;
    for (std::size_t a = 0; a < 3; ++a) colour |= static_cast<std::uint64_t>(g[a] & 1) << a;
    return (colour << 61) | detail::pack_cell(g);
}

/// The MLS samples in a UniformGrid (cells as wide as the gather radius: one hash
/// look-up, at most 27 cells a query) with their normals in the grid's slot order, so
/// that a gather reads positions and normals from a few contiguous runs (by index, the
/// reads scattered over the input: the gather took 1.9x the time on bunny00 134K).
struct InputSamples {
    UniformGrid grid;
    std::vector<Vec3> normals;  ///< normals[s]: the normal of the sample in slot s
    InputSamples(const PointSetSurface& mls, Scalar radius) : grid(mls.tree().points(), radius), normals(grid.size()) {
        parallel_for(0, normals.size(), [&](std::size_t s) { normals[s] = mls.normals()[grid.slot_index(s)]; }, 4096);
    }
    /// Fills `local` with every sample within `radius` of `centre` (index, position,
    /// normal), in the grid's order: cells by (z, y, x), sample index within a cell
    /// (the same set as a kd-tree radius search).
    void gather(const Vec3& centre, Scalar radius, detail::pss::LocalSamples& local) const {
        local.centre = centre;
        local.radius = radius;
        local.index.clear();
        local.points.clear();
        local.normals.clear();
        grid.for_each_slot_in_ball(centre, radius, [&](std::size_t s, Scalar) {
            local.index.push_back(grid.slot_index(s));
            local.points.push_back(grid.slot_point(s));
            local.normals.push_back(normals[s]);
        });
    }
};

/// An orthonormal tangent basis of the plane with unit normal n (a fixed function of n).
inline void tangent_basis(const Vec3& n, Vec3& e1, Vec3& e2) {
    const Vec3 a = std::abs(n.x()) < 0.6 ? Vec3::UnitX() : (std::abs(n.y()) < 0.6 ? Vec3::UnitY() : Vec3::UnitZ());
    e1 = n.cross(a).normalized();
    e2 = n.cross(e1);
}

}  // namespace kintsugi::detail::surfel_fill
