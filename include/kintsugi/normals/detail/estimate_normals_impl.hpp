// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file estimate_normals_impl.hpp
/// @brief Internal: k-nearest-neighbour table, PCA and jet normal fitting,
/// minimum-spanning-tree orientation. Works on the internal layout only
/// (std::vector<Vec3>); nothing here is templated on the user's container.
///
/// Dependencies: Eigen, Boost.Graph, nanoflann (through KdTree); no GPL code.

#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/control.hpp>
#include <kintsugi/core/disjoint_sets.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/parallel.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/spatial/jet_fit.hpp>
#include <kintsugi/spatial/kd_tree.hpp>

#include <boost/graph/compressed_sparse_row_graph.hpp>
#include <boost/graph/prim_minimum_spanning_tree.hpp>
#include <boost/property_map/property_map.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi::detail::normals {

using NodeIndex = std::uint32_t;

/// Row-major n × k table of neighbour indices: row i holds the k nearest points
/// of point i (itself first), by increasing distance, ties by index. (k here is
/// the row length: the public k plus one.)
struct KnnTable {
    std::size_t k = 0;
    std::vector<NodeIndex> index;
    [[nodiscard]] const NodeIndex* row(std::size_t i) const { return index.data() + i * k; }
};

/// Runs body(i) for i in [0, n) in parallel, in fixed blocks; reports progress
/// (and checks for cancellation) on the calling thread between blocks.
template <class Body>
void blocked_for(std::size_t n, Progress& progress, Body&& body) {
    const std::size_t blocks = std::clamp<std::size_t>(n / 4096, 1, 50);
    for (std::size_t b = 0; b < blocks; ++b) {
        parallel_for(n * b / blocks, n * (b + 1) / blocks, body, 64);
        progress.update(static_cast<double>(b + 1) / static_cast<double>(blocks));
    }
}

/// The k nearest indexed points of every query, from any SpatialIndex (queried in
/// parallel: its const queries must be safe to call concurrently, as KdTree's and
/// UniformGrid's are). Throws invalid_input naming `fn` when a row is short or holds an
/// index out of [0, index.size()) (an index not over the queries' points).
/// @pre k <= index.size()
template <SpatialIndex S>
KnnTable knn_table(const S& index, const std::vector<Vec3>& queries, std::size_t k, Progress& progress,
                   const char* fn = "kintsugi::estimate_normals") {
    const std::size_t n = queries.size(), size = index.size();
    KnnTable t;
    t.k = k;
    t.index.resize(n * k);
    blocked_for(n, progress, [&](std::size_t i) {
        thread_local std::vector<Neighbor> nn;
        index.knn(queries[i], k, nn);
        NodeIndex* out = t.index.data() + i * k;
        for (std::size_t j = 0; j < k; ++j)
            out[j] = j < nn.size() && nn[j].index < size ? static_cast<NodeIndex>(nn[j].index)
                                                         : std::numeric_limits<NodeIndex>::max();
    });
    for (std::size_t i = 0; i < n * k; ++i)
        if (t.index[i] == std::numeric_limits<NodeIndex>::max())
            throw invalid_input(std::string(fn) + ": the spatial index gave point " + std::to_string(i / k) +
                                " fewer than " + std::to_string(k) +
                                " neighbours or an index out of range; build it over the same points");
    return t;
}

/// Unit normal of the least-squares plane through the neighbours (smallest
/// eigenvector of their covariance), as CGAL's pca_estimate_normals.
inline Vec3 pca_normal(const std::vector<Vec3>& pts, const NodeIndex* nb, std::size_t k) {
    return kintsugi::detail::pca_frame([&](std::size_t j) -> const Vec3& { return pts[nb[j]]; }, k)
        .col(0)
        .normalized();
}

/// Unit normal of the degree-2 jet (osculating quadric) fitted to the
/// neighbours, origin at the point itself (nb[0]): the library's one jet fit
/// (spatial/jet_fit.hpp, Cazals & Pouget's Monge fitting as in CGAL's
/// Monge_via_jet_fitting, which jet_estimate_normals calls; tests/normals checks it
/// against jet_estimate_normals). Falls back to PCA when the fit is degenerate
/// (e.g. all neighbours at one place). @pre k >= 6 (row length)
inline Vec3 jet_normal(const std::vector<Vec3>& pts, const NodeIndex* nb, std::size_t k) {
    const JetFit j = kintsugi::detail::fit_jet([&](std::size_t i) -> const Vec3& { return pts[nb[i]]; }, k, 2, false);
    return j.valid ? j.normal : pca_normal(pts, nb, k);
}

/// Fits one unit normal per point from the neighbour table (jet when `jet`).
inline std::vector<Vec3> fit_normals(const std::vector<Vec3>& pts, const KnnTable& t, bool jet, Progress& progress) {
    std::vector<Vec3> normals(pts.size());
    blocked_for(pts.size(), progress, [&](std::size_t i) {
        normals[i] = jet ? jet_normal(pts, t.row(i), t.k) : pca_normal(pts, t.row(i), t.k);
    });
    return normals;
}

/// Orients `normals` in place (signs only) by propagation along a minimum
/// spanning tree of the symmetric kNN graph weighted 1 - |ni·nj| (Hoppe et al.
/// 1992, as CGAL's mst_orient_normals), one tree per connected component. Each
/// component's seed is its top-most point (largest z, ties by lowest index),
/// whose normal is turned towards +z: outward for a closed surface.
///
/// The forest is computed in one Boost.Graph Prim run from a virtual root joined
/// to every seed with weight 0 (CGAL's own device for constrained points); the
/// sign is propagated in Prim's visiting order, where a vertex's tree parent is
/// always final before the vertex itself is visited.
/// @return the number of connected components oriented.
inline std::size_t orient_mst(const std::vector<Vec3>& pts, const KnnTable& t, std::vector<Vec3>& normals,
                              Progress& progress) {
    const std::size_t n = pts.size();
    const std::size_t k = t.k;

    // --- symmetric adjacency (i ~ j when either is among the other's k nearest), CSR layout
    std::vector<std::size_t> offset(n + 2, 0);  // vertex n is the virtual root
    for (std::size_t i = 0; i < n; ++i) {
        const NodeIndex* r = t.row(i);
        for (std::size_t j = 0; j < k; ++j)
            if (r[j] != i) {
                ++offset[i + 1];
                ++offset[r[j] + 1];
            }
    }
    for (std::size_t i = 0; i < n; ++i) offset[i + 1] += offset[i];
    std::vector<NodeIndex> adj(offset[n]);
    {
        std::vector<std::size_t> fill(offset.begin(), offset.begin() + static_cast<std::ptrdiff_t>(n));
        for (std::size_t i = 0; i < n; ++i) {
            const NodeIndex* r = t.row(i);
            for (std::size_t j = 0; j < k; ++j)
                if (r[j] != i) {
                    adj[fill[i]++] = r[j];
                    adj[fill[r[j]]++] = static_cast<NodeIndex>(i);
                }
        }
    }
    std::vector<std::size_t> degree(n);
    parallel_for(0, n, [&](std::size_t i) {
        const auto b = adj.begin() + static_cast<std::ptrdiff_t>(offset[i]);
        const auto e = adj.begin() + static_cast<std::ptrdiff_t>(offset[i + 1]);
        std::sort(b, e);
        degree[i] = static_cast<std::size_t>(std::unique(b, e) - b);
    });
    progress.update(0.2);

    // --- connected components and their seeds (top-most point)
    DisjointSets<NodeIndex> sets(n);
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t e = offset[i]; e < offset[i] + degree[i]; ++e)
            if (adj[e] > i) sets.unite(static_cast<NodeIndex>(i), adj[e]);
    std::vector<NodeIndex> seed_of_root(n, std::numeric_limits<NodeIndex>::max());
    for (std::size_t i = 0; i < n; ++i) {
        const NodeIndex r = sets.find(static_cast<NodeIndex>(i));
        NodeIndex& s = seed_of_root[r];
        if (s == std::numeric_limits<NodeIndex>::max() || pts[i].z() > pts[s].z()) s = static_cast<NodeIndex>(i);
    }
    std::vector<NodeIndex> seeds;
    for (std::size_t r = 0; r < n; ++r)
        if (seed_of_root[r] != std::numeric_limits<NodeIndex>::max()) seeds.push_back(seed_of_root[r]);
    std::sort(seeds.begin(), seeds.end());
    progress.update(0.3);

    // --- the graph for Boost: sorted directed edges both ways, plus root -> seeds
    std::vector<std::pair<NodeIndex, NodeIndex>> edges;
    std::vector<double> weight;
    std::size_t m = seeds.size();
    for (std::size_t i = 0; i < n; ++i) m += degree[i];
    edges.reserve(m);
    weight.reserve(m);
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t e = offset[i]; e < offset[i] + degree[i]; ++e) {
            edges.emplace_back(static_cast<NodeIndex>(i), adj[e]);
            weight.push_back(std::max(0.0, 1.0 - std::abs(normals[i].dot(normals[adj[e]]))));
        }
    const auto root = static_cast<NodeIndex>(n);
    for (NodeIndex s : seeds) {
        edges.emplace_back(root, s);
        weight.push_back(0.0);
    }
    adj = {};
    using Graph = boost::compressed_sparse_row_graph<boost::directedS, boost::no_property, boost::no_property,
                                                     boost::no_property, NodeIndex, NodeIndex>;
    const Graph g(boost::edges_are_sorted, edges.begin(), edges.end(), static_cast<NodeIndex>(n + 1));
    edges = {};
    progress.update(0.4);

    // --- Prim from the virtual root; propagate signs as vertices are visited
    struct Visitor : boost::default_dijkstra_visitor {
        const std::vector<NodeIndex>* pred;
        std::vector<Vec3>* normals;
        Progress* progress;
        NodeIndex root;
        std::size_t visited = 0, total = 0;
        void examine_vertex(NodeIndex u, const Graph&) {
            if (u == root) return;
            const NodeIndex p = (*pred)[u];
            Vec3& nu = (*normals)[u];
            if (p == root) {
                if (nu.z() < 0) nu = -nu;
            } else if (nu.dot((*normals)[p]) < 0) {
                nu = -nu;
            }
            if ((++visited & 0x3fff) == 0) progress->update(0.4 + 0.6 * double(visited) / double(total));
        }
    };
    std::vector<NodeIndex> pred(n + 1);
    std::vector<double> dist(n + 1);
    Visitor vis;
    vis.pred = &pred;
    vis.normals = &normals;
    vis.progress = &progress;
    vis.root = root;
    vis.total = n;
    boost::prim_minimum_spanning_tree(
        g, root, boost::make_iterator_property_map(pred.begin(), get(boost::vertex_index, g)),
        boost::make_iterator_property_map(dist.begin(), get(boost::vertex_index, g)),
        boost::make_iterator_property_map(weight.begin(), get(boost::edge_index, g)), get(boost::vertex_index, g),
        vis);
    progress.update(1.0);
    return seeds.size();
}

}  // namespace kintsugi::detail::normals
