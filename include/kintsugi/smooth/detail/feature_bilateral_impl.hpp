// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file feature_bilateral_impl.hpp
/// @brief Internal machinery of smooth/feature_bilateral.hpp: normal voting tensor,
/// sharp-edge extraction and the four bilateral filters, on the internal layout
/// (vector<Vec3> positions + vector<Face>). Not part of the API.

#include <kintsugi/core/control.hpp>
#include <kintsugi/core/disjoint_sets.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/mesh/topology.hpp>
#include <kintsugi/smooth/sharp_feature_params.hpp>
#include <kintsugi/spatial/uniform_grid.hpp>

#include <Eigen/Eigenvalues>

#if defined(__SSE2__)
#include <emmintrin.h>
#include <xmmintrin.h>
#endif
// Filter 3's passes also have an AVX body, chosen at run time on x86 CPUs that have AVX (GCC
// and clang: functions with their own target; the build's flags stay baseline). Not in builds
// with FMA enabled (-march=native and the like): GCC may then fuse the SSE2 body's products
// and sums, and the two bodies would no longer give the same bits.
#if defined(__SSE2__) && (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__)) && \
    !defined(__FMA__) && !defined(KINTSUGI_NO_AVX)
#define KINTSUGI_FBS_AVX 1
#include <immintrin.h>
#endif

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <iterator>
#include <limits>
#include <optional>
#include <utility>
#include <string>
#include <vector>

namespace kintsugi::detail::fbs {

/// Runs body(i) for i in [0, n) in parallel, in ~20 blocks, reporting progress
/// (local fraction from `from` to `to`) and checking cancellation between blocks on
/// the calling thread.
template <class Body>
void blocked_for(Progress& progress, std::size_t n, double from, double to, Body&& body) {
    const std::size_t blocks = std::clamp<std::size_t>(n / 4096, 1, 20);
    for (std::size_t b = 0; b < blocks; ++b) {
        const std::size_t first = n * b / blocks, last = n * (b + 1) / blocks;
        parallel_for(first, last, body, 64);
        progress.update(from + (to - from) * static_cast<double>(b + 1) / static_cast<double>(blocks));
    }
}

/// Most grid points one neighbourhood query tests (UniformGrid's max_candidates), so a
/// query costs O(1) however many faces crowd into its cells (a fan of 20K triangles
/// around one vertex: every cube holds thousands). Ordinary meshes stay far below it
/// (a few hundred at most); above it the query tests an evenly strided subset.
inline constexpr std::size_t max_candidates = 2048;
/// Cap on the grid points each query behind the stored neighbour lists (filters 3
/// and 4) tests, for lists over n items: max_candidates while the lists fit in about
/// 16M entries (8 bytes each), less above (never below 256), so the lists' memory and
/// each pass's work stay linear in the mesh with a small constant. Meshes up to 8K
/// items keep max_candidates exactly; ordinary larger ones stay below the cap (cubes
/// of 1–2 mean edges: tens to a few hundred faces). A 200K-face fan (every cube holds
/// thousands) took 3.6 GB and 54 s with max_candidates, 0.6 GB and 10 s with this.
inline std::size_t max_listed(std::size_t n) {
    constexpr std::size_t budget = std::size_t{1} << 24, floor = 256;
    return std::clamp<std::size_t>(budget / std::max<std::size_t>(n, 1), floor, max_candidates);
}
/// Most edge-to-face entries one sharp-edge-bounded walk (reach_faces) scans.
inline constexpr std::size_t max_walk = 16 * max_candidates;

/// Unit normal (zero for a degenerate face), area and centroid of every face.
struct FaceGeometry {
    std::vector<Vec3> normal, centroid;
    std::vector<Scalar> area;
};

inline void compute_face_geometry(const std::vector<Vec3>& V, const std::vector<Face>& F, FaceGeometry& g) {
    const std::size_t nf = F.size();
    g.normal.resize(nf);
    g.centroid.resize(nf);
    g.area.resize(nf);
    parallel_for(0, nf, [&](std::size_t f) {
        const Vec3& a = V[F[f][0]];
        const Vec3& b = V[F[f][1]];
        const Vec3& c = V[F[f][2]];
        const Vec3 cr = (b - a).cross(c - a);
        const Scalar len = cr.norm();
        // A face whose cross product is below round-off of its size is degenerate:
        // zero normal and zero area, so it never weighs in any filter.
        const Scalar scale = std::max({(b - a).squaredNorm(), (c - a).squaredNorm(), (c - b).squaredNorm()});
        const bool degenerate = !(len > 1e-14 * scale) || !std::isfinite(len);
        g.normal[f] = degenerate ? Vec3::Zero() : Vec3(cr / len);
        g.area[f] = degenerate ? Scalar(0) : len / 2;
        g.centroid[f] = (a + b + c) / 3;
    }, 1024);
}

/// Grid filter: item i is kept when weight[i] > 0 (zero-area faces, zero-length edges
/// never weigh in).
inline auto has_area(const std::vector<Scalar>& weight) {
    return [&weight](std::size_t i) { return weight[i] > 0; };
}

/// Gaussian exp(-x²/(2σ²)) (unnormalised: the filters normalise by k_r).
inline Scalar gauss(Scalar x2, Scalar sigma) { return std::exp(-x2 / (2 * sigma * sigma)); }

/// Gaussian exp(-x²/(2σ²)) for x² in [0, max2], tabulated (2048 intervals, linear
/// interpolation: absolute error below 1e-6 for max2 ≤ 40σ²); 0 beyond max2. Used
/// where the filters evaluate one Gaussian per neighbour per pass.
class GaussTable {
public:
    GaussTable(Scalar sigma, Scalar max2) : scale_(n_ / max2) {
        for (std::size_t k = 0; k <= n_; ++k) table_[k] = gauss(static_cast<Scalar>(k) / scale_, sigma);
        table_[n_ + 1] = table_[n_];
    }
    Scalar operator()(Scalar x2) const {
        const Scalar u = x2 * scale_;
        if (!(u < static_cast<Scalar>(n_))) return u == static_cast<Scalar>(n_) ? table_[n_] : Scalar(0);
        const std::size_t k = static_cast<std::size_t>(u);
        const Scalar t = u - static_cast<Scalar>(k);
        return table_[k] + t * (table_[k + 1] - table_[k]);
    }
    /// For vector versions of operator(): the values at the n_ + 2 knots, and the factor
    /// taking x² to the knot scale.
    [[nodiscard]] const Scalar* knots() const { return table_.data(); }
    [[nodiscard]] Scalar knot_scale() const { return scale_; }
    static constexpr std::size_t intervals() { return n_; }

private:
    static constexpr std::size_t n_ = 2048;
    Scalar scale_;
    std::array<Scalar, n_ + 2> table_{};
};

/// Neighbour indices as stored in Neighbourhoods: 32-bit, or 16-bit offsets from a base.
struct WideIndex {
    const std::uint32_t* p;
    std::uint32_t operator[](std::size_t j) const { return p[j]; }
};
struct NarrowIndex {
    const std::uint16_t* p;
    std::uint32_t base;
    std::uint32_t operator[](std::size_t j) const { return base + p[j]; }
};

/// Neighbour lists in CSR form (indices and single-precision weights), stored in
/// fixed chunks of `chunk` items (each chunk its own CSR, filled by one task: no copy
/// into one array, so the peak memory is the lists themselves). A list spanning at most
/// 65535 indices (items and neighbours Morton-ordered: most lists) is held as 16-bit offsets
/// from its smallest index, so the passes stream 6 bytes per neighbour instead of 8; the
/// others (a cube across a large Morton step) as 32-bit indices. The same indices either way.
struct Neighbourhoods {
    static constexpr std::size_t chunk = 2048;
    /// base[] of a list held as 32-bit indices (no index reaches it: UniformGrid holds fewer
    /// than 2^32 − 1 points).
    static constexpr std::uint32_t wide = 0xffffffffu;
    struct Part {
        std::vector<std::uint32_t> offset;  // items in the chunk + 1: the lists in `weight`
        std::vector<std::uint32_t> start;   // each list's first entry in `delta` or `index`
        std::vector<std::uint32_t> base;    // its smallest index, or `wide`
        std::vector<std::uint16_t> delta;   // offsets from base (lists with a base)
        std::vector<std::uint32_t> index;   // indices (wide lists)
        std::vector<float> weight;
    };
    std::vector<Part> parts;
    std::size_t items = 0;  ///< the item count and cube half side of the last build
    Scalar scale = 0;
    /// The neighbours of item i: indices (`index`, or `delta` from `base` when `index` is
    /// null) and weights (nullptr for lists built without weights), `size` of each.
    struct Span {
        const std::uint32_t* index;
        const std::uint16_t* delta;
        std::uint32_t base;
        const float* weight;
        std::size_t size;
        [[nodiscard]] std::uint32_t at(std::size_t j) const { return index ? index[j] : base + delta[j]; }
        /// f(WideIndex or NarrowIndex): one dispatch per list, not per neighbour.
        template <class F>
        decltype(auto) with_indices(F&& f) const {
            return index ? f(WideIndex{index}) : f(NarrowIndex{delta, base});
        }
    };
    [[nodiscard]] Span of(std::size_t i) const {
        const Part& p = parts[i / chunk];
        const std::size_t k = i % chunk;
        const bool narrow = p.base[k] != wide;
        return {narrow ? nullptr : p.index.data() + p.start[k], narrow ? p.delta.data() + p.start[k] : nullptr,
                narrow ? p.base[k] : 0, p.weight.empty() ? nullptr : p.weight.data() + p.offset[k],
                p.offset[k + 1] - p.offset[k]};
    }
};

/// Builds the lists: gather(i, append) calls append(q, w, count) with the neighbours
/// q[0..count) of i and their weights (w = nullptr: lists without weights), in an
/// order that depends on i alone. Chunks
/// are filled in parallel; the lists do not depend on the thread count.
template <class Gather>
void build_neighbourhoods(std::size_t n, Neighbourhoods& out, Progress& progress, double from, double to,
                          Gather&& gather) {
    constexpr std::size_t chunk = Neighbourhoods::chunk;
    const std::size_t nc = (n + chunk - 1) / chunk;
    out.parts.resize(nc);  // parts keep their capacity from an earlier build
    const std::size_t blocks = std::clamp<std::size_t>(nc / 4, 1, 20);
    for (std::size_t blk = 0; blk < blocks; ++blk) {
        parallel_for(nc * blk / blocks, nc * (blk + 1) / blocks, [&](std::size_t c) {
            const std::size_t first = c * chunk, last = std::min(n, first + chunk);
            Neighbourhoods::Part& part = out.parts[c];
            part.offset.assign(last - first + 1, 0);
            // Gathered into this thread's buffers, then copied at their exact size: grown in
            // place, a chunk's arrays kept up to twice their size in capacity (the lists were
            // 541 MB at 590K faces, 2026-12-07).
            thread_local std::vector<std::uint32_t> index;
            thread_local std::vector<float> weight;
            index.clear();
            weight.clear();
            for (std::size_t i = first; i < last; ++i) {
                gather(i, [&](const std::uint32_t* q, const float* w, std::size_t count) {
                    index.insert(index.end(), q, q + count);
                    if (w) weight.insert(weight.end(), w, w + count);
                });
                part.offset[i - first + 1] = static_cast<std::uint32_t>(index.size());
            }
            // Each list as 16-bit offsets from its smallest index when it spans at most 65535,
            // else as 32-bit indices. Sized exactly when they grow (clear, then resize: a vector
            // grown from empty gets the exact size); a later, smaller build keeps the capacity, as
            // the lists of each build are about the same size. An array the chunk no longer
            // uses is released (the chunk's lists may have changed kind).
            const std::size_t items = last - first;
            part.start.clear();
            part.start.resize(items);
            part.base.clear();
            part.base.resize(items);
            std::size_t narrow = 0, far = 0;
            for (std::size_t k = 0; k < items; ++k) {
                const auto lo = index.begin() + part.offset[k], hi = index.begin() + part.offset[k + 1];
                const auto [mn, mx] = std::minmax_element(lo, hi);
                const bool fits = lo == hi || *mx - *mn <= 0xffffu;
                part.base[k] = fits ? (lo == hi ? 0 : *mn) : Neighbourhoods::wide;
                part.start[k] = static_cast<std::uint32_t>(fits ? narrow : far);
                (fits ? narrow : far) += static_cast<std::size_t>(hi - lo);
            }
            part.delta.clear();
            if (narrow == 0) part.delta.shrink_to_fit();
            part.delta.resize(narrow);
            part.index.clear();
            if (far == 0) part.index.shrink_to_fit();
            part.index.resize(far);
            for (std::size_t k = 0; k < items; ++k) {
                const std::uint32_t b = part.base[k], count = part.offset[k + 1] - part.offset[k];
                const std::uint32_t* q = index.data() + part.offset[k];
                if (b == Neighbourhoods::wide)
                    std::copy(q, q + count, part.index.begin() + part.start[k]);
                else
                    for (std::uint32_t e = 0; e < count; ++e)
                        part.delta[part.start[k] + e] = static_cast<std::uint16_t>(q[e] - b);
            }
            part.weight.assign(weight.begin(), weight.end());
            // The buffers outlive the call (one pair per thread): kept up to 1M entries (4 MB
            // each; an ordinary chunk holds about 150K), released above (dense cubes).
            if (index.capacity() > (std::size_t{1} << 20)) index = {};
            if (weight.capacity() > (std::size_t{1} << 20)) weight = {};
        }, 1);
        progress.update(from + (to - from) * static_cast<double>(blk + 1) / static_cast<double>(blocks));
    }
}

/// Buffers reused by every pass of one run (grid, neighbour lists, face geometry), so
/// that the repeated neighbourhood builds do not allocate and fault in fresh memory.
struct Workspace {
    UniformGrid grid;
    Neighbourhoods lists;         // filter 3: faces around each face
    Neighbourhoods vertex_lists;  // filter 4: faces around each vertex (no weights)
    FaceGeometry geometry;
};

/// Sharp edges as barriers for the face filters (features = true): a face t* in the
/// cube of r counts only when it is reached from r's own faces by a walk over faces
/// inside the cube that crosses no sharp edge. Away from features (no sharp-edge
/// vertex near) this is every face of the cube and no walk is made.
struct Barriers {
    const MeshTopology* topo = nullptr;
    std::vector<unsigned char> sharp_edge;  // by topology edge id
    std::vector<Index> feature_vertices;     // vertices of sharp edges (for the "near" test)
    [[nodiscard]] bool active() const { return topo != nullptr && !feature_vertices.empty(); }
};

/// Marks (with the current stamp) the faces reachable from `seeds` over non-sharp
/// edges with centroid in the cube of half side h around c. Returns the calling
/// thread's marks and the stamp: face q was reached iff marks[q] == stamp.
struct Reach {
    const std::vector<std::uint32_t>* marks;
    std::uint32_t stamp;
    [[nodiscard]] bool operator()(Index q) const { return (*marks)[q] == stamp; }
};
inline Reach reach_faces(const Barriers& b, const std::vector<Vec3>& centroid, std::span<const Index> seeds,
                                 const Vec3& c, Scalar h) {
    thread_local std::vector<std::uint32_t> mark, edge_mark;
    thread_local std::vector<Index> queue;
    thread_local std::uint32_t stamp = 0;
    thread_local const std::vector<Vec3>* owner = nullptr;
    thread_local const MeshTopology* owner_topo = nullptr;
    if (mark.size() != centroid.size() || owner != &centroid || edge_mark.size() != b.topo->num_edges() ||
        owner_topo != b.topo) {
        mark.assign(centroid.size(), 0);
        edge_mark.assign(b.topo->num_edges(), 0);
        stamp = 0;
        owner = &centroid;
        owner_topo = b.topo;
    }
    if (++stamp == 0) {
        std::fill(mark.begin(), mark.end(), 0);
        std::fill(edge_mark.begin(), edge_mark.end(), 0);
        stamp = 1;
    }
    queue.clear();
    for (Index f : seeds)
        if (mark[f] != stamp) {
            mark[f] = stamp;
            queue.push_back(f);
        }
    // Each edge is expanded once (a second expansion finds nothing new), and the walk
    // stops after max_walk edge-face entries: an edge shared by thousands of faces
    // costs one scan, not one per face.
    std::size_t scanned = 0;
    for (std::size_t k = 0; k < queue.size() && scanned <= max_walk; ++k) {
        const Index f = queue[k];
        for (Index e : b.topo->face_edges(f)) {
            if (b.sharp_edge[e] || edge_mark[e] == stamp) continue;
            edge_mark[e] = stamp;
            scanned += b.topo->edge_faces(e).size();
            for (Index q : b.topo->edge_faces(e))
                if (mark[q] != stamp && (centroid[q] - c).cwiseAbs().maxCoeff() <= h) {
                    mark[q] = stamp;
                    queue.push_back(q);
                }
        }
    }
    return {&mark, stamp};
}
/// The range kernel of filter 3 on Y = ‖n_t − n_t*‖: g(Y) = exp(−Y²/(2σ²)) for Y ≤ cut, 0
/// beyond (a neighbour across a sharp edge). The paper's: σ = 0.6, cut 1 (normals 60° apart).
struct RangeKernel {
    Scalar sigma = 0.6;
    Scalar cut = 1;
};

/// The range weight of filter 3, g = exp(−a·Y²) for Y² ≤ cut2 and 0 beyond: exp(x) = p(x/8)⁸
/// with p the degree-5 Taylor polynomial, relative error below 1e-6 for a·Y² ≤ 1.4 (σ 0.6,
/// cut 1) and below 3e-4 for a·Y² ≤ 4.02 (σ 0.3, cut 0.85: the straight-crease detection; a
/// weight, not a test), no branch and no table, in the same arithmetic for one value and for
/// four (SSE2).
inline float range_weight(float Y2, float a, float cut2 = 1.f) {
    const float x = -a * Y2 * 0.125f;
    float e = 1 + x * (1 + x * (0.5f + x * (1.f / 6 + x * (1.f / 24 + x * (1.f / 120)))));
    e *= e;
    e *= e;
    e *= e;
    return Y2 <= cut2 ? e : 0.f;
}
#if defined(__SSE2__)
inline __m128 range_weight(__m128 Y2, float a, float cut2 = 1.f) {
    const __m128 x = _mm_mul_ps(Y2, _mm_set1_ps(-a * 0.125f));
    __m128 e = _mm_add_ps(_mm_set1_ps(1.f / 24), _mm_mul_ps(x, _mm_set1_ps(1.f / 120)));
    e = _mm_add_ps(_mm_set1_ps(1.f / 6), _mm_mul_ps(x, e));
    e = _mm_add_ps(_mm_set1_ps(0.5f), _mm_mul_ps(x, e));
    e = _mm_add_ps(_mm_set1_ps(1.f), _mm_mul_ps(x, e));
    e = _mm_add_ps(_mm_set1_ps(1.f), _mm_mul_ps(x, e));
    e = _mm_mul_ps(e, e);
    e = _mm_mul_ps(e, e);
    e = _mm_mul_ps(e, e);
    return _mm_and_ps(e, _mm_cmple_ps(Y2, _mm_set1_ps(cut2)));
}
#endif

/// Filter 3's sum over the neighbours q of one face t: Σ_q w_q·g(‖n_t − n_q‖)·n_q, with w_q
/// the stored spatial weight, g range_weight, and the normals as padded, 16-byte aligned float4
/// (`normal`, `nt`). Four neighbours at a time where SSE2 is available, with local
/// accumulators (through a lambda capturing them by reference they went through memory on
/// every neighbour) and no branch on the cut-off (whether a noisy neighbour's normal is
/// beyond it is unpredictable); eight at a time with AVX (sum_normals_avx), which adds in the
/// same order, so both give the same bits.
struct NormalSum {
    float x = 0, y = 0, z = 0;
};

/// One neighbour list for the sums: indices (WideIndex or NarrowIndex), weights, size.
template <class I>
struct IndexedList {
    I index;
    const float* weight;
    std::size_t size;
};

/// The lane sums, added (0 + 1) + (2 + 3), and the neighbours from `j` on one at a time.
template <class L>
NormalSum finish_normal_sum(const float (&lane)[3][4], const float* normal, const float* nt, const L& nbrs,
                            std::size_t j, float a, float cut2) {
    NormalSum s{(lane[0][0] + lane[0][1]) + (lane[0][2] + lane[0][3]),
                (lane[1][0] + lane[1][1]) + (lane[1][2] + lane[1][3]),
                (lane[2][0] + lane[2][1]) + (lane[2][2] + lane[2][3])};
    for (; j < nbrs.size; ++j) {
        const float* nq = normal + 4 * std::size_t{nbrs.index[j]};
        const float dx = nt[0] - nq[0], dy = nt[1] - nq[1], dz = nt[2] - nq[2];
        const float w = nbrs.weight[j] * range_weight(dx * dx + dy * dy + dz * dz, a, cut2);
        s.x += w * nq[0];
        s.y += w * nq[1];
        s.z += w * nq[2];
    }
    return s;
}

#if defined(__SSE2__)
/// Neighbours j..j+3 into the lane sums sx, sy, sz (t's normal broadcast in tx, ty, tz).
template <class L>
void add_four_normals(__m128& sx, __m128& sy, __m128& sz, __m128 tx, __m128 ty, __m128 tz, const float* normal,
                      const L& nbrs, std::size_t j, float a, float cut2) {
    __m128 n0 = _mm_load_ps(normal + 4 * std::size_t{nbrs.index[j]});
    __m128 n1 = _mm_load_ps(normal + 4 * std::size_t{nbrs.index[j + 1]});
    __m128 n2 = _mm_load_ps(normal + 4 * std::size_t{nbrs.index[j + 2]});
    __m128 n3 = _mm_load_ps(normal + 4 * std::size_t{nbrs.index[j + 3]});
    _MM_TRANSPOSE4_PS(n0, n1, n2, n3);  // n0, n1, n2: x, y, z of the four
    const __m128 dx = _mm_sub_ps(tx, n0), dy = _mm_sub_ps(ty, n1), dz = _mm_sub_ps(tz, n2);
    const __m128 Y2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
    const __m128 w = _mm_mul_ps(_mm_loadu_ps(nbrs.weight + j), range_weight(Y2, a, cut2));
    sx = _mm_add_ps(sx, _mm_mul_ps(w, n0));
    sy = _mm_add_ps(sy, _mm_mul_ps(w, n1));
    sz = _mm_add_ps(sz, _mm_mul_ps(w, n2));
}
#endif

#if defined(KINTSUGI_FBS_AVX)
/// range_weight on eight values, in the SSE2 version's arithmetic (no FMA: the target is AVX
/// alone, so nothing is contracted and each lane gives the SSE2 version's bits).
__attribute__((target("avx"))) inline __m256 range_weight8(__m256 Y2, float a, float cut2) {
    const __m256 x = _mm256_mul_ps(Y2, _mm256_set1_ps(-a * 0.125f));
    __m256 e = _mm256_add_ps(_mm256_set1_ps(1.f / 24), _mm256_mul_ps(x, _mm256_set1_ps(1.f / 120)));
    e = _mm256_add_ps(_mm256_set1_ps(1.f / 6), _mm256_mul_ps(x, e));
    e = _mm256_add_ps(_mm256_set1_ps(0.5f), _mm256_mul_ps(x, e));
    e = _mm256_add_ps(_mm256_set1_ps(1.f), _mm256_mul_ps(x, e));
    e = _mm256_add_ps(_mm256_set1_ps(1.f), _mm256_mul_ps(x, e));
    e = _mm256_mul_ps(e, e);
    e = _mm256_mul_ps(e, e);
    e = _mm256_mul_ps(e, e);
    return _mm256_and_ps(e, _mm256_cmp_ps(Y2, _mm256_set1_ps(cut2), _CMP_LE_OS));
}

/// sum_normals with eight neighbours per step: the weights of eight at once, then added to the
/// four lane sums as two steps of four, in the order of the SSE2 loop.
template <class L>
__attribute__((target("avx"))) NormalSum sum_normals_avx(const float* normal, const float* nt, const L& nbrs,
                                                         float a, float cut2) {
    const __m256 tx = _mm256_set1_ps(nt[0]), ty = _mm256_set1_ps(nt[1]), tz = _mm256_set1_ps(nt[2]);
    __m128 sx = _mm_setzero_ps(), sy = _mm_setzero_ps(), sz = _mm_setzero_ps();
    std::size_t j = 0;
    for (; j + 8 <= nbrs.size; j += 8) {
        const std::uint32_t q[8] = {nbrs.index[j],     nbrs.index[j + 1], nbrs.index[j + 2], nbrs.index[j + 3],
                                    nbrs.index[j + 4], nbrs.index[j + 5], nbrs.index[j + 6], nbrs.index[j + 7]};
        // Rows k and k + 4 in the two 128-bit halves; the in-half transpose (as _MM_TRANSPOSE4_PS).
        const __m256 r0 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_load_ps(normal + 4 * std::size_t{q[0]})),
                                               _mm_load_ps(normal + 4 * std::size_t{q[4]}), 1);
        const __m256 r1 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_load_ps(normal + 4 * std::size_t{q[1]})),
                                               _mm_load_ps(normal + 4 * std::size_t{q[5]}), 1);
        const __m256 r2 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_load_ps(normal + 4 * std::size_t{q[2]})),
                                               _mm_load_ps(normal + 4 * std::size_t{q[6]}), 1);
        const __m256 r3 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_load_ps(normal + 4 * std::size_t{q[3]})),
                                               _mm_load_ps(normal + 4 * std::size_t{q[7]}), 1);
        const __m256 t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpacklo_ps(r2, r3);
        const __m256 t2 = _mm256_unpackhi_ps(r0, r1), t3 = _mm256_unpackhi_ps(r2, r3);
        const __m256 nx = _mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(1, 0, 1, 0));
        const __m256 ny = _mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(3, 2, 3, 2));
        const __m256 nz = _mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(1, 0, 1, 0));
        const __m256 dx = _mm256_sub_ps(tx, nx), dy = _mm256_sub_ps(ty, ny), dz = _mm256_sub_ps(tz, nz);
        const __m256 Y2 =
            _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)), _mm256_mul_ps(dz, dz));
        const __m256 w = _mm256_mul_ps(_mm256_loadu_ps(nbrs.weight + j), range_weight8(Y2, a, cut2));
        const __m256 wx = _mm256_mul_ps(w, nx), wy = _mm256_mul_ps(w, ny), wz = _mm256_mul_ps(w, nz);
        sx = _mm_add_ps(_mm_add_ps(sx, _mm256_castps256_ps128(wx)), _mm256_extractf128_ps(wx, 1));
        sy = _mm_add_ps(_mm_add_ps(sy, _mm256_castps256_ps128(wy)), _mm256_extractf128_ps(wy, 1));
        sz = _mm_add_ps(_mm_add_ps(sz, _mm256_castps256_ps128(wz)), _mm256_extractf128_ps(wz, 1));
    }
    const __m128 tx4 = _mm_set1_ps(nt[0]), ty4 = _mm_set1_ps(nt[1]), tz4 = _mm_set1_ps(nt[2]);
    for (; j + 4 <= nbrs.size; j += 4) add_four_normals(sx, sy, sz, tx4, ty4, tz4, normal, nbrs, j, a, cut2);
    alignas(16) float lane[3][4];
    _mm_store_ps(lane[0], sx);
    _mm_store_ps(lane[1], sy);
    _mm_store_ps(lane[2], sz);
    return finish_normal_sum(lane, normal, nt, nbrs, j, a, cut2);
}

/// Whether this CPU (and its OS) runs AVX: sum_normals then takes sum_normals_avx (false
/// in builds without the AVX body).
inline bool cpu_has_avx() {
    static const bool yes = [] {
        __builtin_cpu_init();
        return __builtin_cpu_supports("avx") != 0;
    }();
    return yes;
}
#else
inline bool cpu_has_avx() { return false; }
#endif

/// See NormalSum; `wide`: take the AVX body (cpu_has_avx()).
template <class L>
NormalSum sum_normals(const float* normal, const float* nt, const L& nbrs, float a, float cut2,
                      [[maybe_unused]] bool wide) {
#if defined(KINTSUGI_FBS_AVX)
    if (wide) return sum_normals_avx(normal, nt, nbrs, a, cut2);
#endif
    alignas(16) float lane[3][4] = {};
    std::size_t j = 0;
#if defined(__SSE2__)
    const __m128 tx = _mm_set1_ps(nt[0]), ty = _mm_set1_ps(nt[1]), tz = _mm_set1_ps(nt[2]);
    __m128 sx = _mm_setzero_ps(), sy = _mm_setzero_ps(), sz = _mm_setzero_ps();
    for (; j + 4 <= nbrs.size; j += 4) add_four_normals(sx, sy, sz, tx, ty, tz, normal, nbrs, j, a, cut2);
    _mm_store_ps(lane[0], sx);
    _mm_store_ps(lane[1], sy);
    _mm_store_ps(lane[2], sz);
#endif
    return finish_normal_sum(lane, normal, nt, nbrs, j, a, cut2);
}

/// sum_normals over a stored list (one dispatch on its index width).
inline NormalSum sum_normals(const float* normal, const float* nt, const Neighbourhoods::Span& nbrs, float a,
                             float cut2, bool wide) {
    return nbrs.with_indices([&](auto index) {
        return sum_normals(normal, nt, IndexedList<decltype(index)>{index, nbrs.weight, nbrs.size}, a, cut2, wide);
    });
}

/// Each face's centroid and area as one aligned 4-vector (x, y, z, a): the spatial weights
/// read both for every neighbour, one 32-byte load instead of two scattered ones.
/// 32-byte aligned (over-aligned new), so a row is one aligned AVX load and never straddles a
/// cache line.
struct alignas(32) CentroidAreaRow {
    double v[4];
};
using CentroidArea = std::vector<CentroidAreaRow>;

inline void pack_centroid_area(const FaceGeometry& g, CentroidArea& out) {
    out.resize(g.area.size());
    parallel_for(0, out.size(), [&](std::size_t t) {
        out[t] = {{g.centroid[t].x(), g.centroid[t].y(), g.centroid[t].z(), g.area[t]}};
    }, 4096);
}

/// Filter 3's spatial weights of face t's neighbours q[0..n): w[k] = a_q·f(‖c_q − c_t‖²), the
/// product in double (the centroids are double) and stored as float (`ca`: pack_centroid_area).
/// ‖·‖² is (x² + y²) + z², the order of Eigen's vectorised squaredNorm, which computed it before.
/// Built and kept sets get their weights here alike, so a later run keeping the sets
/// (select_by_risk's perturbed run) computes exactly what the first did.
/// (Neighbours k0..n of the list; `q`: WideIndex or NarrowIndex.)
template <class I>
void spatial_weights_scalar(const CentroidAreaRow* ca, const GaussTable& f, std::size_t t, I q, std::size_t k0,
                            std::size_t n, float* w) {
    const double* c = ca[t].v;
    for (std::size_t k = k0; k < n; ++k) {
        const double* p = ca[q[k]].v;
        const double dx = p[0] - c[0], dy = p[1] - c[1], dz = p[2] - c[2];
        w[k] = static_cast<float>(p[3] * f((dx * dx + dy * dy) + dz * dz));
    }
}

#if defined(KINTSUGI_FBS_AVX)
/// spatial_weights_scalar four neighbours at a time, in its operations and order
/// (GaussTable's interpolation; no FMA), so both give the same bits. The kept sets are
/// reweighed at every face iteration: in scalar code, with centroids and areas in separate
/// arrays, this took about half as long as filter 3's passes (2026-12-07, 590K faces).
template <class I>
__attribute__((target("avx"))) void spatial_weights_avx(const CentroidAreaRow* ca, const GaussTable& f, std::size_t t, I q,
                                                        std::size_t n, float* w) {
    // c_t with a zero area lane: subtracting it leaves each row's area exact.
    const __m256d c = _mm256_blend_pd(_mm256_load_pd(ca[t].v), _mm256_setzero_pd(), 0x8);
    const Scalar* knot = f.knots();
    const __m256d scale = _mm256_set1_pd(f.knot_scale());
    const __m256d top = _mm256_set1_pd(static_cast<Scalar>(GaussTable::intervals()));
    const __m256d at_top = _mm256_set1_pd(knot[GaussTable::intervals()]);
    std::size_t k = 0;
    for (; k + 4 <= n; k += 4) {
        // Rows (x − c_x, y − c_y, z − c_z, a) of the four, transposed into dx, dy, dz, a.
        const __m256d r0 = _mm256_sub_pd(_mm256_load_pd(ca[q[k]].v), c);
        const __m256d r1 = _mm256_sub_pd(_mm256_load_pd(ca[q[k + 1]].v), c);
        const __m256d r2 = _mm256_sub_pd(_mm256_load_pd(ca[q[k + 2]].v), c);
        const __m256d r3 = _mm256_sub_pd(_mm256_load_pd(ca[q[k + 3]].v), c);
        const __m256d t0 = _mm256_unpacklo_pd(r0, r1), t1 = _mm256_unpackhi_pd(r0, r1);  // x0 x1 z0 z1, y0 y1 a0 a1
        const __m256d t2 = _mm256_unpacklo_pd(r2, r3), t3 = _mm256_unpackhi_pd(r2, r3);
        const __m256d dx = _mm256_permute2f128_pd(t0, t2, 0x20), dz = _mm256_permute2f128_pd(t0, t2, 0x31);
        const __m256d dy = _mm256_permute2f128_pd(t1, t3, 0x20), area = _mm256_permute2f128_pd(t1, t3, 0x31);
        const __m256d d2 =
            _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)), _mm256_mul_pd(dz, dz));
        // GaussTable::operator(): u below the last knot interpolates; u at it gives its value;
        // beyond it (or NaN) 0. Lanes not below take knot 0, their result masked off.
        const __m256d u = _mm256_mul_pd(d2, scale);
        const __m256d below = _mm256_cmp_pd(u, top, _CMP_LT_OQ);
        const __m256d ub = _mm256_and_pd(u, below);
        const __m128i ki = _mm256_cvttpd_epi32(ub);
        const __m256d frac = _mm256_sub_pd(ub, _mm256_cvtepi32_pd(ki));
        alignas(16) std::int32_t i[4];
        _mm_store_si128(reinterpret_cast<__m128i*>(i), ki);
        const __m256d lo = _mm256_set_pd(knot[i[3]], knot[i[2]], knot[i[1]], knot[i[0]]);
        const __m256d hi = _mm256_set_pd(knot[i[3] + 1], knot[i[2] + 1], knot[i[1] + 1], knot[i[0] + 1]);
        const __m256d inside = _mm256_add_pd(lo, _mm256_mul_pd(frac, _mm256_sub_pd(hi, lo)));
        const __m256d edge = _mm256_and_pd(at_top, _mm256_cmp_pd(u, top, _CMP_EQ_OQ));
        const __m256d fw = _mm256_blendv_pd(edge, inside, below);
        _mm_storeu_ps(w + k, _mm256_cvtpd_ps(_mm256_mul_pd(area, fw)));
    }
    spatial_weights_scalar(ca, f, t, q, k, n, w);
}
#endif

/// See spatial_weights_scalar; `wide`: take the AVX body (cpu_has_avx()).
template <class I>
void spatial_weights(const CentroidAreaRow* ca, const GaussTable& f, std::size_t t, I q, std::size_t n, float* w,
                     [[maybe_unused]] bool wide) {
#if defined(KINTSUGI_FBS_AVX)
    if (wide) return spatial_weights_avx(ca, f, t, q, n, w);
#endif
    spatial_weights_scalar(ca, f, t, q, 0, n, w);
}

/// Filter 3) (face normals): r = t, q = t* with centroid in the cube of half side
/// `scale` (= σ_f = c|e|) around c_t; I = n_t*, w = a_t*, f(‖c_t − c_t*‖, scale/2),
/// g(‖n_t − n_t*‖, σ) with g = 0 when the normals differ by more than the cut (`kernel`; by
/// default σ 0.6, cut 1: 60°).
/// Applied `iterations` times to `normals` with the positions fixed: the cube
/// neighbourhoods and their spatial weights a_t*·f are found once (two grid
/// passes, CSR arrays linear in the mesh) and reused by every pass.
inline std::vector<Vec3> filter_normals(const FaceGeometry& g, const UniformGrid& grid, std::vector<Vec3> normals,
                                        Scalar scale, std::size_t iterations, Progress& progress, double from,
                                        double to, const Barriers* barriers = nullptr,
                                        const std::vector<unsigned char>* near = nullptr,
                                        Neighbourhoods* lists = nullptr, bool keep_sets = false,
                                        const RangeKernel& kernel = {}) {
    const std::size_t nf = normals.size();
    if (iterations == 0 || nf == 0) return normals;
    const Scalar s_mf = scale / 2, s_mg = kernel.sigma, h = scale;
    const double q2 = from + (to - from) * 0.3;
    Neighbourhoods local;
    Neighbourhoods& nb = lists ? *lists : local;
    const GaussTable spatial(s_mf, 3 * h * h);
    const bool wide = cpu_has_avx();
    const bool reweigh = keep_sets && lists && nb.items == nf && nb.scale == h;
    CentroidArea ca;
    pack_centroid_area(g, ca);
    // Kept sets get their weights from the positions now, each face's just before the first
    // pass reads them (its list is then in cache: the lists are streamed once less than with
    // a pass of their own, 50 ms of each such call at 590K faces).
    if (!reweigh) build_neighbourhoods(nf, nb, progress, from, q2, [&, cap = max_listed(nf)](std::size_t t, auto&& append) {
        if (g.area[t] == 0) return;
        thread_local std::vector<std::uint32_t> found;
        thread_local std::vector<Scalar> dist2;
        thread_local std::vector<float> weight;
        grid.gather(g.centroid[t], h, found, dist2, cap);
        std::size_t n = found.size();
        weight.resize(n);
        if (barriers && (*near)[t]) {  // keep the faces reached without crossing a sharp edge
            const Index seed[1] = {t};
            const Reach reached = reach_faces(*barriers, g.centroid, seed, g.centroid[t], h);
            n = 0;
            for (std::size_t k = 0; k < found.size(); ++k)
                if (reached(found[k])) found[n++] = found[k];
        }
        spatial_weights(ca.data(), spatial, t, WideIndex{found.data()}, n, weight.data(), wide);
        append(found.data(), weight.data(), n);
    });
    nb.items = nf;
    nb.scale = h;
    // g(Y) = exp(−Y²/(2σ_mg²)), 0 for Y > cut, evaluated by range_weight (above).
    const float a_mg = static_cast<float>(1 / (2 * s_mg * s_mg));
    const float cut2 = static_cast<float>(kernel.cut * kernel.cut);
    // The passes run in single precision (normals as padded float4: half the memory
    // traffic of the random neighbour reads); the result is renormalised in double.
    using N4 = Eigen::Vector4f;
    std::vector<N4, Eigen::aligned_allocator<N4>> cur(nf), nxt(nf);
    parallel_for(0, nf, [&](std::size_t t) { cur[t] = N4(float(normals[t].x()), float(normals[t].y()), float(normals[t].z()), 0.f); }, 4096);
    for (std::size_t k = 0; k < iterations; ++k) {
        const double a0 = q2 + (to - q2) * static_cast<double>(k) / static_cast<double>(iterations);
        const double a1 = q2 + (to - q2) * static_cast<double>(k + 1) / static_cast<double>(iterations);
        blocked_for(progress, nf, a0, a1, [&](std::size_t t) {
            const Neighbourhoods::Span list = nb.of(t);
            if (reweigh && k == 0) {  // the list's weights, written through its (mutable) part
                Neighbourhoods::Part& part = nb.parts[t / Neighbourhoods::chunk];
                float* w = part.weight.data() + part.offset[t % Neighbourhoods::chunk];
                list.with_indices([&](auto index) { spatial_weights(ca.data(), spatial, t, index, list.size, w, wide); });
            }
            const N4 nt = cur[t];
            const NormalSum sum = sum_normals(cur[0].data(), nt.data(), list, a_mg, cut2, wide);
            const N4 acc(sum.x, sum.y, sum.z, 0.f);
            const float n = acc.norm();
            nxt[t] = n > 0 && std::isfinite(n) ? N4(acc / n) : nt;
        });
        cur.swap(nxt);
    }
    parallel_for(0, nf, [&](std::size_t t) {
        const Vec3 n(cur[t].x(), cur[t].y(), cur[t].z());
        const Scalar len = n.norm();
        if (len > 0) normals[t] = n / len;
    }, 4096);
    return normals;
}

// ------------------------------------------------------------------ features

struct FeatureData {
    std::vector<Scalar> strength;              // s_i
    std::vector<Vec3> eigenvalues;             // (v1, v2, v3), v1 >= v2 >= v3, sum 1
    std::vector<std::array<Vec3, 3>> eigenvectors;  // e1, e2, e3
    std::vector<std::array<Index, 2>> sharp_edges;  // vertex pairs, a < b, sorted
    std::size_t candidate_vertices = 0;
    std::size_t anchored_faces = 0;          // coplanar_creases.hpp
    std::size_t coplanar_sharp_edges = 0;
    std::size_t straight_sharp_edges = 0;      // added by the straight-crease detection
};

/// The cosine of the crease angle an edge-strength threshold implies: s = tan²(φ/2) for a
/// symmetric edge, so φ = 2·atan(√s) (the crease test here and the coplanar-crease stage).
inline Scalar crease_cosine(Scalar edge_threshold) { return std::cos(2 * std::atan(std::sqrt(edge_threshold))); }

/// Normal voting tensor of every vertex (Sun et al. 2002), its eigen-analysis, the
/// edge strength s_i = v2 / v1 and the sharp edges. With `edges_only` the tensor is computed
/// only at the vertices of edges that pass the other tests (the crease test), which are all
/// the sharp edges need: the same sharp edges, the per-vertex arrays filled only there (the
/// straight-crease detection, which uses its edges alone).
inline FeatureData detect_features(const std::vector<Vec3>& V, const std::vector<Face>& /*F*/, const MeshTopology& topo,
                                   const FaceGeometry& geo, Scalar mean_edge, const SharpFeatureParams& st,
                                   Progress& progress, double from, double to, Workspace& ws,
                                   bool keep_sets = false, const RangeKernel& kernel = {}, bool edges_only = false) {
    const std::size_t nv = V.size();
    FeatureData out;
    out.strength.assign(nv, 0);
    out.eigenvalues.assign(nv, Vec3::Zero());
    out.eigenvectors.assign(nv, {Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()});

    const Scalar h = st.voting_cube * mean_edge / 2;  // half side of the voting cube
    const Scalar falloff = h;                  // distance decay of the votes (see header)
    UniformGrid& grid = ws.grid;
    grid.build(geo.centroid, std::max(h, st.prefilter_scale * mean_edge), has_area(geo.area));
    const double mid = from + (to - from) * (st.prefilter_iterations ? 0.5 : 0.0);
    const std::vector<Vec3> N = st.prefilter_iterations
        ? filter_normals(geo, grid, geo.normal, st.prefilter_scale * mean_edge, st.prefilter_iterations, progress, from, mid,
                         nullptr, nullptr, &ws.lists, keep_sets, kernel)
        : geo.normal;
    const auto& A = geo.area;
    // Edges that pass every test but the strength at their vertices (and, without the crease
    // test, the direction test): a sharp edge needs one of its vertices to pass that too.
    const auto& E = topo.edges();
    std::vector<unsigned char> passes(E.size(), 0);
    const Scalar crease_cos = crease_cosine(st.edge_threshold);
    parallel_for(0, E.size(), [&](std::size_t e) {
        const Index a = E[e][0], b = E[e][1];
        if (a == b) return;
        const auto ef = topo.edge_faces(e);
        if (!st.boundary_edges_sharp && ef.size() < 2) return;
        if (st.crease_test && ef.size() >= 2) {
            // Every pair of the edge's faces; for a non-manifold edge with more than 64
            // faces, the pairs with one of its first 64 (bounded cost).
            Scalar min_dot = 1;
            for (std::size_t i = 0; i < std::min<std::size_t>(ef.size(), 64); ++i)
                for (std::size_t j = i + 1; j < ef.size(); ++j) min_dot = std::min(min_dot, N[ef[i]].dot(N[ef[j]]));
            if (min_dot > crease_cos) return;
        }
        if (!((V[b] - V[a]).norm() > 0)) return;
        passes[e] = 1;
    }, 4096);
    std::vector<unsigned char> wanted;
    if (edges_only) {
        wanted.assign(nv, 0);
        for (std::size_t e = 0; e < E.size(); ++e)
            if (passes[e]) wanted[E[e][0]] = wanted[E[e][1]] = 1;
    }
    blocked_for(progress, nv, mid, mid + 0.9 * (to - mid), [&](std::size_t v) {
        if (edges_only && !wanted[v]) return;
        thread_local std::vector<std::uint32_t> found;
        thread_local std::vector<Scalar> dist2;
        grid.gather(V[v], h, found, dist2, max_candidates);
        Scalar xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;  // local sums (see filter_normals)
        for (std::size_t k = 0; k < found.size(); ++k) {
            const Vec3& n = N[found[k]];
            const Scalar w = A[found[k]] * std::exp(-std::sqrt(dist2[k]) / falloff);
            xx += w * n.x() * n.x();
            xy += w * n.x() * n.y();
            xz += w * n.x() * n.z();
            yy += w * n.y() * n.y();
            yz += w * n.y() * n.z();
            zz += w * n.z() * n.z();
        }
        Eigen::Matrix3d T;
        T << xx, xy, xz, xy, yy, yz, xz, yz, zz;
        const Scalar tr = T.trace();
        if (!(tr > 0) || !std::isfinite(tr)) return;  // no face around: not a feature
        T /= tr;
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
        es.computeDirect(T);
        const Vec3 ev = es.eigenvalues();  // increasing
        const Scalar v1 = std::max(ev[2], Scalar(0)), v2 = std::clamp(ev[1], Scalar(0), v1),
                     v3 = std::clamp(ev[0], Scalar(0), v2);
        out.eigenvalues[v] = Vec3(v1, v2, v3);
        out.eigenvectors[v] = {Vec3(es.eigenvectors().col(2)), Vec3(es.eigenvectors().col(1)),
                               Vec3(es.eigenvectors().col(0))};
        out.strength[v] = v1 > 0 ? v2 / v1 : Scalar(0);
    });

    // Sharp edges: an edge at a candidate vertex (s >= threshold) whose direction is
    // aligned with that vertex's e3 (the crease direction).
    std::vector<unsigned char> sharp(E.size(), 0);
    parallel_for(0, E.size(), [&](std::size_t e) {
        if (!passes[e]) return;
        const Index a = E[e][0], b = E[e][1];
        Vec3 d = V[b] - V[a];
        d /= d.norm();
        for (Index v : {a, b})
            if (out.strength[v] >= st.edge_threshold &&
                (st.crease_test || std::abs(d.dot(out.eigenvectors[v][2])) >= st.direction_threshold)) {
                sharp[e] = 1;
                return;
            }
    }, 4096);
    for (std::size_t v = 0; v < nv; ++v) out.candidate_vertices += out.strength[v] >= st.edge_threshold;
    for (std::size_t e = 0; e < E.size(); ++e)
        if (sharp[e]) out.sharp_edges.push_back(E[e]);
    progress.update(to);
    return out;
}

// ------------------------------------------------------------------ filters

struct FilterSettings {
    Scalar a = 2, b = 0.1, c = 2, d = 0.1;
    std::size_t edge_iterations = 2, face_iterations = 2;
    bool features = true;
    std::size_t normal_iterations = 1;
    std::size_t vertex_iterations = 1;
    Scalar vertex_c = 0;  // spatial scale of filter 4 when not c (0: c)
    RangeKernel kernel{};  // filter 3's range kernel
};

/// Filters 1) and 2): sharp-edge directions, then sharp-edge vertices. Moves only the
/// vertices of sharp edges. One call = one iteration.
inline void edge_iteration(std::vector<Vec3>& V, const std::vector<std::array<Index, 2>>& edges,
                           const std::vector<Index>& edge_vertices, Scalar L, const FilterSettings& st,
                           Progress& progress, double from, double to) {
    const std::size_t ne = edges.size();
    if (ne == 0) return;
    std::vector<Vec3> c(ne), dir(ne), dir_f(ne);
    std::vector<Scalar> len(ne);
    for (std::size_t e = 0; e < ne; ++e) {
        const Vec3 p = V[edges[e][0]], q = V[edges[e][1]];
        c[e] = (p + q) / 2;
        len[e] = (q - p).norm();
        dir[e] = len[e] > 0 ? Vec3((q - p) / len[e]) : Vec3::Zero();
    }
    const UniformGrid grid(c, st.a * L / 2, has_area(len));
    const Scalar s_mef = st.a * L / 2, s_meg = 0.6, s_ef = st.a * L, s_eg = st.b * L;
    const Scalar h = s_mef;  // the edge cube has side 2σ_mef
    const double mid = from + (to - from) / 2;

    // 1) directions: r = e, q = e*, I = d_e* (sign-aligned with d_e), w = l_e*.
    blocked_for(progress, ne, from, mid, [&](std::size_t e) {
        dir_f[e] = dir[e];
        if (len[e] == 0) return;
        Vec3 acc = Vec3::Zero();
        grid.for_each_in_cube(c[e], h, [&](Index q, Scalar d2) {
            const Vec3 dq = dir[e].dot(dir[q]) < 0 ? Vec3(-dir[q]) : dir[q];
            const Scalar Y2 = (dir[e] - dq).squaredNorm();
            if (Y2 > 1) return;  // another feature branch (corner): g = 0
            acc += len[q] * gauss(d2, s_mef) * gauss(Y2, s_meg) * dq;
        }, max_candidates);
        const Scalar n = acc.norm();
        if (n > 0 && std::isfinite(n)) dir_f[e] = acc / n;
    });

    // 2) vertices: r = i, q = e*, I = Π_e* (projection of p_i on the filtered line of e*), w = l_e*.
    std::vector<Vec3> out(edge_vertices.size());
    blocked_for(progress, edge_vertices.size(), mid, to, [&](std::size_t k) {
        const Vec3& p = V[edge_vertices[k]];
        out[k] = p;
        Vec3 acc = Vec3::Zero();
        Scalar kr = 0;
        grid.for_each_in_cube(p, h, [&](Index q, Scalar d2) {
            const Vec3& dq = dir_f[q];
            const Vec3 proj = c[q] + (p - c[q]).dot(dq) * dq;
            const Scalar w = len[q] * gauss(d2, s_ef) * gauss((proj - p).squaredNorm(), s_eg);
            acc += w * proj;
            kr += w;
        }, max_candidates);
        if (kr > 0 && std::isfinite(kr)) out[k] = acc / kr;
    });
    for (std::size_t k = 0; k < edge_vertices.size(); ++k) V[edge_vertices[k]] = out[k];
}

/// Filters 3) and 4): face normals, then vertices (all vertices, or those not on a
/// sharp edge when `fixed` marks them). One call = one iteration. With `keep_sets`
/// (iterations after the first of a stage, and every iteration of select_by_risk's perturbed
/// run) filter 3 keeps the neighbour sets in `ws` (those of the stage's first iteration) when
/// they are of the same faces and scale (see "Neighbour sets per stage" in
/// docs/methods/feature_bilateral.md);
/// with `keep_vertex_sets` as well, filter 4 keeps the sets in `ws` (when of the same vertices
/// and scale) and nothing is gathered.
inline void face_iteration(std::vector<Vec3>& V, const std::vector<Face>& F, const std::vector<unsigned char>& fixed,
                           const std::vector<unsigned char>& has_face, Scalar L, const FilterSettings& st,
                           Progress& progress, double from, double to, Workspace& ws,
                           const Barriers* barriers = nullptr, bool keep_sets = false,
                           bool keep_vertex_sets = false) {
    FaceGeometry& g = ws.geometry;
    compute_face_geometry(V, F, g);
    const std::size_t nv = V.size();
    const Scalar s_f = (st.vertex_c > 0 ? st.vertex_c : st.c) * L, s_g = st.d * L;
    const Scalar h = s_f;  // the face cube has side 2σ_f
    keep_sets = keep_sets && ws.lists.items == F.size() && ws.lists.scale == st.c * L;
    keep_vertex_sets = keep_vertex_sets && ws.vertex_lists.items == nv && ws.vertex_lists.scale == h;
    const bool filter3_gathers = !keep_sets && st.normal_iterations > 0;
    UniformGrid& grid = ws.grid;
    if (filter3_gathers || !keep_vertex_sets) grid.build(g.centroid, st.c * L, has_area(g.area));
    // Faces and vertices whose cube may hold a sharp-edge vertex walk over the faces (only
    // when gathering: kept sets already left out what is behind a sharp edge).
    std::vector<unsigned char> near_face, near_vertex;
    if (barriers && (!barriers->active() || (!filter3_gathers && keep_vertex_sets))) barriers = nullptr;
    if (barriers) {
        const Scalar reach = st.c * L + 2 * L;
        std::vector<Vec3> points(barriers->feature_vertices.size());
        for (std::size_t k = 0; k < points.size(); ++k) points[k] = V[barriers->feature_vertices[k]];
        const UniformGrid fp(points, reach);
        near_face.assign(F.size(), 0);
        near_vertex.assign(nv, 0);
        parallel_for(0, F.size(), [&](std::size_t t) {
            bool any = false;
            fp.for_each_in_cube(g.centroid[t], reach, [&](Index, Scalar) { any = true; }, max_candidates);
            near_face[t] = any;
        }, 1024);
        for (std::size_t t = 0; t < F.size(); ++t)
            if (near_face[t])
                for (Index v : F[t]) near_vertex[v] = 1;
    }
    // f over the whole cube (0 beyond); g tabulated to 8σ_g (beyond, e^-32 < 1e-13: 0).
    const GaussTable spatial(s_f, 3 * h * h), range(s_g, 64 * s_g * s_g);
    const double mid = from + (to - from) / 2;

    // 3) normals, normal_iterations times.
    std::vector<Vec3> nf_ = filter_normals(g, grid, g.normal, st.c * L, st.normal_iterations, progress, from, mid,
                                           barriers, &near_face, &ws.lists, keep_sets, st.kernel);

    // 4) vertices: r = i, q = t* (same cube, around p_i); I = Π_t, w = a_t*. Repeated
    // vertex_iterations times with the filtered normals n'_t, the centroids following
    // the moved vertices. The faces around each vertex are gathered once per
    // iteration, before its first pass (through the grid of filter 3: with its larger
    // cells the gather tests more points, which costs less than a grid of its own);
    // later passes keep them; the pre-smoothing (`keep_vertex_sets`) keeps them for
    // the whole stage, as filter 3 does, and then builds no grid after its first
    // iteration; select_by_risk's perturbed run takes those of the first run's same
    // iteration. Keeping them for the whole face-smoothing stage too was 15 % faster
    // but moved Twelve0.5Impulsive from 7.99° to 8.10°.
    Neighbourhoods& around = ws.vertex_lists;
    if (!keep_vertex_sets) {
        build_neighbourhoods(nv, around, progress, mid, mid, [&, cap = max_listed(nv)](std::size_t i, auto&& append) {
            if (fixed[i] || !has_face[i]) return;
            thread_local std::vector<std::uint32_t> found;
            thread_local std::vector<Scalar> dist2;
            grid.gather(V[i], h, found, dist2, cap);
            std::size_t n = found.size();
            if (barriers && near_vertex[i]) {  // keep the faces reached without crossing a sharp edge
                const Reach reached = reach_faces(*barriers, g.centroid, barriers->topo->vertex_faces(i), V[i], h);
                n = 0;
                for (std::size_t k = 0; k < found.size(); ++k)
                    if (reached(found[k])) found[n++] = found[k];
            }
            append(found.data(), nullptr, n);
        });
        around.items = nv;
        around.scale = h;
    }
    std::vector<Vec3> out(nv);
    const std::size_t vit = std::max<std::size_t>(st.vertex_iterations, 1);
    for (std::size_t k = 0; k < vit; ++k) {
        if (k > 0) compute_face_geometry(V, F, g);
        blocked_for(progress, nv, mid + (to - mid) * static_cast<double>(k) / static_cast<double>(vit),
                    mid + (to - mid) * static_cast<double>(k + 1) / static_cast<double>(vit), [&](std::size_t i) {
            const Vec3& p = V[i];
            out[i] = p;
            if (fixed[i] || !has_face[i]) return;
            // Plain loop, local accumulators (kept in registers; see filter_normals).
            Scalar ax = 0, ay = 0, az = 0, kr = 0;
            const Neighbourhoods::Span nbrs = around.of(i);
            for (std::size_t j = 0; j < nbrs.size; ++j) {
                const std::uint32_t q = nbrs.at(j);
                const Vec3& n = nf_[q];
                const Vec3 d = p - g.centroid[q];
                const Scalar off = d.dot(n);
                const Vec3 proj = p - off * n;
                const Scalar w = g.area[q] * spatial(d.squaredNorm()) * range(off * off);  // f·g
                ax += w * proj.x();
                ay += w * proj.y();
                az += w * proj.z();
                kr += w;
            }
            if (kr > 0 && std::isfinite(kr)) out[i] = Vec3(ax, ay, az) / kr;
        });
        V.swap(out);
    }
}

}  // namespace kintsugi::detail::fbs

namespace kintsugi::detail::fbs {

/// The straight-crease detection (SharpFeatureParams::straight_creases): a second detection
/// whose pre-smoothing and prefilter use a narrow range kernel, so that they do not average
/// across a crease of 53-65° once noise tilts the normals (the default kernel admits normals
/// 60° apart); its edges are kept only on straight runs whose two sides are distinct planes,
/// which the noise-made creases of a curved surface are not (they zigzag across the mesh, or
/// their sides bend by less than a face's width). Set on the noise tables' CAD shapes (the
/// Block, SharpSphere, Twelve), checked on the curved ones and on 13 held-out shapes
/// (docs/methods/feature_bilateral.md, "Straight creases").
struct StraightCreaseConstants {
    /// Filter 3's range kernel in that detection (σ, cut; the default's 0.6, 1).
    static constexpr Scalar kernel_sigma = 0.3, kernel_cut = 0.85;
    /// Two edges at a vertex continue each other when they turn by at most 30°.
    static constexpr Scalar turn_cos = 0.8660254037844386;
    /// A run (edges linked by such continuations) is kept from 8 edges ...
    static constexpr std::size_t min_run = 8;
    /// ... when the input's summed face area vectors on its two sides are at least 45° apart
    /// (a prism's 30° sides are not creases to add; Twelve's 63° ones are).
    static constexpr Scalar side_cos = 0.7071067811865476;
    /// Edges per vertex whose pairs are tested (bounded cost at a high-valence vertex).
    static constexpr std::size_t max_edges_at_vertex = 8;
};

/// The edges of `edges` (vertex pairs, a < b, sorted) on straight two-sided runs
/// (StraightCreaseConstants): continuations tested on `W` (the detection's pre-smoothed
/// positions), sides on the input `V`. Deterministic (sequential, in edge order); linear in the
/// edges. Returns a sorted subset of `edges`.
inline std::vector<std::array<Index, 2>> straight_two_sided_runs(const std::vector<std::array<Index, 2>>& edges,
                                                                 const std::vector<Vec3>& V, const std::vector<Vec3>& W,
                                                                 const std::vector<Face>& F, const MeshTopology& topo) {
    using K = StraightCreaseConstants;
    constexpr Index none = std::numeric_limits<Index>::max();
    const std::size_t ne = edges.size();
    std::vector<std::pair<Index, Index>> at;  // (vertex, edge id)
    at.reserve(2 * ne);
    for (std::size_t i = 0; i < ne; ++i) {
        at.emplace_back(edges[i][0], static_cast<Index>(i));
        at.emplace_back(edges[i][1], static_cast<Index>(i));
    }
    std::sort(at.begin(), at.end());
    auto other = [&](Index e, Index v) { return edges[e][0] == v ? edges[e][1] : edges[e][0]; };
    // Links: edges i and j continue each other through vertex v.
    struct Link {
        Index i, j, v;
    };
    std::vector<Link> links;
    DisjointSets<Index> runs(ne);
    for (std::size_t b = 0; b < at.size();) {
        std::size_t e = b;
        while (e < at.size() && at[e].first == at[b].first) ++e;
        const Index v = at[b].first;
        const std::size_t end = std::min(e, b + K::max_edges_at_vertex);
        for (std::size_t x = b; x < end; ++x)
            for (std::size_t y = x + 1; y < end; ++y) {
                const Index i = at[x].second, j = at[y].second;
                const Vec3 ui = W[other(i, v)] - W[v], uj = W[other(j, v)] - W[v];
                const Scalar li = ui.norm(), lj = uj.norm();
                if (li > 0 && lj > 0 && ui.dot(uj) <= -K::turn_cos * li * lj) {
                    links.push_back({i, j, v});
                    runs.unite(i, j);
                }
            }
        b = e;
    }
    std::vector<std::size_t> size(ne, 0);
    for (std::size_t i = 0; i < ne; ++i) ++size[runs.find(static_cast<Index>(i))];
    // The edges of long runs, each oriented along its run (breadth-first over the links from
    // the run's first edge), so that its two sides are told apart consistently along a curved run.
    std::vector<Index> slot(ne, none);
    std::size_t slots = 0;
    for (std::size_t i = 0; i < ne; ++i)
        if (size[runs.find(static_cast<Index>(i))] >= K::min_run) slot[i] = static_cast<Index>(slots++);
    std::vector<std::vector<std::pair<Index, Index>>> adj(slots);  // (linked edge, through vertex)
    for (const Link& l : links)
        if (slot[l.i] != none) {
            adj[slot[l.i]].emplace_back(l.j, l.v);
            adj[slot[l.j]].emplace_back(l.i, l.v);
        }
    std::vector<signed char> to(ne, -1);  // the end of edge i along its run: edges[i][to[i]]
    std::vector<Index> queue;
    for (std::size_t s = 0; s < ne; ++s) {
        if (slot[s] == none || to[s] >= 0) continue;
        to[s] = 1;
        queue.assign(1, static_cast<Index>(s));
        for (std::size_t q = 0; q < queue.size(); ++q) {
            const Index i = queue[q];
            for (const auto& [j, v] : adj[slot[i]]) {
                if (to[j] >= 0) continue;
                // j continues i through v: it leaves v where i arrives at v, and the reverse.
                const bool i_arrives = edges[i][static_cast<std::size_t>(to[i])] == v;
                const bool j_starts_at_v = edges[j][0] == v;
                to[j] = static_cast<signed char>(i_arrives == j_starts_at_v ? 1 : 0);
                queue.push_back(j);
            }
        }
    }
    std::vector<Vec3> side_a(ne, Vec3::Zero()), side_b(ne, Vec3::Zero());  // by run (its root)
    auto area = [&](Index f) {
        const Face& t = F[f];
        return Vec3((V[t[1]] - V[t[0]]).cross(V[t[2]] - V[t[0]]));
    };
    for (std::size_t i = 0; i < ne; ++i) {
        if (slot[i] == none) continue;
        const Index b = edges[i][static_cast<std::size_t>(to[i])], a = edges[i][1 - static_cast<std::size_t>(to[i])];
        const std::optional<Index> e = topo.find_edge(a, b);
        if (!e || topo.edge_faces(*e).size() != 2) continue;  // a border or non-manifold edge: no two sides
        const Index f0 = topo.edge_faces(*e)[0], f1 = topo.edge_faces(*e)[1];
        const Vec3 n0 = area(f0), n1 = area(f1);
        const Scalar l0 = n0.norm(), l1 = n1.norm();
        if (!(l0 > 0) || !(l1 > 0)) continue;
        const Vec3 side = (V[b] - V[a]).cross(n0 / l0 + n1 / l1), mid = (V[a] + V[b]) / 2;
        const Index r = runs.find(static_cast<Index>(i));
        for (Index f : {f0, f1}) {
            const Face& t = F[f];
            const Vec3 c = (V[t[0]] + V[t[1]] + V[t[2]]) / 3;
            ((c - mid).dot(side) >= 0 ? side_a[r] : side_b[r]) += area(f);
        }
    }
    std::vector<std::array<Index, 2>> kept;
    for (std::size_t i = 0; i < ne; ++i) {
        if (slot[i] == none) continue;
        const Index r = runs.find(static_cast<Index>(i));
        const Scalar la = side_a[r].norm(), lb = side_b[r].norm();
        if (la > 0 && lb > 0 && side_a[r].dot(side_b[r]) <= K::side_cos * la * lb) kept.push_back(edges[i]);
    }
    return kept;
}

/// Feature detection, optionally on a pre-smoothed copy: `presmooth` passes of
/// filters 3–4 on every vertex (settings `fs`) before voting, so that the voting sees
/// the creases rather than the noise. Connectivity is shared, so the sharp edges found
/// on the copy are the input's edges. With SharpFeatureParams::straight_creases the
/// straight-crease detection (StraightCreaseConstants) runs after it on the same neighbour
/// sets, and the edges it keeps join the sharp edges (`straight_sharp_edges` counts those added).
inline FeatureData detect_features_presmoothed(const std::vector<Vec3>& V, const std::vector<Face>& F,
                                               const MeshTopology& topo, Scalar L, const SharpFeatureParams& st,
                                               const FilterSettings& fs, std::size_t presmooth,
                                               const std::vector<unsigned char>& has_face, Progress& progress,
                                               Workspace& ws) {
    const double span = st.straight_creases ? 0.5 : 1.0;  // of the progress, per detection
    // One detection with `settings` from progress `from`; `reuse` (the second detection):
    // every pass keeps the neighbour sets the first detection gathered on the same input (same
    // cubes), and only the sharp edges are computed (detect_features' `edges_only`).
    auto detect = [&](const FilterSettings& settings, bool reuse, double from, std::vector<Vec3>& W) {
        W = V;
        if (presmooth > 0) {
            const std::vector<unsigned char> none(V.size(), 0);
            for (std::size_t it = 0; it < presmooth; ++it)
                face_iteration(W, F, none, has_face, L, settings, progress,
                               from + span * 0.5 * static_cast<double>(it) / static_cast<double>(presmooth),
                               from + span * 0.5 * static_cast<double>(it + 1) / static_cast<double>(presmooth), ws,
                               nullptr, reuse || it > 0, reuse || it > 0);
        }
        FaceGeometry geo;
        compute_face_geometry(W, F, geo);
        // The prefilter keeps the pre-smoothing's neighbour sets when it has the same cube.
        return detect_features(W, F, topo, geo, L, st, progress, from + (presmooth > 0 ? span * 0.5 : 0.0), from + span,
                               ws, presmooth > 0 || reuse, settings.kernel, /*edges_only=*/reuse);
    };
    std::vector<Vec3> W;
    FeatureData fd = detect(fs, false, 0.0, W);
    if (!st.straight_creases) return fd;
    FilterSettings narrow = fs;
    narrow.kernel = {StraightCreaseConstants::kernel_sigma, StraightCreaseConstants::kernel_cut};
    const FeatureData second = detect(narrow, true, 0.5, W);
    const std::vector<std::array<Index, 2>> kept = straight_two_sided_runs(second.sharp_edges, V, W, F, topo);
    std::vector<std::array<Index, 2>> merged;
    merged.reserve(fd.sharp_edges.size() + kept.size());
    std::set_union(fd.sharp_edges.begin(), fd.sharp_edges.end(), kept.begin(), kept.end(), std::back_inserter(merged));
    fd.straight_sharp_edges = merged.size() - fd.sharp_edges.size();
    fd.sharp_edges = std::move(merged);
    return fd;
}

}  // namespace kintsugi::detail::fbs
