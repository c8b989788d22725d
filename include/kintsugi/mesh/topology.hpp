// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file topology.hpp
/// @brief `MeshTopology`: edges, edge-face, face-edge, vertex-face and vertex-vertex
/// adjacency of an indexed triangle mesh, in compact CSR arrays, and boundary loops.
///
/// @code
/// kintsugi::MeshTopology topo(mesh);                 // any TriangleMesh
/// for (kintsugi::Index e = 0; e < topo.num_edges(); ++e)
///     if (topo.edge_faces(e).size() > 2) { /* non-manifold edge */ }
/// for (kintsugi::Index n : topo.vertex_neighbors(v)) { /* one ring, sorted */ }
/// auto holes = topo.boundary_loops();                // vertex loops, one per hole
/// @endcode
///
/// Memory is linear in the mesh: every adjacency is one offset array plus one flat
/// data array (no per-vertex std::vector). Any input is accepted: boundaries,
/// non-manifold edges (more than two faces), non-manifold (pinched) vertices,
/// inconsistent orientation, isolated vertices and faces with a repeated vertex
/// index. The last ones give "self edges" (v0 == v1), the only edges whose
/// endpoints are equal; they are never boundary edges and never neighbours.

#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/types.hpp>

#include <algorithm>
#include <array>
#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

/// Adjacency of an indexed triangle mesh (edges, incidences, one-rings, boundary loops).
///
/// Built once, then read-only and safe to query from several threads. Edges are
/// numbered in lexicographic order of (v0, v1) with v0 <= v1. All spans point into the
/// object and stay valid while it lives.
class MeshTopology {
public:
    MeshTopology() = default;

    /// @brief Builds the adjacency of `faces` over vertices 0 .. num_vertices-1.
    /// @param num_vertices number of vertices (isolated vertices are allowed)
    /// @param faces        triangles as vertex indices, any orientation
    /// @pre nothing; any combinatorics is accepted
    /// @throws invalid_input if a face has a vertex index >= num_vertices.
    /// Cost: O(F log d) time for maximal vertex degree d, O(V + F) memory.
    MeshTopology(std::size_t num_vertices, const std::vector<Face>& faces) { build(num_vertices, faces); }

    /// @brief Builds the adjacency of any TriangleMesh (its faces are read once).
    /// @tparam M a type modelling TriangleMesh
    /// @throws invalid_input if a face has a vertex index out of range.
    template <TriangleMesh M>
    explicit MeshTopology(const M& m) {
        const std::size_t nf = kintsugi::num_faces(m);
        std::vector<Face> faces(nf);
        for (std::size_t f = 0; f < nf; ++f) faces[f] = kintsugi::face_at(m, f);
        build(kintsugi::num_vertices(m), faces);
    }

    [[nodiscard]] std::size_t num_vertices() const { return num_vertices_; }
    [[nodiscard]] std::size_t num_faces() const { return faces_.size(); }
    [[nodiscard]] std::size_t num_edges() const { return edges_.size(); }

    /// The faces the topology was built from.
    [[nodiscard]] const std::vector<Face>& faces() const { return faces_; }

    /// Unique undirected edges, v0 < v1 (v0 == v1 only for the self edge of a face
    /// with a repeated index), sorted lexicographically.
    [[nodiscard]] const std::vector<std::array<Index, 2>>& edges() const { return edges_; }

    /// Distinct faces using edge e, increasing: 1 = boundary, 2 = manifold, >2 = non-manifold.
    [[nodiscard]] std::span<const Index> edge_faces(Index e) const {
        return {edge_face_data_.data() + edge_face_offsets_[e], edge_face_offsets_[e + 1] - edge_face_offsets_[e]};
    }

    /// Edges of face f: (f0,f1), (f1,f2), (f2,f0).
    [[nodiscard]] const std::array<Index, 3>& face_edges(Index f) const { return face_edges_[f]; }

    /// Distinct faces using vertex v, increasing.
    [[nodiscard]] std::span<const Index> vertex_faces(Index v) const {
        return {vertex_face_data_.data() + vertex_face_offsets_[v],
                vertex_face_offsets_[v + 1] - vertex_face_offsets_[v]};
    }

    /// One-ring of v: the vertices sharing an edge with v, sorted, without v itself.
    [[nodiscard]] std::span<const Index> vertex_neighbors(Index v) const {
        return {neighbor_data_.data() + neighbor_offsets_[v], neighbor_offsets_[v + 1] - neighbor_offsets_[v]};
    }

    /// Edges incident to v, in the order of vertex_neighbors(v) (the i-th joins v and
    /// its i-th neighbour). Self edges are not listed.
    [[nodiscard]] std::span<const Index> vertex_edges(Index v) const {
        return {neighbor_edge_data_.data() + neighbor_offsets_[v], neighbor_offsets_[v + 1] - neighbor_offsets_[v]};
    }

    /// The edge joining a and b (either order), if any. O(log degree).
    [[nodiscard]] std::optional<Index> find_edge(Index a, Index b) const {
        if (a >= num_vertices_ || b >= num_vertices_) return std::nullopt;
        if (a == b) {
            const auto it = std::lower_bound(edges_.begin(), edges_.end(), std::array<Index, 2>{a, a});
            if (it != edges_.end() && (*it)[0] == a && (*it)[1] == a) return static_cast<Index>(it - edges_.begin());
            return std::nullopt;
        }
        const auto nb = vertex_neighbors(a);
        const auto it = std::lower_bound(nb.begin(), nb.end(), b);
        if (it == nb.end() || *it != b) return std::nullopt;
        return vertex_edges(a)[static_cast<std::size_t>(it - nb.begin())];
    }

    /// Edge used by exactly one face (self edges excluded).
    [[nodiscard]] bool is_boundary_edge(Index e) const {
        return edge_faces(e).size() == 1 && edges_[e][0] != edges_[e][1];
    }

    /// Vertex on at least one boundary edge.
    [[nodiscard]] bool is_boundary_vertex(Index v) const {
        for (Index e : vertex_edges(v))
            if (is_boundary_edge(e)) return true;
        return false;
    }

    /// @brief Boundary loops as vertex loops (the first vertex is not repeated at the end).
    ///
    /// Each loop follows the directed boundary half-edges: for a boundary edge whose
    /// face runs a -> b, the boundary half-edge runs b -> a (CGAL's border half-edge),
    /// so the face along the loop runs loop[i+1] -> loop[i] and a face
    /// (loop[i], loop[i+1], x) fills the hole with the orientation of its neighbours.
    /// Where the orientation is inconsistent (or the surface non-orientable, e.g. a
    /// Moebius strip) the walk continues along the undirected boundary. Loops are
    /// simple: where boundaries meet at a vertex (two holes touching, a bow-tie), the
    /// closed walk is split at the repeated vertex, so loops touching at a vertex are
    /// reported separately. Every boundary edge is in exactly
    /// one loop. Where non-manifold edges leave a vertex with an odd number of
    /// boundary edges, a piece cannot close: it is reported as an open chain that
    /// lists its last vertex too.
    /// Cost: O(boundary edges) after the build.
    [[nodiscard]] std::vector<std::vector<Index>> boundary_loops() const;

private:
    void build(std::size_t nv, const std::vector<Face>& faces);

    /// The boundary half-edge of boundary edge e as (source, target).
    [[nodiscard]] std::pair<Index, Index> boundary_halfedge(Index e) const {
        const Face& f = faces_[edge_faces(e)[0]];
        const Index a = edges_[e][0], b = edges_[e][1];
        for (int k = 0; k < 3; ++k)
            if (f[k] == a && f[(k + 1) % 3] == b) return {b, a};  // face runs a -> b
        return {a, b};
    }

    std::size_t num_vertices_ = 0;
    std::vector<Face> faces_;
    std::vector<std::array<Index, 2>> edges_;
    std::vector<Index> edge_face_offsets_{0}, edge_face_data_;
    std::vector<std::array<Index, 3>> face_edges_;
    std::vector<Index> vertex_face_offsets_{0}, vertex_face_data_;
    std::vector<Index> neighbor_offsets_{0}, neighbor_data_, neighbor_edge_data_;
};

inline void MeshTopology::build(std::size_t nv, const std::vector<Face>& faces) {
    const std::size_t nf = faces.size();
    for (std::size_t f = 0; f < nf; ++f)
        for (int k = 0; k < 3; ++k)
            if (faces[f][k] >= nv)
                throw invalid_input("kintsugi::MeshTopology: face " + std::to_string(f) + " uses vertex " +
                                    std::to_string(faces[f][k]) + " but the mesh has " + std::to_string(nv) +
                                    " vertices; fix or remove the face");
    num_vertices_ = nv;
    faces_ = faces;

    // Half-edge slots (f, k) bucketed by their lower vertex (counting sort), then
    // sorted by (upper vertex, face) inside each bucket.
    struct Slot {
        Index hi, face;
        unsigned char k;
    };
    std::vector<Index> bucket(nv + 1, 0);
    for (const Face& t : faces)
        for (int k = 0; k < 3; ++k) ++bucket[std::min(t[k], t[(k + 1) % 3]) + 1];
    for (std::size_t v = 0; v < nv; ++v) bucket[v + 1] += bucket[v];
    std::vector<Slot> slots(3 * nf);
    {
        std::vector<Index> fill(bucket.begin(), bucket.end() - 1);
        for (std::size_t f = 0; f < nf; ++f)
            for (int k = 0; k < 3; ++k) {
                const Index a = faces[f][k], b = faces[f][(k + 1) % 3];
                slots[fill[std::min(a, b)]++] = Slot{std::max(a, b), f, static_cast<unsigned char>(k)};
            }
    }
    for (std::size_t v = 0; v < nv; ++v)
        std::sort(slots.begin() + static_cast<std::ptrdiff_t>(bucket[v]),
                  slots.begin() + static_cast<std::ptrdiff_t>(bucket[v + 1]), [](const Slot& x, const Slot& y) {
                      return x.hi < y.hi || (x.hi == y.hi && x.face < y.face);
                  });

    edges_.clear();
    edges_.reserve(3 * nf / 2 + 16);
    edge_face_offsets_.assign(1, 0);
    edge_face_data_.clear();
    edge_face_data_.reserve(3 * nf);
    face_edges_.assign(nf, {0, 0, 0});
    for (std::size_t v = 0; v < nv; ++v) {
        for (Index s = bucket[v]; s < bucket[v + 1]; ++s) {
            const Slot& sl = slots[s];
            if (s == bucket[v] || slots[s - 1].hi != sl.hi) {
                if (!edges_.empty()) edge_face_offsets_.push_back(edge_face_data_.size());
                edges_.push_back({v, sl.hi});
            }
            const Index e = edges_.size() - 1;
            face_edges_[sl.face][sl.k] = e;
            if (edge_face_data_.size() == edge_face_offsets_.back() || edge_face_data_.back() != sl.face)
                edge_face_data_.push_back(sl.face);
        }
    }
    if (!edges_.empty()) edge_face_offsets_.push_back(edge_face_data_.size());
    slots = {};

    // One-rings from the sorted edge list: for vertex v, first the edges (u, v) with
    // u < v (visited in increasing u), then the edges (v, w) with w > v (increasing w).
    neighbor_offsets_.assign(nv + 1, 0);
    for (const auto& e : edges_)
        if (e[0] != e[1]) {
            ++neighbor_offsets_[e[0] + 1];
            ++neighbor_offsets_[e[1] + 1];
        }
    for (std::size_t v = 0; v < nv; ++v) neighbor_offsets_[v + 1] += neighbor_offsets_[v];
    neighbor_data_.assign(neighbor_offsets_[nv], 0);
    neighbor_edge_data_.assign(neighbor_offsets_[nv], 0);
    {
        std::vector<Index> fill(neighbor_offsets_.begin(), neighbor_offsets_.end() - 1);
        for (Index e = 0; e < edges_.size(); ++e) {
            const auto [a, b] = edges_[e];
            if (a == b) continue;
            neighbor_data_[fill[b]] = a;
            neighbor_edge_data_[fill[b]++] = e;
        }
        for (Index e = 0; e < edges_.size(); ++e) {
            const auto [a, b] = edges_[e];
            if (a == b) continue;
            neighbor_data_[fill[a]] = b;
            neighbor_edge_data_[fill[a]++] = e;
        }
    }

    // Vertex -> faces (increasing, distinct).
    vertex_face_offsets_.assign(nv + 1, 0);
    auto distinct = [](const Face& t, int k) {
        return (k == 0) || (k == 1 && t[1] != t[0]) || (k == 2 && t[2] != t[0] && t[2] != t[1]);
    };
    for (const Face& t : faces)
        for (int k = 0; k < 3; ++k)
            if (distinct(t, k)) ++vertex_face_offsets_[t[k] + 1];
    for (std::size_t v = 0; v < nv; ++v) vertex_face_offsets_[v + 1] += vertex_face_offsets_[v];
    vertex_face_data_.assign(vertex_face_offsets_[nv], 0);
    {
        std::vector<Index> fill(vertex_face_offsets_.begin(), vertex_face_offsets_.end() - 1);
        for (std::size_t f = 0; f < nf; ++f)
            for (int k = 0; k < 3; ++k)
                if (distinct(faces[f], k)) vertex_face_data_[fill[faces[f][k]]++] = f;
    }
}

inline std::vector<std::vector<Index>> MeshTopology::boundary_loops() const {
    constexpr Index none = static_cast<Index>(-1);
    // Boundary edges bucketed by both endpoints.
    std::vector<Index> boundary;
    for (Index e = 0; e < edges_.size(); ++e)
        if (is_boundary_edge(e)) boundary.push_back(e);
    std::vector<Index> offsets(num_vertices_ + 1, 0);
    for (Index e : boundary) {
        ++offsets[edges_[e][0] + 1];
        ++offsets[edges_[e][1] + 1];
    }
    for (std::size_t v = 0; v < num_vertices_; ++v) offsets[v + 1] += offsets[v];
    std::vector<Index> incident(offsets[num_vertices_]);
    std::vector<Index> source(edges_.size(), none);  // source of the boundary half-edge
    {
        std::vector<Index> fill(offsets.begin(), offsets.end() - 1);
        for (Index e : boundary) {
            incident[fill[edges_[e][0]]++] = e;
            incident[fill[edges_[e][1]]++] = e;
            source[e] = boundary_halfedge(e).first;
        }
    }
    std::vector<char> used(edges_.size(), 0);
    // Next edge from v: an unused boundary half-edge leaving v; failing that (the
    // orientation is inconsistent there), any unused boundary edge at v.
    auto next_from = [&](Index v) {
        Index any = none;
        for (Index i = offsets[v]; i < offsets[v + 1]; ++i) {
            const Index e = incident[i];
            if (used[e]) continue;
            if (source[e] == v) return e;
            if (any == none) any = e;
        }
        return any;
    };

    // Walk, and split off a simple loop whenever the walk returns to a vertex of the
    // current path (pos[v] = position of v in the path, none when not on it).
    std::vector<Index> pos(num_vertices_, none);
    std::vector<Index> path;
    std::vector<std::vector<Index>> loops;
    auto emit = [&](std::size_t from) {
        std::vector<Index> loop(path.begin() + static_cast<std::ptrdiff_t>(from), path.end());
        for (Index v : loop) pos[v] = none;
        path.resize(from);
        loops.push_back(std::move(loop));
    };
    for (Index start : boundary) {
        if (used[start]) continue;
        Index e = start;
        Index x = source[start];
        while (true) {
            used[e] = 1;
            const Index y = edges_[e][0] == x ? edges_[e][1] : edges_[e][0];
            pos[x] = path.size();
            path.push_back(x);
            if (pos[y] != none) {
                emit(pos[y]);
                if (path.empty()) break;
            }
            e = next_from(y);
            if (e == none) {  // open chain: the boundary has an odd-degree vertex here
                pos[y] = path.size();
                path.push_back(y);
                emit(0);
                break;
            }
            x = y;
        }
    }
    return loops;
}

}  // namespace kintsugi
