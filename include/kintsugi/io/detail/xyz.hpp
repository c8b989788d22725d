// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file xyz.hpp
/// @brief XYZ and PWN point files: one point per line, `x y z` or `x y z nx ny nz`
/// (PWN, as CGAL writes it: always 6 numbers). '#' comments and blank lines are
/// skipped; a first line holding a single integer (a point count, as CGAL's reader
/// accepts) is skipped. Every line must have as many numbers as the first one.
/// See common.hpp for why kintsugi parses files itself.

#include <kintsugi/io/detail/common.hpp>
#include <kintsugi/io/detail/output_file.hpp>

#include <string>
#include <string_view>
#include <vector>

namespace kintsugi::detail::io {

inline RawGeometry read_xyz(const FileBuffer& buf, bool pwn, const std::string& path) {
    RawGeometry g = raw_geometry(pwn ? "pwn" : "xyz");
    TextLines lr(buf, path, pwn ? "PWN" : "XYZ");
    std::string_view line, s;
    std::size_t columns = 0;
    bool first = true;
    double v[6];
    while (lr.next(line)) {
        Tokens t(line);
        std::size_t n = 0;
        while (t.next(s)) {
            if (n < 6 && !parse_double(s, v[n]))
                throw lr.malformed(quote(s) + " is not a number");
            ++n;
        }
        if (first) {
            first = false;
            long long count = 0;
            if (n == 1 && parse_integer(line, count)) {
                note_ignored(g.info, "point count line");
                continue;
            }
        }
        if (columns == 0) {
            if (pwn ? n != 6 : (n != 3 && n != 6))
                throw lr.malformed(std::string("expected ") + (pwn ? "6 numbers (x y z nx ny nz)" :
                                                                 "3 numbers (x y z) or 6 (x y z nx ny nz)") +
                                         ", found " + std::to_string(n));
            columns = n;
        } else if (n != columns) {
            throw lr.malformed("found " + std::to_string(n) + " numbers, but the first point has " +
                                     std::to_string(columns));
        }
        const Vec3 p(v[0], v[1], v[2]);
        if (!all_finite(p))
            throw io_error(path, "line " + std::to_string(lr.line()) + ": point " + std::to_string(g.vertices.size()) +
                                     " has a non-finite coordinate (NaN or Inf)");
        g.vertices.push_back(p);
        if (columns == 6) {
            const Vec3 nrm(v[3], v[4], v[5]);
            if (!all_finite(nrm))
                throw io_error(path, "line " + std::to_string(lr.line()) + ": point " +
                                         std::to_string(g.vertices.size() - 1) + " has a non-finite normal (NaN or Inf)");
            g.normals.push_back(nrm);
        }
    }
    if (g.vertices.empty()) throw io_error(path, "no points: the file holds only comments or blank lines");
    finish(g);
    return g;
}

/// Writes `x y z [nx ny nz]` per line (also the vertex lines of OFF).
inline void write_xyz(AtomicOutputFile& out, const std::vector<Vec3>& points, const std::vector<Vec3>* normals) {
    const bool with_normals = normals && !normals->empty();
    for (std::size_t i = 0; i < points.size(); ++i) {
        out.put_triple(points[i]);
        if (with_normals) {
            out.put(' ');
            out.put_triple((*normals)[i]);
        }
        out.put('\n');
    }
}

}  // namespace kintsugi::detail::io
