// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file off.hpp
/// @brief OFF reader and writer (Geomview OFF with the ST/C/N prefixes: OFF, NOFF, COFF,
/// CNOFF, STOFF...; '#' comments). See common.hpp for why kintsugi parses files itself.
///
/// A vertex line is `x y z [nx ny nz] [colour] [s t]`; a face line is
/// `k i0 ... i(k-1) [colour]`. Colours and texture coordinates are skipped and listed in
/// ReadInfo::ignored_properties. 4OFF / nOFF (other dimensions) and binary OFF are rejected.

#include <kintsugi/io/detail/common.hpp>
#include <kintsugi/io/detail/output_file.hpp>
#include <kintsugi/io/detail/xyz.hpp>

#include <string>
#include <string_view>
#include <vector>

namespace kintsugi::detail::io {

inline RawGeometry read_off(const FileBuffer& buf, const ReadOptions& options, const std::string& path) {
    RawGeometry g = raw_geometry("off");
    TextLines lr(buf, path, "OFF");
    std::string_view line;
    if (!lr.next(line)) throw io_error(path, "not an OFF file: it holds only comments or blank lines");
    std::vector<std::string_view> tok;
    Tokens(line).all(tok);
    const std::string_view kw = tok[0];
    if (kw.size() < 3 || kw.substr(kw.size() - 3) != "OFF")
        throw io_error(path, "not an OFF file: the first line must be 'OFF' (or NOFF, COFF, CNOFF, STOFF...), not " +
                                 quote(kw));
    bool normals = false, colours = false, texture = false;
    std::string_view prefix = kw.substr(0, kw.size() - 3);
    if (prefix.substr(0, 2) == "ST") {
        texture = true;
        prefix.remove_prefix(2);
    }
    if (!prefix.empty() && prefix.front() == 'C') {
        colours = true;
        prefix.remove_prefix(1);
    }
    if (!prefix.empty() && prefix.front() == 'N') {
        normals = true;
        prefix.remove_prefix(1);
    }
    if (!prefix.empty()) {
        if (prefix.front() == '4' || prefix.front() == 'n')
            throw lr.malformed(quote(kw) + ": only 3D OFF files are supported (no 4OFF or nOFF)");
        throw lr.malformed("unknown header keyword " + quote(kw));
    }
    std::vector<std::string_view> counts(tok.begin() + 1, tok.end());
    if (!counts.empty() && counts[0] == "BINARY") throw lr.malformed("binary OFF is not supported; convert it to text OFF or PLY");
    if (counts.empty()) {
        if (!lr.next(line)) throw io_error(path, "truncated OFF: the file ends before the vertex and face counts");
        Tokens(line).all(counts);
    }
    long long nv = -1, nf = -1;
    if (counts.size() < 2 || !parse_integer(counts[0], nv) || !parse_integer(counts[1], nf) || nv < 0 || nf < 0)
        throw lr.malformed("expected the counts '<vertices> <faces> [<edges>]'");
    // A vertex line takes at least "0 0 0\n", a face line "0\n" (a face of fewer than 3
    // vertices is reported by add_polygon(), not as a truncation).
    const std::size_t remaining = lr.remaining() + 1;
    if (static_cast<unsigned long long>(nv) > remaining / 6 ||
        static_cast<unsigned long long>(nf) > (remaining - static_cast<std::size_t>(nv) * 6) / 2)
        throw io_error(path, "truncated OFF: the header declares " + std::to_string(nv) + " vertices and " +
                                 std::to_string(nf) + " faces, but only " + std::to_string(lr.remaining()) +
                                 " bytes follow");
    const std::size_t n_vertices = static_cast<std::size_t>(nv), n_faces = static_cast<std::size_t>(nf);
    if (colours) note_ignored(g.info, "vertex colors");
    if (texture) note_ignored(g.info, "texture coordinates");
    g.vertices.reserve(n_vertices);
    if (normals) g.normals.reserve(n_vertices);
    const std::size_t need = normals ? 6 : 3;
    for (std::size_t i = 0; i < n_vertices; ++i) {
        if (!lr.next(line))
            throw io_error(path, "truncated OFF: the file ends after " + std::to_string(i) + " of " +
                                     std::to_string(n_vertices) + " vertices");
        Tokens t(line);
        double v[6];
        std::string_view s;
        for (std::size_t k = 0; k < need; ++k) {
            if (!t.next(s))
                throw lr.malformed(vertex_where(i, 0) + " has " + std::to_string(k) + " numbers, expected at least " +
                          std::to_string(need));
            if (!parse_double(s, v[k])) throw lr.malformed(quote(s) + " is not a number (" + vertex_where(i, 0) + ")");
        }
        const Vec3 p(v[0], v[1], v[2]);
        if (!all_finite(p)) throw lr.malformed(vertex_where(i, 0) + " has a non-finite coordinate (NaN or Inf)");
        g.vertices.push_back(p);
        if (normals) {
            const Vec3 n(v[3], v[4], v[5]);
            if (!all_finite(n)) throw lr.malformed(vertex_where(i, 0) + " has a non-finite normal (NaN or Inf)");
            g.normals.push_back(n);
        }
        if (t.next(s) && !colours && !texture) note_ignored(g.info, "extra vertex values");
    }
    g.faces.reserve(std::min(n_faces, remaining / 8));  // a triangle line takes at least "3 0 1 2\n"
    std::vector<Index> poly;
    for (std::size_t f = 0; f < n_faces; ++f) {
        if (!lr.next(line))
            throw io_error(path, "truncated OFF: the file ends after " + std::to_string(f) + " of " +
                                     std::to_string(n_faces) + " faces");
        Tokens t(line);
        std::string_view s;
        long long k = -1;
        t.next(s);
        if (!parse_integer(s, k) || k < 0) throw lr.malformed(face_where(f, 0) + " does not start with a vertex count");
        const std::size_t declared = static_cast<std::size_t>(k);
        poly.clear();  // grows with the indices listed, not with the declared count
        while (poly.size() < declared && t.next(s)) {
            long long idx = -1;
            if (!parse_integer(s, idx)) throw lr.malformed(quote(s) + " is not a vertex index (" + face_where(f, 0) + ")");
            if (idx < 0) throw lr.malformed(face_where(f, 0) + " uses a negative vertex index " + std::to_string(idx));
            poly.push_back(static_cast<Index>(idx));
        }
        if (poly.size() < declared)
            throw lr.malformed(face_where(f, 0) + " declares " + std::to_string(k) + " vertices but lists " +
                      std::to_string(poly.size()));
        if (t.next(s)) note_ignored(g.info, "face colors");
        add_polygon(g, poly, options, path, f, lr.line(), n_vertices, nullptr);
    }
    finish(g);
    return g;
}

/// Writes OFF (NOFF with normals): vertices, then triangles (none for a point set).
inline void write_off(AtomicOutputFile& out, const std::vector<Vec3>& vertices, const std::vector<Vec3>* normals,
                      const std::vector<Face>* faces) {
    const bool with_normals = normals && !normals->empty();
    out.write(with_normals ? "NOFF\n" : "OFF\n");
    out.put_uint(vertices.size());
    out.put(' ');
    out.put_uint(faces ? faces->size() : 0);
    out.write(" 0\n");
    write_xyz(out, vertices, normals);
    if (faces)
        for (const Face& f : *faces) {
            out.write("3 ");
            out.put_triple(f);
            out.put('\n');
        }
}

}  // namespace kintsugi::detail::io
