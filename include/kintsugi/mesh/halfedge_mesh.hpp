// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file halfedge_mesh.hpp
/// @brief `HalfedgeMesh`: an editable manifold triangle mesh (edge split, collapse and
/// flip with manifold checks) whose vertices carry attributes (position, optional
/// normal, named user scalars) that follow them through every edit.
///
/// @code
/// auto hm = kintsugi::HalfedgeMesh::from_mesh(mesh);      // any TriangleMesh; throws on non-manifold
/// const auto s = hm.add_scalar("u", 0.0);                  // a user scalar per vertex
/// kintsugi::Index h = hm.find_halfedge(3, 7);              // the edge 3 -> 7
/// if (hm.can_flip(h)) hm.flip(h);
/// kintsugi::Index m = hm.split(h, 0.5);                    // new vertex, attributes interpolated
/// if (hm.can_collapse(h)) hm.collapse(h, 0.5);             // source merged into target
/// hm.to_mesh(out);                                         // any TopologyMutableMesh, compacted
/// @endcode
///
/// Structure (the "directed edges" layout of Campagna, Kobbelt, Seidel, 1998): halfedge
/// h = 3 f + k runs from corner k to corner k+1 of face f, so next, prev and face are
/// arithmetic; per halfedge only its vertex and its twin are stored (4 + 4 bytes), per
/// vertex one outgoing halfedge. Chosen over CGAL::Surface_mesh with its Euler
/// operations by measurement (docs/methods/mesh_editing.md: 1M random split / collapse /
/// flip, time and memory). Removed vertices and faces leave holes in the index ranges,
/// which later splits reuse; collect_garbage() or to_mesh() compacts them.
///
/// Invariants (checked by validate()): every face has three distinct live vertices;
/// every edge has one or two faces, consistently oriented; every vertex's faces form
/// one fan (a disk, or a half-disk at the boundary).

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/core/concepts.hpp>
#include <kintsugi/core/error.hpp>
#include <kintsugi/core/types.hpp>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace kintsugi {

/// Editable manifold triangle mesh with per-vertex attributes (see the file comment).
///
/// Indices: vertices 0 .. vertex_capacity()-1, faces 0 .. face_capacity()-1, halfedges
/// 0 .. 3 face_capacity()-1; removed elements keep their index until a split reuses it
/// or collect_garbage() compacts. Without collapses, new elements are appended.
/// Not thread-safe for writing; concurrent reads are fine.
class HalfedgeMesh {
    using I = std::uint32_t;
    static constexpr I nil = std::numeric_limits<I>::max();

public:
    /// The value of an absent halfedge, vertex or face (a boundary twin, a refused collapse).
    static constexpr Index invalid = std::numeric_limits<Index>::max();

    HalfedgeMesh() = default;

    // ------------------------------------------------------------ construction

    /// @brief Builds the structure from positions and faces.
    /// @param positions one finite position per vertex (isolated vertices allowed)
    /// @param faces     triangles, consistently oriented
    /// @throws invalid_input naming the face, edge or vertex when: an index is out of range,
    ///         a face repeats a vertex, an edge has more than two faces or two faces that
    ///         run it the same way (non-manifold or inconsistently oriented), a vertex's
    ///         faces form several fans (non-manifold vertex), a coordinate is NaN/Inf, or
    ///         the mesh has 2^32-1 or more halfedges.
    static HalfedgeMesh from_faces(std::vector<Vec3> positions, const std::vector<Face>& faces);

    /// @brief Builds the structure from any TriangleMesh (read once).
    /// @tparam M a TriangleMesh (IndexedMesh, Eigen V/F view, CGAL::Surface_mesh, ...).
    /// Normals are taken along when M is an IndexedMesh that has one per vertex.
    /// @throws invalid_input as from_faces.
    template <TriangleMesh M>
    static HalfedgeMesh from_mesh(const M& mesh) {
        const std::size_t nv = kintsugi::num_vertices(mesh), nf = kintsugi::num_faces(mesh);
        std::vector<Vec3> p(nv);
        for (std::size_t v = 0; v < nv; ++v) p[v] = vertex_position(mesh, v);
        std::vector<Face> f(nf);
        for (std::size_t i = 0; i < nf; ++i) f[i] = face_at(mesh, i);
        HalfedgeMesh out = from_faces(std::move(p), f);
        if constexpr (std::is_same_v<M, IndexedMesh>)
            if (!mesh.normals.empty() && mesh.normals.size() == nv) out.normals_ = mesh.normals;
        return out;
    }

    /// @brief Writes the live vertices and faces, compacted, into any TopologyMutableMesh
    /// (cleared first; an IndexedMesh also receives the normals when present).
    /// @return the new index of each vertex (invalid for removed ones), to carry user
    ///         attributes across.
    template <TopologyMutableMesh M>
    std::vector<Index> to_mesh(M& out) const {
        std::vector<Index> map(v_out_.size(), invalid);
        IndexedMesh tmp;
        for (Index v = 0; v < v_out_.size(); ++v)
            if (!v_removed_[v]) {
                map[v] = tmp.vertices.size();
                tmp.vertices.push_back(pos_[v]);
                if (!normals_.empty()) tmp.normals.push_back(normals_[v]);
            }
        for (Index f = 0; f < face_capacity(); ++f)
            if (!is_removed_face(f))
                tmp.faces.push_back({map[corner_[3 * f]], map[corner_[3 * f + 1]], map[corner_[3 * f + 2]]});
        if constexpr (std::is_same_v<M, IndexedMesh>) {
            out = std::move(tmp);
        } else {
            assign_mesh(out, tmp);
        }
        return map;
    }

    /// Compacts the index ranges (removed elements dropped, order kept). Invalidates
    /// every index held outside; returns the new index of each old vertex.
    std::vector<Index> collect_garbage();

    // ------------------------------------------------------------ sizes

    [[nodiscard]] std::size_t num_vertices() const { return v_out_.size() - removed_vertices_; }
    [[nodiscard]] std::size_t num_faces() const { return face_capacity() - removed_faces_; }
    [[nodiscard]] std::size_t vertex_capacity() const { return v_out_.size(); }
    [[nodiscard]] std::size_t face_capacity() const { return corner_.size() / 3; }
    [[nodiscard]] std::size_t halfedge_capacity() const { return corner_.size(); }
    [[nodiscard]] bool is_removed_vertex(Index v) const { return v_removed_[v] != 0; }
    [[nodiscard]] bool is_removed_face(Index f) const { return corner_[3 * f] == nil; }

    // ------------------------------------------------------------ navigation

    [[nodiscard]] static Index face(Index h) { return h / 3; }
    [[nodiscard]] static Index next(Index h) { return h % 3 == 2 ? h - 2 : h + 1; }
    [[nodiscard]] static Index prev(Index h) { return h % 3 == 0 ? h + 2 : h - 1; }
    /// The opposite halfedge, or invalid on the boundary.
    [[nodiscard]] Index twin(Index h) const { return widen(twin_[h]); }
    [[nodiscard]] Index source(Index h) const { return corner_[h]; }
    [[nodiscard]] Index target(Index h) const { return corner_[next(h)]; }
    /// The vertex opposite h in its face.
    [[nodiscard]] Index opposite(Index h) const { return corner_[prev(h)]; }
    /// Vertex k (0, 1, 2) of face f.
    [[nodiscard]] Index face_vertex(Index f, int k) const { return corner_[3 * f + static_cast<Index>(k)]; }
    /// One outgoing halfedge of v, invalid for an isolated vertex.
    [[nodiscard]] Index halfedge(Index v) const { return widen(v_out_[v]); }
    [[nodiscard]] bool is_boundary_halfedge(Index h) const { return twin_[h] == nil; }
    /// Whether an edge of v lies on the boundary (isolated vertices are not).
    [[nodiscard]] bool is_boundary_vertex(Index v) const;
    /// The halfedge from a to b, invalid when a and b share no edge. O(degree).
    [[nodiscard]] Index find_halfedge(Index a, Index b) const;
    /// Outgoing halfedges of v, counter-clockwise; at the boundary the first one is the
    /// clockwise-most, whose twin is absent. Cleared first.
    void outgoing_halfedges(Index v, std::vector<Index>& out) const;
    /// Neighbours of v (counter-clockwise, each once). Cleared first.
    void vertex_ring(Index v, std::vector<Index>& out) const;
    /// Number of neighbours of v.
    [[nodiscard]] std::size_t valence(Index v) const;

    // ------------------------------------------------------------ attributes

    [[nodiscard]] const Vec3& position(Index v) const { return pos_[v]; }
    Vec3& position(Index v) { return pos_[v]; }
    [[nodiscard]] bool has_normals() const { return !normals_.empty(); }
    /// Allocates a normal per vertex (zero) if absent. Normals are interpolated and
    /// renormalised by split and collapse.
    void enable_normals() {
        if (normals_.empty()) normals_.assign(v_out_.size(), Vec3::Zero());
    }
    /// @pre has_normals()
    [[nodiscard]] const Vec3& normal(Index v) const { return normals_[v]; }
    Vec3& normal(Index v) { return normals_[v]; }
    /// Adds a user scalar per vertex, set to `value`; returns its channel. Split and
    /// collapse interpolate it linearly along the edge.
    std::size_t add_scalar(std::string name, Scalar value = 0) {
        scalar_names_.push_back(std::move(name));
        scalars_.emplace_back(v_out_.size(), value);
        return scalars_.size() - 1;
    }
    /// The channel named `name`, or invalid.
    [[nodiscard]] std::size_t find_scalar(const std::string& name) const {
        const auto it = std::find(scalar_names_.begin(), scalar_names_.end(), name);
        return it == scalar_names_.end() ? invalid : static_cast<std::size_t>(it - scalar_names_.begin());
    }
    [[nodiscard]] std::size_t num_scalars() const { return scalars_.size(); }
    [[nodiscard]] Scalar scalar(std::size_t channel, Index v) const { return scalars_[channel][v]; }
    Scalar& scalar(std::size_t channel, Index v) { return scalars_[channel][v]; }

    // ------------------------------------------------------------ edits

    /// Whether flip(h) keeps the mesh manifold: h is interior and the new edge (between
    /// the two opposite vertices) does not exist yet.
    [[nodiscard]] bool can_flip(Index h) const;
    /// Replaces the edge of h by the other diagonal of its two faces: afterwards h runs
    /// from the vertex that was opposite twin(h) to the one that was opposite h.
    /// Returns false (nothing changed) when !can_flip(h).
    bool flip(Index h);

    /// Splits the edge of h at source + t (target - source): a new vertex, each face of
    /// the edge split in two. Always possible. Attributes are interpolated at t.
    /// @param t in [0, 1]; 0.5 splits at the midpoint.
    /// @return the new vertex. Afterwards h runs from the old source to the new vertex.
    Index split(Index h, Scalar t = 0.5);

    /// Whether collapse(h) keeps the mesh manifold: the link condition (the common
    /// neighbours of the two ends are exactly the vertices opposite the edge), no
    /// tetrahedron collapses flat, an interior edge does not join two boundary vertices,
    /// and a lone triangle is not collapsed.
    [[nodiscard]] bool can_collapse(Index h) const;
    /// Merges source(h) into target(h), which moves to source + t (target - source) and
    /// takes the attributes interpolated at t; the one or two faces of the edge vanish.
    /// @return the kept vertex, or invalid (nothing changed) when !can_collapse(h).
    Index collapse(Index h, Scalar t = 0.5);

    /// Empty when every invariant holds, else the first violation found (for tests and
    /// debugging; O(V + F)).
    [[nodiscard]] std::string validate() const;

private:
    static Index widen(I x) { return x == nil ? invalid : static_cast<Index>(x); }
    static I narrow(Index x) { return x == invalid ? nil : static_cast<I>(x); }
    void set_twin(Index a, Index b) {
        if (a != invalid) twin_[a] = narrow(b);
        if (b != invalid) twin_[b] = narrow(a);
    }
    Index new_vertex() {
        if (!free_vertices_.empty()) {  // reuse a removed vertex's slot
            const Index v = free_vertices_.back();
            free_vertices_.pop_back();
            v_removed_[v] = 0;
            v_out_[v] = nil;
            --removed_vertices_;
            return v;
        }
        v_out_.push_back(nil);
        v_removed_.push_back(0);
        pos_.emplace_back(Vec3::Zero());
        if (!normals_.empty()) normals_.emplace_back(Vec3::Zero());
        for (auto& s : scalars_) s.push_back(0);
        return v_out_.size() - 1;
    }
    Index new_face(Index a, Index b, Index c) {
        Index f = 0;
        if (!free_faces_.empty()) {  // reuse a removed face's slot
            f = free_faces_.back();
            free_faces_.pop_back();
            --removed_faces_;
        } else {
            f = corner_.size() / 3;
            corner_.resize(corner_.size() + 3);
            twin_.resize(twin_.size() + 3);
        }
        corner_[3 * f] = narrow(a);
        corner_[3 * f + 1] = narrow(b);
        corner_[3 * f + 2] = narrow(c);
        for (Index k = 0; k < 3; ++k) twin_[3 * f + k] = nil;
        return f;
    }
    /// Attributes of `dst` = interpolation between a and b at t.
    void interpolate(Index dst, Index a, Index b, Scalar t) {
        pos_[dst] = (1 - t) * pos_[a] + t * pos_[b];
        if (!normals_.empty()) {
            const Vec3 n = (1 - t) * normals_[a] + t * normals_[b];
            normals_[dst] = n.norm() > 0 ? Vec3(n.normalized()) : n;
        }
        for (auto& s : scalars_) s[dst] = (1 - t) * s[a] + t * s[b];
    }
    /// The clockwise-most outgoing halfedge of v (its twin absent) or, for an interior
    /// vertex, halfedge(v).
    [[nodiscard]] Index first_outgoing(Index v) const;
    /// Whether a face with the three vertices exists (any orientation).
    [[nodiscard]] bool has_face(Index a, Index b, Index c) const;

    std::vector<I> corner_;  ///< per halfedge: its source; nil for a removed face
    std::vector<I> twin_;    ///< per halfedge: its twin, nil on the boundary
    std::vector<I> v_out_;   ///< per vertex: one outgoing halfedge, nil if isolated
    std::vector<std::uint8_t> v_removed_;
    std::vector<Vec3> pos_, normals_;
    std::vector<std::vector<Scalar>> scalars_;
    std::vector<std::string> scalar_names_;
    std::vector<Index> free_vertices_, free_faces_;  ///< removed slots, reused by split
    std::size_t removed_vertices_ = 0, removed_faces_ = 0;
};

// ---------------------------------------------------------------- construction

inline HalfedgeMesh HalfedgeMesh::from_faces(std::vector<Vec3> positions, const std::vector<Face>& faces) {
    const std::string fn = "kintsugi::HalfedgeMesh: ";
    const std::size_t nv = positions.size(), nf = faces.size();
    if (3 * nf >= static_cast<std::size_t>(nil) || nv >= static_cast<std::size_t>(nil))
        throw invalid_input(fn + "the mesh has " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
                            " faces; at most 2^32-2 halfedges and vertices are supported; split the mesh");
    detail::check_finite_points(positions, fn + "vertex ", "; remove it");
    for (std::size_t f = 0; f < nf; ++f) {
        const Face& t = faces[f];
        for (int k = 0; k < 3; ++k)
            if (t[k] >= nv)
                throw invalid_input(fn + "face " + std::to_string(f) + " uses vertex " + std::to_string(t[k]) +
                                    " but the mesh has " + std::to_string(nv) + " vertices; fix or remove the face");
        if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0])
            throw invalid_input(fn + "face " + std::to_string(f) + " (" + std::to_string(t[0]) + ", " +
                                std::to_string(t[1]) + ", " + std::to_string(t[2]) +
                                ") repeats a vertex; remove degenerate faces first");
    }
    HalfedgeMesh m;
    m.pos_ = std::move(positions);
    m.corner_.resize(3 * nf);
    m.twin_.assign(3 * nf, nil);
    m.v_out_.assign(nv, nil);
    m.v_removed_.assign(nv, 0);
    for (std::size_t f = 0; f < nf; ++f)
        for (int k = 0; k < 3; ++k) m.corner_[3 * f + static_cast<std::size_t>(k)] = static_cast<I>(faces[f][k]);
    // Directed edges sorted by (source, target): a repeat is a non-manifold or
    // inconsistently oriented edge; twins are found by binary search.
    struct DE {
        I a, b, h;
    };
    std::vector<DE> de(3 * nf);
    for (Index h = 0; h < 3 * nf; ++h) de[h] = {m.corner_[h], m.corner_[next(h)], static_cast<I>(h)};
    std::sort(de.begin(), de.end(), [](const DE& x, const DE& y) { return x.a != y.a ? x.a < y.a : x.b != y.b ? x.b < y.b : x.h < y.h; });
    for (std::size_t i = 1; i < de.size(); ++i)
        if (de[i].a == de[i - 1].a && de[i].b == de[i - 1].b)
            throw invalid_input(fn + "edge (" + std::to_string(de[i].a) + ", " + std::to_string(de[i].b) +
                                ") is run the same way by faces " + std::to_string(de[i - 1].h / 3) + " and " +
                                std::to_string(de[i].h / 3) +
                                ": the edge has more than two faces or they are inconsistently oriented; "
                                "the mesh must be an oriented 2-manifold (repair or orient it first)");
    for (const DE& e : de) {
        DE key{e.b, e.a, 0};
        const auto jt = std::lower_bound(de.begin(), de.end(), key, [](const DE& x, const DE& y) {
            return x.a != y.a ? x.a < y.a : x.b < y.b;
        });
        if (jt != de.end() && jt->a == e.b && jt->b == e.a) m.twin_[e.h] = jt->h;
        if (m.v_out_[e.a] == nil) m.v_out_[e.a] = e.h;
    }
    // One fan per vertex: the halfedges reached by rotation must be all of its outgoing ones.
    std::vector<Index> ring;
    std::size_t i = 0;
    while (i < de.size()) {
        std::size_t j = i;
        while (j < de.size() && de[j].a == de[i].a) ++j;
        const Index v = de[i].a;
        m.outgoing_halfedges(v, ring);
        if (ring.size() != j - i)
            throw invalid_input(fn + "vertex " + std::to_string(v) + " is non-manifold: its faces form " +
                                "more than one fan (" + std::to_string(j - i) + " faces, " +
                                std::to_string(ring.size()) + " in one fan); split the vertex or remove faces");
        i = j;
    }
    return m;
}

inline std::vector<Index> HalfedgeMesh::collect_garbage() {
    std::vector<Index> vmap(v_out_.size(), invalid), fmap(face_capacity(), invalid);
    Index nv = 0, nf = 0;
    for (Index v = 0; v < v_out_.size(); ++v)
        if (!v_removed_[v]) vmap[v] = nv++;
    for (Index f = 0; f < face_capacity(); ++f)
        if (!is_removed_face(f)) fmap[f] = nf++;
    auto hmap = [&](I h) { return h == nil ? nil : static_cast<I>(3 * fmap[h / 3] + h % 3); };
    for (Index f = 0; f < face_capacity(); ++f) {
        if (fmap[f] == invalid) continue;
        for (Index k = 0; k < 3; ++k) {
            corner_[3 * fmap[f] + k] = static_cast<I>(vmap[corner_[3 * f + k]]);
            twin_[3 * fmap[f] + k] = hmap(twin_[3 * f + k]);
        }
    }
    corner_.resize(3 * nf);
    twin_.resize(3 * nf);
    for (Index v = 0; v < v_out_.size(); ++v) {
        if (vmap[v] == invalid) continue;
        const Index w = vmap[v];
        v_out_[w] = hmap(v_out_[v]);
        pos_[w] = pos_[v];
        if (!normals_.empty()) normals_[w] = normals_[v];
        for (auto& s : scalars_) s[w] = s[v];
    }
    v_out_.resize(nv);
    v_removed_.assign(nv, 0);
    pos_.resize(nv);
    if (!normals_.empty()) normals_.resize(nv);
    for (auto& s : scalars_) s.resize(nv);
    removed_vertices_ = removed_faces_ = 0;
    free_vertices_.clear();
    free_faces_.clear();
    return vmap;
}

// ---------------------------------------------------------------- navigation

inline Index HalfedgeMesh::first_outgoing(Index v) const {
    const Index h0 = halfedge(v);
    if (h0 == invalid) return invalid;
    Index h = h0;
    for (std::size_t guard = 0; guard < corner_.size(); ++guard) {
        const Index t = twin(h);
        if (t == invalid) return h;
        h = next(t);  // clockwise
        if (h == h0) return h0;
    }
    return h0;
}

inline void HalfedgeMesh::outgoing_halfedges(Index v, std::vector<Index>& out) const {
    out.clear();
    const Index h0 = first_outgoing(v);
    if (h0 == invalid) return;
    Index h = h0;
    for (std::size_t guard = 0; guard < corner_.size(); ++guard) {
        out.push_back(h);
        const Index t = twin(prev(h));  // counter-clockwise
        if (t == invalid || t == h0) return;
        h = t;
    }
}

inline void HalfedgeMesh::vertex_ring(Index v, std::vector<Index>& out) const {
    std::vector<Index> hs;
    outgoing_halfedges(v, hs);
    out.clear();
    for (Index h : hs) out.push_back(target(h));
    if (!hs.empty() && twin(prev(hs.back())) == invalid) out.push_back(source(prev(hs.back())));
}

inline std::size_t HalfedgeMesh::valence(Index v) const {
    const Index h0 = first_outgoing(v);
    if (h0 == invalid) return 0;
    std::size_t n = 0;
    Index h = h0;
    for (std::size_t guard = 0; guard < corner_.size(); ++guard) {
        ++n;
        const Index t = twin(prev(h));
        if (t == invalid) return n + 1;
        if (t == h0) return n;
        h = t;
    }
    return n;
}

inline bool HalfedgeMesh::is_boundary_vertex(Index v) const {
    const Index h = first_outgoing(v);
    return h != invalid && twin(h) == invalid;
}

inline Index HalfedgeMesh::find_halfedge(Index a, Index b) const {
    const Index h0 = first_outgoing(a);
    if (h0 == invalid) return invalid;
    Index h = h0;
    for (std::size_t guard = 0; guard < corner_.size(); ++guard) {
        if (target(h) == b) return h;
        const Index t = twin(prev(h));
        if (t == invalid || t == h0) return invalid;
        h = t;
    }
    return invalid;
}

inline bool HalfedgeMesh::has_face(Index a, Index b, Index c) const {
    Index h = find_halfedge(a, b);
    if (h != invalid && opposite(h) == c) return true;
    h = find_halfedge(b, a);
    return h != invalid && opposite(h) == c;
}

// ---------------------------------------------------------------- edits

inline bool HalfedgeMesh::can_flip(Index h) const {
    const Index g = twin(h);
    if (g == invalid || is_removed_face(face(h))) return false;
    const Index c = opposite(h), d = opposite(g);
    return c != d && find_halfedge(c, d) == invalid && find_halfedge(d, c) == invalid;
}

inline bool HalfedgeMesh::flip(Index h) {
    if (!can_flip(h)) return false;
    const Index g = twin(h);
    const Index a = source(h), b = target(h), c = opposite(h), d = opposite(g);
    const Index nh = next(h), ph = prev(h), ng = next(g), pg = prev(g);
    const Index t_bc = twin(nh), t_ca = twin(ph), t_ad = twin(ng), t_db = twin(pg);
    // (a, b, c), (b, a, d) -> (d, c, a), (c, d, b): h runs d -> c, g runs c -> d.
    corner_[h] = narrow(d);
    corner_[nh] = narrow(c);
    corner_[ph] = narrow(a);
    corner_[g] = narrow(c);
    corner_[ng] = narrow(d);
    corner_[pg] = narrow(b);
    set_twin(nh, t_ca);
    set_twin(ph, t_ad);
    set_twin(ng, t_db);
    set_twin(pg, t_bc);
    set_twin(h, g);
    v_out_[a] = narrow(ph);
    v_out_[b] = narrow(pg);
    v_out_[c] = narrow(nh);
    v_out_[d] = narrow(ng);
    return true;
}

inline Index HalfedgeMesh::split(Index h, Scalar t) {
    const Index g = twin(h);
    const Index a = source(h), b = target(h);
    const Index m = new_vertex();
    interpolate(m, a, b, t);
    // The face of e, (from, to, o), becomes (from, m, o) + the new face (m, to, o).
    auto cut = [&](Index e, Index to) {
        const Index o = opposite(e);
        const Index e1 = next(e);
        const Index te = twin(e1);
        corner_[e1] = narrow(m);
        const Index f = new_face(m, to, o);
        set_twin(3 * f + 1, te);
        set_twin(e1, 3 * f + 2);
        if (v_out_[to] == e1) v_out_[to] = narrow(3 * f + 1);
        return f;
    };
    const Index f1 = cut(h, b);  // (a, b, c) -> (a, m, c) + (m, b, c)
    v_out_[m] = narrow(3 * f1);
    if (g == invalid) return m;
    const Index f2 = cut(g, a);  // (b, a, d) -> (b, m, d) + (m, a, d)
    set_twin(h, 3 * f2);  // a -> m with m -> a
    set_twin(3 * f1, g);  // m -> b with b -> m
    return m;
}

inline bool HalfedgeMesh::can_collapse(Index h) const {
    if (is_removed_face(face(h))) return false;
    const Index g = twin(h);
    const Index a = source(h), b = target(h), c = opposite(h);
    const Index d = g == invalid ? invalid : opposite(g);
    if (g == invalid) {
        // A lone triangle would vanish to an edge.
        if (twin(next(h)) == invalid && twin(prev(h)) == invalid) return false;
    } else if (is_boundary_vertex(a) && is_boundary_vertex(b)) {
        return false;  // would pinch the boundary at the merged vertex
    }
    // Link condition on the vertices.
    std::vector<Index> ra, rb;
    vertex_ring(a, ra);
    vertex_ring(b, rb);
    std::sort(ra.begin(), ra.end());
    for (Index x : rb)
        if (x != c && x != d && std::binary_search(ra.begin(), ra.end(), x)) return false;
    // ... and on the edges: c-d in both links means a tetrahedron folding flat.
    if (d != invalid && has_face(a, c, d) && has_face(b, c, d)) return false;
    return true;
}

inline Index HalfedgeMesh::collapse(Index h, Scalar t) {
    if (!can_collapse(h)) return invalid;
    const Index g = twin(h);
    const Index a = source(h), b = target(h), c = opposite(h);
    std::vector<Index> out_a;
    outgoing_halfedges(a, out_a);
    interpolate(b, a, b, t);
    for (Index x : out_a) corner_[x] = narrow(b);
    // Face of h, (a, b, c): the twins of b -> c and c -> a meet.
    const Index t1 = twin(next(h)), t2 = twin(prev(h));  // c -> b, b -> c (was a -> c)
    set_twin(t1, t2);
    Index t3 = invalid, t4 = invalid, d = invalid;
    if (g != invalid) {
        d = opposite(g);
        t3 = twin(next(g));  // d -> b (was d -> a)
        t4 = twin(prev(g));  // b -> d
        set_twin(t3, t4);
    }
    auto remove_face = [&](Index f) {
        for (Index k = 0; k < 3; ++k) {
            corner_[3 * f + k] = nil;
            twin_[3 * f + k] = nil;
        }
        ++removed_faces_;
        free_faces_.push_back(f);
    };
    remove_face(face(h));
    if (g != invalid) remove_face(face(g));
    // New outgoing halfedges of b, c, d (theirs may have been in a removed face).
    Index ob = invalid;
    for (Index x : {t4, t2}) if (ob == invalid && x != invalid) ob = x;
    if (ob == invalid && t1 != invalid) ob = next(t1);
    if (ob == invalid && t3 != invalid) ob = next(t3);
    v_out_[b] = narrow(ob);
    v_out_[c] = narrow(t1 != invalid ? t1 : next(t2));
    if (d != invalid) v_out_[d] = narrow(t3 != invalid ? t3 : next(t4));
    v_out_[a] = nil;
    v_removed_[a] = 1;
    ++removed_vertices_;
    free_vertices_.push_back(a);
    return b;
}

inline std::string HalfedgeMesh::validate() const {
    const std::size_t nh = corner_.size();
    std::vector<std::size_t> out_count(v_out_.size(), 0);
    for (Index h = 0; h < nh; ++h) {
        if (is_removed_face(face(h))) {
            if (corner_[h] != nil) return "face " + std::to_string(face(h)) + " is half removed";
            continue;
        }
        const Index a = source(h), b = target(h);
        if (a >= v_out_.size() || v_removed_[a]) return "halfedge " + std::to_string(h) + " starts at a dead vertex";
        if (a == b) return "face " + std::to_string(face(h)) + " repeats vertex " + std::to_string(a);
        ++out_count[a];
        const Index g = twin(h);
        if (g != invalid) {
            if (g >= nh || is_removed_face(face(g))) return "halfedge " + std::to_string(h) + " has a dead twin";
            if (twin(g) != h) return "twins of halfedge " + std::to_string(h) + " disagree";
            if (source(g) != b || target(g) != a)
                return "halfedge " + std::to_string(h) + " and its twin do not run opposite ways";
        }
    }
    std::vector<Index> ring;
    for (Index v = 0; v < v_out_.size(); ++v) {
        if (v_removed_[v]) continue;
        const Index h = halfedge(v);
        if (h == invalid) {
            if (out_count[v] != 0) return "vertex " + std::to_string(v) + " has faces but no halfedge";
            continue;
        }
        if (is_removed_face(face(h)) || source(h) != v)
            return "vertex " + std::to_string(v) + " points to a halfedge that does not leave it";
        outgoing_halfedges(v, ring);
        if (ring.size() != out_count[v]) return "vertex " + std::to_string(v) + " has more than one fan";
        // A repeated neighbour is a duplicate edge.
        vertex_ring(v, ring);
        std::sort(ring.begin(), ring.end());
        if (std::adjacent_find(ring.begin(), ring.end()) != ring.end())
            return "vertex " + std::to_string(v) + " has a duplicate edge";
    }
    return {};
}

}  // namespace kintsugi
