// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file st_cut.hpp
/// @brief Generic s-t minimum cut labelling of a graph (Boykov–Kolmogorov max-flow).
///
/// A graph is given as `num_nodes` nodes, undirected or two-way edges with
/// capacities, and per-node capacities to the two terminals (source and sink).
/// `st_min_cut` returns, for each node, the side of the minimum cut it lies on,
/// and the cut value. Boost.Graph's `boykov_kolmogorov_max_flow` runs inside; no
/// Boost type appears in this interface.
///
/// @code
/// kintsugi::StCutGraph g;
/// g.num_nodes = 2;
/// g.edges = {{0, 1}};
/// g.capacities = {1.0};                 // symmetric when reverse_capacities is empty
/// g.source_capacities = {5.0, 0.0};     // node 0 wants to be on the source side
/// g.sink_capacities = {0.0, 5.0};
/// auto cut = kintsugi::st_min_cut(g);   // cut.cut_value == 1, labels {source, sink}
/// @endcode

#include <kintsugi/core/control.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/memory.hpp>
#include <kintsugi/core/types.hpp>

#include <boost/graph/boykov_kolmogorov_max_flow.hpp>
#include <boost/graph/compressed_sparse_row_graph.hpp>
#include <boost/property_map/function_property_map.hpp>
#include <boost/property_map/property_map.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

/// A graph for an s-t minimum cut. Plain aggregate; all vectors are read only.
struct StCutGraph {
    /// Number of non-terminal nodes, numbered 0 .. num_nodes-1.
    std::size_t num_nodes = 0;
    /// Edges between non-terminal nodes (a, b). Self loops are allowed and ignored.
    std::vector<std::array<Index, 2>> edges;
    /// Capacity from edges[i][0] to edges[i][1]; one per edge, finite, >= 0.
    std::vector<Scalar> capacities;
    /// Capacity from edges[i][1] to edges[i][0]; empty means symmetric (= capacities).
    std::vector<Scalar> reverse_capacities;
    /// Capacity source → node; empty means all zero. May be +infinity (hard constraint).
    std::vector<Scalar> source_capacities;
    /// Capacity node → sink; empty means all zero. May be +infinity (hard constraint).
    std::vector<Scalar> sink_capacities;
};

/// Side of the minimum cut a node lies on.
enum class StSide : std::uint8_t {
    source = 0,  ///< reachable from the source in the residual graph
    sink = 1,    ///< everything else
};

/// Parameters of st_min_cut.
struct StCutParams {
    RunControl control{};
};

/// Result of st_min_cut.
struct StCutResult {
    Status status = Status::ok;
    /// One label per node (empty when cancelled).
    std::vector<StSide> labels;
    /// Sum of the capacities of the arcs from the source side to the sink side
    /// (terminal arcs included). +infinity when every cut severs an infinite arc.
    Scalar cut_value = 0;
    /// Nodes and directed arcs of the flow network built (terminals included).
    std::size_t network_nodes = 0;
    std::size_t network_arcs = 0;
    std::vector<StageTiming> timings;

    [[nodiscard]] bool on_source_side(Index node) const { return labels[node] == StSide::source; }
};

namespace detail {

inline void st_cut_check_capacity(Scalar c, const char* what, std::size_t i, bool allow_inf) {
    if (std::isnan(c) || c < 0 || (!allow_inf && std::isinf(c)))
        throw invalid_input(std::string("kintsugi::st_min_cut: ") + what + "[" + std::to_string(i) + "] = " +
                            std::to_string(c) + " is not a " + (allow_inf ? "" : "finite ") +
                            "capacity >= 0; give every capacity as a " + (allow_inf ? "" : "finite ") +
                            "non-negative number");
}

inline void st_cut_validate(const StCutGraph& g) {
    const std::size_t n = g.num_nodes, m = g.edges.size();
    if (g.capacities.size() != m)
        throw invalid_input("kintsugi::st_min_cut: capacities has " + std::to_string(g.capacities.size()) +
                            " entries for " + std::to_string(m) + " edges; give one capacity per edge");
    if (!g.reverse_capacities.empty() && g.reverse_capacities.size() != m)
        throw invalid_input("kintsugi::st_min_cut: reverse_capacities has " +
                            std::to_string(g.reverse_capacities.size()) + " entries for " + std::to_string(m) +
                            " edges; give one per edge or leave it empty for symmetric edges");
    if (!g.source_capacities.empty() && g.source_capacities.size() != n)
        throw invalid_input("kintsugi::st_min_cut: source_capacities has " +
                            std::to_string(g.source_capacities.size()) + " entries for " + std::to_string(n) +
                            " nodes; give one per node or leave it empty");
    if (!g.sink_capacities.empty() && g.sink_capacities.size() != n)
        throw invalid_input("kintsugi::st_min_cut: sink_capacities has " + std::to_string(g.sink_capacities.size()) +
                            " entries for " + std::to_string(n) + " nodes; give one per node or leave it empty");
    for (std::size_t i = 0; i < m; ++i) {
        const auto& e = g.edges[i];
        if (e[0] >= n || e[1] >= n)
            throw invalid_input("kintsugi::st_min_cut: edge " + std::to_string(i) + " (" + std::to_string(e[0]) +
                                ", " + std::to_string(e[1]) + ") refers to a node >= num_nodes = " +
                                std::to_string(n) + "; node indices must be in [0, num_nodes)");
        st_cut_check_capacity(g.capacities[i], "capacities", i, false);
        if (!g.reverse_capacities.empty()) st_cut_check_capacity(g.reverse_capacities[i], "reverse_capacities", i, false);
    }
    for (std::size_t i = 0; i < g.source_capacities.size(); ++i)
        st_cut_check_capacity(g.source_capacities[i], "source_capacities", i, true);
    for (std::size_t i = 0; i < g.sink_capacities.size(); ++i) {
        st_cut_check_capacity(g.sink_capacities[i], "sink_capacities", i, true);
        if (!g.source_capacities.empty() && std::isinf(g.sink_capacities[i]) && std::isinf(g.source_capacities[i]))
            throw invalid_input("kintsugi::st_min_cut: node " + std::to_string(i) +
                                " has infinite capacity to both the source and the sink; at most one "
                                "terminal capacity of a node may be infinite");
    }
}

/// The (source, target) arcs of a CSR network in order, from its offsets and targets: the
/// source of position p is the node whose offset range holds p, followed as p grows.
struct CsrArcIterator {
    using iterator_category = std::input_iterator_tag;
    using value_type = std::pair<std::uint32_t, std::uint32_t>;
    using difference_type = std::ptrdiff_t;
    using pointer = const value_type*;
    using reference = const value_type&;
    const std::vector<std::uint32_t>* offset = nullptr;
    const std::vector<std::uint32_t>* target = nullptr;
    std::uint32_t p = 0, v = 0;
    value_type cur{};
    void settle() {
        if (p >= target->size()) return;
        while ((*offset)[v + 1] <= p) ++v;
        cur = {v, (*target)[p]};
    }
    reference operator*() const { return cur; }
    pointer operator->() const { return &cur; }
    CsrArcIterator& operator++() {
        ++p;
        settle();
        return *this;
    }
    CsrArcIterator operator++(int) {
        CsrArcIterator old = *this;
        ++*this;
        return old;
    }
    bool operator==(const CsrArcIterator& o) const { return p == o.p; }
    bool operator!=(const CsrArcIterator& o) const { return p != o.p; }
};

/// The flow computation proper, on validated input.
inline StCutResult st_min_cut_impl(const StCutGraph& g, Progress& progress) {
    const std::size_t n = g.num_nodes;
    const std::size_t src = n, snk = n + 1;
    auto tcap = [&](const std::vector<Scalar>& v, std::size_t i) { return v.empty() ? Scalar(0) : v[i]; };
    // Capacity of edge i from b to a (the same both ways without reverse_capacities).
    auto rcap = [&](std::size_t i) { return g.reverse_capacities.empty() ? g.capacities[i] : g.reverse_capacities[i]; };

    // A finite stand-in for infinite terminal capacities: larger than any cut of finite arcs.
    Scalar finite_total = 0;
    for (std::size_t i = 0; i < g.edges.size(); ++i)
        finite_total += g.capacities[i] + rcap(i);
    for (std::size_t i = 0; i < n; ++i) {
        for (Scalar c : {tcap(g.source_capacities, i), tcap(g.sink_capacities, i)})
            if (!std::isinf(c)) finite_total += c;
    }
    const Scalar big = 2 * finite_total + 1;

    // The network in CSR form with 32-bit indices (half the memory of size_t: 2M points
    // at level 9 build 10M arcs). Each edge gives a pair of arcs, each the other's
    // reverse; the arcs of a node are stored in the order they are made (the edges in
    // their order, then the terminal arcs node by node), so the network is a function
    // of the graph alone.
    const std::size_t nv = n + 2;
    Scalar constant = 0;
    bool constant_infinite = false;
    // Terminal capacities after removing their common part, which every labelling cuts
    // (it goes into a constant).
    auto terminal = [&](std::size_t i, Scalar& cs, Scalar& ct) {
        cs = tcap(g.source_capacities, i);
        ct = tcap(g.sink_capacities, i);
        const bool inf_s = std::isinf(cs), inf_t = std::isinf(ct);
        if (inf_s) cs = big;
        if (inf_t) ct = big;
        const Scalar common = std::min(cs, ct);
        cs -= common;
        ct -= common;
        return (!inf_s && !inf_t) ? common : Scalar(0);
    };
    auto kept = [&](std::size_t i) {
        return g.edges[i][0] != g.edges[i][1] && !(g.capacities[i] == 0 && rcap(i) == 0);
    };
    std::vector<std::uint32_t> offset(nv + 1, 0);
    std::size_t na = 0;
    {
        std::vector<std::size_t> deg(nv, 0);
        for (std::size_t i = 0; i < g.edges.size(); ++i)
            if (kept(i)) {
                ++deg[g.edges[i][0]];
                ++deg[g.edges[i][1]];
            }
        for (std::size_t i = 0; i < n; ++i) {
            Scalar cs = 0, ct = 0;
            constant += terminal(i, cs, ct);
            if (cs > 0) ++deg[src], ++deg[i];
            if (ct > 0) ++deg[i], ++deg[snk];
        }
        for (std::size_t v = 0; v < nv; ++v) na += deg[v];
        if (na >= std::numeric_limits<std::uint32_t>::max() || nv >= std::numeric_limits<std::uint32_t>::max())
            throw invalid_input("kintsugi::st_min_cut: the flow network has " + std::to_string(na) + " arcs and " +
                                std::to_string(nv) + " nodes; at most 4,294,967,294 of each are supported "
                                "(split the problem)");
        for (std::size_t v = 0; v < nv; ++v) offset[v + 1] = offset[v] + static_cast<std::uint32_t>(deg[v]);
    }
    progress.check();
    // (On huge pages where the system allows: 10M arcs fill 300 MB; core/memory.hpp.)
    std::vector<std::uint32_t> target = huge_vector<std::uint32_t>(na), reverse = huge_vector<std::uint32_t>(na);
    std::vector<Scalar> cap = huge_vector<Scalar>(na), residual = huge_vector<Scalar>(na);
    {
        std::vector<std::uint32_t> fill(offset.begin(), offset.end() - 1);
        auto pair = [&](std::size_t a, std::size_t b, Scalar c, Scalar r) {
            const std::uint32_t p = fill[a]++, q = fill[b]++;
            target[p] = static_cast<std::uint32_t>(b);
            target[q] = static_cast<std::uint32_t>(a);
            cap[p] = c;
            cap[q] = r;
            reverse[p] = q;
            reverse[q] = p;
        };
        for (std::size_t i = 0; i < g.edges.size(); ++i)
            if (kept(i))
                pair(g.edges[i][0], g.edges[i][1], g.capacities[i], rcap(i));
        for (std::size_t i = 0; i < n; ++i) {
            Scalar cs = 0, ct = 0;
            (void)terminal(i, cs, ct);
            if (cs > 0) pair(src, i, cs, 0);
            if (ct > 0) pair(i, snk, ct, 0);
        }
    }
    using Graph = boost::compressed_sparse_row_graph<boost::directedS, boost::no_property, boost::no_property,
                                                     boost::no_property, std::uint32_t, std::uint32_t>;
    using Edge = boost::graph_traits<Graph>::edge_descriptor;
    // The (source, target) pairs in CSR order, made on the fly in one pass
    // (CsrArcIterator), into a column array of the known size (2M bench input, 10M arcs:
    // 0.1 s; a binary search per arc and the array grown by doubling took 0.9 s).
    CsrArcIterator first{&offset, &target, 0, 0, {}};
    first.settle();
    const CsrArcIterator last{&offset, &target, static_cast<std::uint32_t>(na), 0, {}};
    Graph graph(boost::edges_are_sorted, first, last, static_cast<std::uint32_t>(nv), static_cast<std::uint32_t>(na));
    const auto eidx = get(boost::edge_index, graph);
    // The edge index of the CSR graph is the arc's position; the reverse arc of p starts
    // at p's target. Made on demand from `reverse` (a table of reverse descriptors took
    // 8 more bytes an arc, 80 MB of fresh pages at 10M arcs).
    std::vector<std::uint32_t>().swap(target);
    std::vector<std::uint32_t>().swap(offset);
    const auto rev = boost::make_function_property_map<Edge>(
        [&graph, &reverse](const Edge& e) { return Edge(boost::target(e, graph), reverse[e.idx]); });
    progress.check();

    const auto vidx = get(boost::vertex_index, graph);
    std::vector<Edge> pred(nv);
    std::vector<boost::default_color_type> color(nv, boost::white_color);
    std::vector<std::size_t> dist(nv, 0);
    const Scalar flow = boost::boykov_kolmogorov_max_flow(
        graph, boost::make_iterator_property_map(cap.begin(), eidx),
        boost::make_iterator_property_map(residual.begin(), eidx), rev,
        boost::make_iterator_property_map(pred.begin(), vidx), boost::make_iterator_property_map(color.begin(), vidx),
        boost::make_iterator_property_map(dist.begin(), vidx), vidx, static_cast<std::uint32_t>(src), static_cast<std::uint32_t>(snk));
    progress.check();

    StCutResult out;
    out.labels.resize(n);
    for (std::size_t i = 0; i < n; ++i)
        out.labels[i] = color[i] == boost::black_color ? StSide::source : StSide::sink;
    // The cut value from the labels (equal to the max flow up to rounding); an
    // infinite terminal arc that is cut makes it infinite.
    Scalar cut = constant;
    for (std::size_t i = 0; i < g.edges.size(); ++i) {
        const auto [a, b] = g.edges[i];
        if (a == b) continue;
        if (out.labels[a] == StSide::source && out.labels[b] == StSide::sink) cut += g.capacities[i];
        if (out.labels[b] == StSide::source && out.labels[a] == StSide::sink) cut += rcap(i);
    }
    for (std::size_t i = 0; i < n; ++i) {
        const Scalar cs = tcap(g.source_capacities, i), ct = tcap(g.sink_capacities, i);
        const Scalar common = (std::isinf(cs) || std::isinf(ct)) ? Scalar(0) : std::min(cs, ct);
        const Scalar severed = out.labels[i] == StSide::source ? ct - common : cs - common;
        if (std::isinf(severed)) constant_infinite = true;
        else cut += severed;
    }
    (void)flow;
    out.cut_value = constant_infinite ? std::numeric_limits<Scalar>::infinity() : cut;
    out.network_nodes = nv;
    out.network_arcs = na;
    return out;
}

}  // namespace detail

/// @brief Labels the nodes of a graph by an s-t minimum cut.
///
/// Boykov, Kolmogorov, "An experimental comparison of min-cut/max-flow algorithms
/// for energy minimization in vision", IEEE TPAMI 26(9), 2004 — through
/// Boost.Graph's `boykov_kolmogorov_max_flow`. Minimises
/// Σ_{cut arcs} capacity over all partitions of the nodes into a source side and
/// a sink side; a node with capacity c_s to the source pays c_s when it ends on the
/// sink side and one with capacity c_t to the sink pays c_t on the source side; an
/// edge (a, b) pays capacities[i] when a is on the source side and b on the sink
/// side, and reverse_capacities[i] in the opposite case.
///
/// Among several minimum cuts, the one with the smallest source side is returned
/// (nodes reachable from the source in the residual graph). Deterministic.
///
/// @param graph nodes, edges and capacities (dimensionless or any consistent unit).
/// @param params cancellation/progress.
/// @pre capacities finite and >= 0; terminal capacities >= 0, possibly +infinity
///      (a hard constraint), never infinite to both terminals for the same node.
/// @throws invalid_input on an edge index >= num_nodes, a NaN, negative or infinite
///         edge capacity, a NaN or negative terminal capacity, or vectors of the
///         wrong length.
/// @return labels, cut value and sizes. Status::cancelled: stopped through
///         params.control; labels empty.
[[nodiscard]] inline StCutResult st_min_cut(const StCutGraph& graph, const StCutParams& params = {}) {
    detail::st_cut_validate(graph);
    return detail::run_cancellable<StCutResult>(params.control, [&](detail::Progress& progress) {
        progress.stage("max_flow", 0.0, 1.0);
        StCutResult out = detail::st_min_cut_impl(graph, progress);
        out.timings = progress.finish();
        return out;
    });
}

}  // namespace kintsugi
