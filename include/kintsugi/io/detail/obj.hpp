// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file obj.hpp
/// @brief Wavefront OBJ reader and writer (geometry only). See common.hpp for why
/// kintsugi parses files itself.
///
/// Read: `v x y z [w]` (or `v x y z r g b`), `vn`, and `f` with corners `v`, `v/t`,
/// `v//n`, `v/t/n`, negative (relative) indices, polygons. Per-vertex normals: when there
/// are as many `vn` as `v` and every corner that names a normal names the one with its
/// vertex's number (or none does), they pair up by order; otherwise a vertex takes the
/// normal its corners reference (the normalised mean of the unit normals when they
/// reference several), and the normals are dropped if some vertex has none. Normals are returned as
/// stored (MeshLab writes unnormalised ones). Every other statement (vt, l, g, o, s,
/// usemtl, mtllib, ...) is skipped and listed in ReadInfo::ignored_properties.

#include <kintsugi/io/detail/common.hpp>
#include <kintsugi/io/detail/output_file.hpp>

#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace kintsugi::detail::io {

inline RawGeometry read_obj(const FileBuffer& buf, const ReadOptions& options, const std::string& path) {
    RawGeometry g = raw_geometry("obj");
    TextLines lr(buf, path, "OBJ");
    std::string_view line, kw, s;
    std::vector<Vec3> vn;
    std::vector<std::pair<Index, Index>> corner_normals;  // (vertex, normal) as written by the faces
    std::vector<std::size_t> face_of_triangle, face_line;
    std::vector<Index> poly, poly_n;
    std::size_t n_faces = 0;
    // Resolves an OBJ index (1-based or negative = relative to the `count` defined so far).
    auto resolve = [&](std::string_view text, std::size_t count, const char* what) -> Index {
        long long i = 0;
        if (!parse_integer(text, i)) throw lr.malformed(quote(text) + " is not a " + what + " index");
        if (i == 0) throw lr.malformed(std::string(what) + " index 0 (OBJ indices start at 1)");
        if (i < 0) {
            const unsigned long long back = 0ULL - static_cast<unsigned long long>(i);  // -i, also for LLONG_MIN
            if (back > count)
                throw lr.malformed("relative " + std::string(what) + " index " + std::to_string(i) + " points before the first " +
                          what + " (only " + std::to_string(count) + " defined so far)");
            return count - static_cast<std::size_t>(back);
        }
        return static_cast<Index>(i - 1);
    };
    while (lr.next(line)) {
        Tokens t(line);
        t.next(kw);
        if (kw == "v" || kw == "vn") {
            double v[3];
            for (int k = 0; k < 3; ++k) {
                if (!t.next(s)) throw lr.malformed("'" + std::string(kw) + "' needs 3 numbers");
                if (!parse_double(s, v[k])) throw lr.malformed(quote(s) + " is not a number");
            }
            const Vec3 p(v[0], v[1], v[2]);
            if (kw == "v") {
                if (!all_finite(p)) throw lr.malformed(vertex_where(g.vertices.size(), 0) + " has a non-finite coordinate (NaN or Inf)");
                g.vertices.push_back(p);
                int extra = 0;
                while (t.next(s)) ++extra;
                if (extra >= 3) note_ignored(g.info, "vertex colors");
            } else {
                if (!all_finite(p)) throw lr.malformed("normal " + std::to_string(vn.size()) + " is not finite (NaN or Inf)");
                vn.push_back(p);
            }
        } else if (kw == "f") {
            poly.clear();
            poly_n.clear();
            bool any_normal = false;
            while (t.next(s)) {
                const std::size_t slash1 = s.find('/');
                const std::string_view vpart = s.substr(0, slash1);
                poly.push_back(resolve(vpart, g.vertices.size(), "vertex"));
                Index ni = static_cast<Index>(-1);
                if (slash1 != std::string_view::npos) {
                    const std::size_t slash2 = s.find('/', slash1 + 1);
                    if (slash2 != std::string_view::npos) {
                        const std::string_view npart = s.substr(slash2 + 1);
                        if (!npart.empty()) {
                            ni = resolve(npart, vn.size(), "normal");
                            any_normal = true;
                        }
                    }
                    if (slash2 != slash1 + 1) note_ignored(g.info, "vt");
                }
                poly_n.push_back(ni);
            }
            const std::size_t before = g.faces.size();
            add_polygon(g, poly, options, path, n_faces, lr.line(), static_cast<std::size_t>(-1), &face_of_triangle);
            for (std::size_t k = before; k < g.faces.size(); ++k) face_line.push_back(lr.line());
            if (any_normal)
                for (std::size_t k = 0; k < poly.size(); ++k)
                    if (poly_n[k] != static_cast<Index>(-1)) {
                        if (poly_n[k] >= vn.size())
                            throw lr.malformed("normal index " + std::to_string(poly_n[k] + 1) + " is out of range: " +
                                      std::to_string(vn.size()) + " normals defined so far");
                        corner_normals.emplace_back(poly[k], poly_n[k]);
                    }
            ++n_faces;
        } else {
            note_ignored(g.info, std::string(kw));
        }
    }
    const std::size_t nv = g.vertices.size();
    if (nv == 0 && n_faces == 0) throw io_error(path, "not an OBJ file: it holds no 'v' or 'f' statements");
    for (std::size_t tri = 0; tri < g.faces.size(); ++tri)
        for (const Index v : g.faces[tri])
            if (v >= nv)
                throw io_error(path, face_where(face_of_triangle[tri], face_line[tri]) + " uses vertex " +
                                         std::to_string(v + 1) + ", out of range: the file has " +
                                         std::to_string(nv) + " vertices");
    // Per-vertex normals.
    bool paired_by_order = !vn.empty() && vn.size() == nv;
    for (const auto& [v, n] : corner_normals) paired_by_order = paired_by_order && v == n;
    if (paired_by_order) {
        g.normals = std::move(vn);  // `f a//a b//b c//c` (MeshLab, kintsugi) or no face references
    } else if (!corner_normals.empty()) {
        constexpr Index none = static_cast<Index>(-1), several = static_cast<Index>(-2);
        std::vector<Index> which(nv, none);
        for (const auto& [v, n] : corner_normals) {
            if (which[v] == none) which[v] = n;
            else if (which[v] != n) which[v] = several;
        }
        bool complete = true;
        for (const Index w : which) complete = complete && w != none;
        if (complete) {
            g.normals.assign(nv, Vec3::Zero());
            for (std::size_t v = 0; v < nv; ++v)
                if (which[v] != several) g.normals[v] = vn[which[v]];
            for (const auto& [v, n] : corner_normals)
                if (which[v] == several) {
                    const Scalar len = vn[n].norm();
                    if (len > 0) g.normals[v] += vn[n] / len;
                }
            for (std::size_t v = 0; v < nv; ++v)
                if (which[v] == several) {
                    const Scalar len = g.normals[v].norm();
                    if (len > 0) g.normals[v] /= len;
                }
        } else {
            note_ignored(g.info, "vn (not given for every vertex)");
        }
    } else if (!vn.empty()) {
        note_ignored(g.info, "vn (count differs from v)");
    }
    finish(g);
    return g;
}

/// Writes OBJ: `v`, `vn` (with normals), `f a//a b//b c//c` or `f a b c`.
inline void write_obj(AtomicOutputFile& out, const std::vector<Vec3>& vertices, const std::vector<Vec3>* normals,
                      const std::vector<Face>* faces, const std::vector<std::array<Index, 2>>* edges = nullptr) {
    const bool with_normals = normals && !normals->empty();
    out.write("# written by kintsugi\n");
    for (const Vec3& p : vertices) {
        out.write("v ");
        out.put_triple(p);
        out.put('\n');
    }
    if (with_normals)
        for (const Vec3& n : *normals) {
            out.write("vn ");
            out.put_triple(n);
            out.put('\n');
        }
    if (faces)
        for (const Face& f : *faces) {
            out.put('f');
            for (const Index v : f) {
                out.put(' ');
                out.put_uint(v + 1);
                if (with_normals) {
                    out.write("//");
                    out.put_uint(v + 1);
                }
            }
            out.put('\n');
        }
    if (edges)
        for (const auto& e : *edges) {
            out.write("l ");
            out.put_uint(e[0] + 1);
            out.put(' ');
            out.put_uint(e[1] + 1);
            out.put('\n');
        }
}

}  // namespace kintsugi::detail::io
