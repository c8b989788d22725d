// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file ply.hpp
/// @brief PLY reader and writer (ascii, binary little- and big-endian). See common.hpp
/// for why kintsugi parses files itself.
///
/// Read: element `vertex` with x y z (any PLY scalar type), optional nx ny nz and
/// `radius`; element `face` with a list `vertex_indices` or `vertex_index` (any count and
/// index integer types). Every other property and element is skipped and listed in
/// ReadInfo::ignored_properties as "element.property". Counts from the header are
/// checked against the bytes that follow before anything is allocated.

#include <kintsugi/io/detail/common.hpp>
#include <kintsugi/io/detail/output_file.hpp>

#include <array>
#include <bit>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <type_traits>
#include <unordered_set>
#include <vector>

namespace kintsugi::detail::io {

enum class PlyType : std::uint8_t { i8, u8, i16, u16, i32, u32, f32, f64 };

[[nodiscard]] inline std::size_t ply_size(PlyType t) {
    switch (t) {
        case PlyType::i8:
        case PlyType::u8: return 1;
        case PlyType::i16:
        case PlyType::u16: return 2;
        case PlyType::i32:
        case PlyType::u32:
        case PlyType::f32: return 4;
        case PlyType::f64: return 8;
    }
    return 0;
}
[[nodiscard]] inline bool ply_is_integer(PlyType t) { return t != PlyType::f32 && t != PlyType::f64; }
[[nodiscard]] inline bool ply_type_from_name(std::string_view s, PlyType& t) {
    struct Entry {
        std::string_view name;
        PlyType type;
    };
    static constexpr Entry table[] = {
        {"char", PlyType::i8},    {"int8", PlyType::i8},     {"uchar", PlyType::u8},   {"uint8", PlyType::u8},
        {"short", PlyType::i16},  {"int16", PlyType::i16},   {"ushort", PlyType::u16}, {"uint16", PlyType::u16},
        {"int", PlyType::i32},    {"int32", PlyType::i32},   {"uint", PlyType::u32},   {"uint32", PlyType::u32},
        {"float", PlyType::f32},  {"float32", PlyType::f32}, {"double", PlyType::f64}, {"float64", PlyType::f64},
    };
    for (const Entry& e : table)
        if (e.name == s) {
            t = e.type;
            return true;
        }
    return false;
}

/// What a property is used for.
enum class PlyRole : std::uint8_t { ignored, x, y, z, nx, ny, nz, radius, indices };

struct PlyProperty {
    std::string name;
    PlyType type = PlyType::f32;  ///< value type (item type for lists)
    bool is_list = false;
    PlyType count_type = PlyType::u8;
    PlyRole role = PlyRole::ignored;
};

struct PlyElement {
    std::string name;
    std::uint64_t count = 0;
    std::vector<PlyProperty> props;
    std::size_t header_line = 0;
};

enum class PlyFormat { ascii, binary_le, binary_be };

struct PlyHeader {
    PlyFormat format = PlyFormat::ascii;
    std::vector<PlyElement> elements;
    std::size_t body_offset = 0;   ///< first byte after the end_header line
    std::size_t body_first_line = 0;  ///< line number of the first body line (ascii)
};

/// Parses and checks the header; assigns roles to the properties.
inline PlyHeader parse_ply_header(const FileBuffer& buf, const std::string& path, ReadInfo& info) {
    PlyHeader h;
    const char* p = text_begin(buf, path);
    const char* end = buf.end();
    auto bad = [&](std::size_t line, const std::string& what) -> io_error {
        return io_error(path, "malformed PLY header (line " + std::to_string(line) + "): " + what);
    };
    // The header's lines end as its first line does: LF or CRLF (then a CR before the
    // LF is dropped), or a lone CR (old Mac). The body starts right after the terminator
    // of 'end_header', so a binary body starting with byte 0x0A is not misread as an LF.
    if (static_cast<std::size_t>(end - p) < 4 || std::string_view(p, 3) != "ply" || (p[3] != '\n' && p[3] != '\r'))
        throw io_error(path, "not a PLY file: the first line is not 'ply'");
    const char eol = p[3] == '\r' && (static_cast<std::size_t>(end - p) < 5 || p[4] != '\n') ? '\r' : '\n';
    std::size_t line_no = 0;
    bool have_format = false, done = false;
    std::vector<std::string_view> tok;
    std::unordered_set<std::string_view> element_names;  // views into `buf`
    while (p < end && !done) {
        const char* nl = static_cast<const char*>(std::memchr(p, eol, static_cast<std::size_t>(end - p)));
        if (!nl) throw io_error(path, "malformed PLY header: no 'end_header' line");
        std::string_view line(p, static_cast<std::size_t>(nl - p));
        p = nl + 1;
        ++line_no;
        if (eol == '\n' && !line.empty() && line.back() == '\r') line.remove_suffix(1);
        if (line_no == 1) continue;  // 'ply', checked above
        Tokens(line).all(tok);
        if (tok.empty()) continue;
        const std::string_view kw = tok[0];
        if (kw == "comment" || kw == "obj_info") continue;
        if (kw == "end_header") {
            done = true;
        } else if (kw == "format") {
            if (tok.size() < 2) throw bad(line_no, "'format' needs a value");
            if (tok[1] == "ascii") h.format = PlyFormat::ascii;
            else if (tok[1] == "binary_little_endian") h.format = PlyFormat::binary_le;
            else if (tok[1] == "binary_big_endian") h.format = PlyFormat::binary_be;
            else throw bad(line_no, "unknown format " + quote(tok[1]));
            have_format = true;
        } else if (kw == "element") {
            if (tok.size() != 3) throw bad(line_no, "expected 'element <name> <count>'");
            PlyElement e;
            e.name = std::string(tok[1]);
            long long count = -1;
            if (!parse_integer(tok[2], count) || count < 0)
                throw bad(line_no, "element count " + quote(tok[2]) + " is not a non-negative integer");
            e.count = static_cast<std::uint64_t>(count);
            e.header_line = line_no;
            if (!element_names.insert(tok[1]).second)  // a set: a header of many elements stays linear
                throw bad(line_no, "element " + quote(e.name) + " is declared twice");
            h.elements.push_back(std::move(e));
        } else if (kw == "property") {
            if (h.elements.empty()) throw bad(line_no, "'property' before any 'element'");
            PlyProperty prop;
            if (tok.size() >= 2 && tok[1] == "list") {
                if (tok.size() != 5) throw bad(line_no, "expected 'property list <count type> <item type> <name>'");
                if (!ply_type_from_name(tok[2], prop.count_type)) throw bad(line_no, "unknown type " + quote(tok[2]));
                if (!ply_type_from_name(tok[3], prop.type)) throw bad(line_no, "unknown type " + quote(tok[3]));
                if (!ply_is_integer(prop.count_type))
                    throw bad(line_no, "the count type of a list must be an integer type, not " + quote(tok[2]));
                prop.is_list = true;
                prop.name = std::string(tok[4]);
            } else {
                if (tok.size() != 3) throw bad(line_no, "expected 'property <type> <name>'");
                if (!ply_type_from_name(tok[1], prop.type)) throw bad(line_no, "unknown type " + quote(tok[1]));
                prop.name = std::string(tok[2]);
            }
            h.elements.back().props.push_back(std::move(prop));
        } else {
            throw bad(line_no, "unknown keyword " + quote(kw));
        }
    }
    if (!done) throw io_error(path, "malformed PLY header: no 'end_header' line");
    if (!have_format) throw io_error(path, "malformed PLY header: no 'format' line");
    h.body_offset = static_cast<std::size_t>(p - buf.begin());
    h.body_first_line = line_no + 1;

    // Roles.
    bool have_vertex = false;
    for (PlyElement& e : h.elements) {
        if (e.props.empty() && e.count > 0)
            throw bad(e.header_line, "element " + quote(e.name) + " has no properties");
        if (e.name == "vertex") {
            have_vertex = true;
            int found[8] = {};
            auto role_of = [](std::string_view n) {
                if (n == "x") return PlyRole::x;
                if (n == "y") return PlyRole::y;
                if (n == "z") return PlyRole::z;
                if (n == "nx") return PlyRole::nx;
                if (n == "ny") return PlyRole::ny;
                if (n == "nz") return PlyRole::nz;
                if (n == "radius") return PlyRole::radius;
                return PlyRole::ignored;
            };
            for (PlyProperty& prop : e.props) {
                if (prop.is_list) continue;
                const PlyRole r = role_of(prop.name);
                if (r == PlyRole::ignored) continue;
                if (found[static_cast<int>(r)]++)
                    throw bad(e.header_line, "vertex property " + quote(prop.name) + " is declared twice");
                prop.role = r;
            }
            if (!found[1] || !found[2] || !found[3])
                throw bad(e.header_line, "the vertex element needs scalar properties x, y and z");
            const bool normals = found[4] && found[5] && found[6];
            for (PlyProperty& prop : e.props) {
                if (!normals && (prop.role == PlyRole::nx || prop.role == PlyRole::ny || prop.role == PlyRole::nz))
                    prop.role = PlyRole::ignored;  // an incomplete normal is not a normal
                if (prop.role == PlyRole::ignored) note_ignored(info, "vertex." + prop.name);
            }
        } else if (e.name == "face") {
            bool found = false;
            for (PlyProperty& prop : e.props) {
                if (!found && prop.is_list && (prop.name == "vertex_indices" || prop.name == "vertex_index")) {
                    if (!ply_is_integer(prop.type))
                        throw bad(e.header_line, "face indices must have an integer type");
                    prop.role = PlyRole::indices;
                    found = true;
                } else {
                    note_ignored(info, "face." + prop.name);
                }
            }
            if (!found)
                throw bad(e.header_line, "the face element has no list property 'vertex_indices' or 'vertex_index'");
        } else {
            for (const PlyProperty& prop : e.props) note_ignored(info, e.name + "." + prop.name);
        }
    }
    if (!have_vertex) throw io_error(path, "malformed PLY header: no 'vertex' element");
    return h;
}

// ------------------------------------------------------------------ binary body

template <class T, bool Swap>
[[nodiscard]] inline T ply_load(const char* p) {
    char b[sizeof(T)];
    std::memcpy(b, p, sizeof(T));
    if constexpr (Swap) std::reverse(b, b + sizeof(T));
    T v;
    std::memcpy(&v, b, sizeof(T));
    return v;
}

/// Loads the value of PLY type `t` at `p` as type R (an integer type gives -1 for a
/// floating-point `t`; integer types are checked in the header).
template <class R, bool Swap>
[[nodiscard]] inline R ply_load_as(const char* p, PlyType t) {
    auto as = [&](auto tag) -> R {
        using T = decltype(tag);
        if constexpr (std::is_integral_v<R> && !std::is_integral_v<T>)
            return -1;
        else
            return static_cast<R>(ply_load<T, Swap>(p));
    };
    switch (t) {
        case PlyType::i8: return as(std::int8_t{});
        case PlyType::u8: return as(std::uint8_t{});
        case PlyType::i16: return as(std::int16_t{});
        case PlyType::u16: return as(std::uint16_t{});
        case PlyType::i32: return as(std::int32_t{});
        case PlyType::u32: return as(std::uint32_t{});
        case PlyType::f32: return as(float{});
        case PlyType::f64: return as(double{});
    }
    return 0;
}

template <bool Swap>
[[nodiscard]] inline double ply_load_double(const char* p, PlyType t) {
    return ply_load_as<double, Swap>(p, t);
}

template <bool Swap>
[[nodiscard]] inline long long ply_load_integer(const char* p, PlyType t) {
    return ply_load_as<long long, Swap>(p, t);
}

/// Per-vertex values collected from one item.
struct PlyVertexValues {
    double v[8] = {};
};

/// Stores the values of one vertex (checks finiteness).
inline void ply_store_vertex(RawGeometry& g, const PlyVertexValues& val, bool normals, bool radius, std::size_t i,
                             std::size_t line, const std::string& path) {
    const Vec3 p(val.v[1], val.v[2], val.v[3]);
    if (!all_finite(p))
        throw io_error(path, vertex_where(i, line) + " has a non-finite coordinate (NaN or Inf)");
    g.vertices.push_back(p);
    if (normals) {
        const Vec3 n(val.v[4], val.v[5], val.v[6]);
        if (!all_finite(n)) throw io_error(path, vertex_where(i, line) + " has a non-finite normal (NaN or Inf)");
        g.normals.push_back(n);
    }
    if (radius) {
        if (!std::isfinite(val.v[7])) throw io_error(path, vertex_where(i, line) + " has a non-finite radius");
        g.radii.push_back(val.v[7]);
    }
}

/// Type of the `radius` property of a vertex element (f32 when absent).
[[nodiscard]] inline PlyType radius_type(const PlyElement& e) {
    for (const PlyProperty& prop : e.props)
        if (prop.role == PlyRole::radius) return prop.type;
    return PlyType::f32;
}

/// What a vertex element holds besides positions.
struct PlyVertexData {
    bool normals = false, radius = false;
};

/// What vertex element `e` holds, with g's arrays reserved for its `count` vertices.
inline PlyVertexData ply_reserve_vertices(const PlyElement& e, std::size_t count, RawGeometry& g) {
    PlyVertexData has;
    for (const PlyProperty& prop : e.props) {
        has.normals = has.normals || prop.role == PlyRole::nx;
        has.radius = has.radius || prop.role == PlyRole::radius;
    }
    g.vertices.reserve(count);
    if (has.normals) g.normals.reserve(count);
    if (has.radius) g.radii.reserve(count);
    return has;
}

[[nodiscard]] inline io_error ply_truncated(const std::string& path, const PlyElement& e, std::uint64_t item) {
    return io_error(path, "truncated PLY body: the file ends inside " + shown(e.name) + " " + std::to_string(item) +
                              " of " + std::to_string(e.count) + " declared in the header");
}

/// Walks one item of element `e` (number `item`) in a binary body, advancing `p`: each scalar
/// property goes to `on_scalar(prop, at)`, each list to `on_list(prop, n, first)` once its `n`
/// items are known to be in the file; `on_negative(n)` may throw its own message for a negative
/// count first (else a negative count, like a short file, is a truncation).
template <bool Swap, class OnScalar, class OnList, class OnNegative>
inline void ply_binary_item(const char*& p, const char* const end, const PlyElement& e, std::size_t item,
                            const std::string& path, OnScalar&& on_scalar, OnList&& on_list,
                            OnNegative&& on_negative) {
    for (const PlyProperty& prop : e.props) {
        if (prop.is_list) {
            const std::size_t cs = ply_size(prop.count_type);
            if (static_cast<std::size_t>(end - p) < cs) throw ply_truncated(path, e, item);
            const long long n = ply_load_integer<Swap>(p, prop.count_type);
            p += cs;
            const std::size_t is = ply_size(prop.type);
            if (n < 0) on_negative(n);
            if (n < 0 || static_cast<std::size_t>(n) > static_cast<std::size_t>(end - p) / is)
                throw ply_truncated(path, e, item);
            on_list(prop, static_cast<std::size_t>(n), static_cast<const char*>(p));
            p += static_cast<std::size_t>(n) * is;
        } else {
            const std::size_t s = ply_size(prop.type);
            if (static_cast<std::size_t>(end - p) < s) throw ply_truncated(path, e, item);
            on_scalar(prop, static_cast<const char*>(p));
            p += s;
        }
    }
}

template <bool Swap>
inline void ply_read_binary_body(const FileBuffer& buf, const PlyHeader& h, const ReadOptions& options,
                                 const std::string& path, RawGeometry& g) {
    const char* p = buf.begin() + h.body_offset;
    const char* const end = buf.end();
    bool vertices_done = false;
    std::vector<std::size_t> face_of_triangle;
    bool deferred_faces = false;
    std::vector<Index> poly;
    for (const PlyElement& e : h.elements) {
        // Smallest possible size of one item, to bound the count before allocating (a face
        // may list fewer than 3 vertices: add_polygon() says so, it is not a truncation);
        // and the size of one with triangles, to bound what is reserved.
        std::size_t min_size = 0, triangle_size = 0;
        bool fixed = true;
        for (const PlyProperty& prop : e.props) {
            if (prop.is_list) {
                fixed = false;
                min_size += ply_size(prop.count_type);
                triangle_size += ply_size(prop.count_type) + (prop.role == PlyRole::indices ? 3 * ply_size(prop.type) : 0);
            } else {
                min_size += ply_size(prop.type);
                triangle_size += ply_size(prop.type);
            }
        }
        const std::size_t remaining = static_cast<std::size_t>(end - p);
        if (min_size > 0 && e.count > remaining / min_size)
            throw io_error(path, "truncated PLY body: the header declares " + std::to_string(e.count) + " " + shown(e.name) +
                                     " elements of at least " + std::to_string(min_size) + " bytes each, but only " +
                                     std::to_string(remaining) + " bytes follow the header");
        const std::size_t count = static_cast<std::size_t>(e.count);
        if (e.name == "vertex") {
            const PlyVertexData has = ply_reserve_vertices(e, count, g);
            const bool normals = has.normals, radius = has.radius;
            PlyVertexValues val;
            if (fixed) {
                // Fast path: fixed stride, offsets precomputed, bounds checked once above.
                struct Slot {
                    std::size_t offset;
                    PlyType type;
                    int role;
                };
                std::vector<Slot> slots;
                std::size_t off = 0;
                for (const PlyProperty& prop : e.props) {
                    if (prop.role != PlyRole::ignored) slots.push_back({off, prop.type, static_cast<int>(prop.role)});
                    off += ply_size(prop.type);
                }
                const std::size_t stride = off;
                // All of x y z (and nx ny nz) of one type, as nearly every file has: typed loads,
                // no per-value dispatch (bench_io: 2x faster than the generic loop below).
                std::size_t off_of[8] = {};
                bool uniform = true;
                const PlyType t0 = slots.front().type;
                for (const Slot& s : slots) {
                    off_of[s.role] = s.offset;
                    if (s.role <= static_cast<int>(PlyRole::nz)) uniform = uniform && s.type == t0;
                }
                const PlyType rtype = radius_type(e);
                auto typed = [&](auto tag) {
                    using T = decltype(tag);
                    const int last = normals ? 6 : 3;
                    for (std::size_t i = 0; i < count; ++i, p += stride) {
                        for (int r = 1; r <= last; ++r) val.v[r] = static_cast<double>(ply_load<T, Swap>(p + off_of[r]));
                        if (radius) val.v[7] = ply_load_double<Swap>(p + off_of[7], rtype);
                        ply_store_vertex(g, val, normals, radius, i, 0, path);
                    }
                };
                if (uniform && t0 == PlyType::f32) {
                    typed(float{});
                } else if (uniform && t0 == PlyType::f64) {
                    typed(double{});
                } else {
                    for (std::size_t i = 0; i < count; ++i, p += stride) {
                        for (const Slot& s : slots) val.v[s.role] = ply_load_double<Swap>(p + s.offset, s.type);
                        ply_store_vertex(g, val, normals, radius, i, 0, path);
                    }
                }
            } else {
                for (std::size_t i = 0; i < count; ++i) {
                    ply_binary_item<Swap>(
                        p, end, e, i, path,
                        [&](const PlyProperty& prop, const char* at) {
                            if (prop.role != PlyRole::ignored)
                                val.v[static_cast<int>(prop.role)] = ply_load_double<Swap>(at, prop.type);
                        },
                        [](const PlyProperty&, std::size_t, const char*) {}, [](long long) {});
                    ply_store_vertex(g, val, normals, radius, i, 0, path);
                }
            }
            vertices_done = true;
        } else if (e.name == "face") {
            const std::size_t nv_known = vertices_done ? g.vertices.size() : static_cast<std::size_t>(-1);
            deferred_faces = !vertices_done;
            g.faces.reserve(std::min(count, remaining / triangle_size));
            for (std::size_t f = 0; f < count; ++f) {
                ply_binary_item<Swap>(
                    p, end, e, f, path, [](const PlyProperty&, const char*) {},
                    [&](const PlyProperty& prop, std::size_t n, const char* at) {
                        if (prop.role != PlyRole::indices) return;
                        const std::size_t is = ply_size(prop.type);
                        poly.resize(n);
                        for (std::size_t k = 0; k < n; ++k, at += is) {
                            const long long idx = ply_load_integer<Swap>(at, prop.type);
                            if (idx < 0)
                                throw io_error(path, face_where(f, 0) + " uses a negative vertex index " +
                                                         std::to_string(idx));
                            poly[k] = static_cast<Index>(idx);
                        }
                        add_polygon(g, poly, options, path, f, 0, nv_known, deferred_faces ? &face_of_triangle : nullptr);
                    },
                    [&](long long n) {
                        throw io_error(path, face_where(f, 0) + " has a negative vertex count " + std::to_string(n));
                    });
            }
        } else if (fixed) {
            p += count * min_size;  // checked against the remaining bytes above
        } else {
            for (std::size_t i = 0; i < count; ++i)
                ply_binary_item<Swap>(
                    p, end, e, i, path, [](const PlyProperty&, const char*) {},
                    [](const PlyProperty&, std::size_t, const char*) {}, [](long long) {});
        }
    }
    if (deferred_faces) check_face_indices(g, face_of_triangle, path);
}

// ------------------------------------------------------------------ ascii body

/// Whitespace-separated tokens across lines, with line numbers (lines end at LF, CRLF or
/// a lone CR).
class AsciiCursor : public TextPosition {
public:
    AsciiCursor(const char* b, const char* e, std::size_t line) : TextPosition(b, e, line) {}
    bool next(std::string_view& out) {
        while (p_ < end_ && is_space(*p_)) {
            if (*p_ == '\n' || (*p_ == '\r' && (p_ + 1 == end_ || p_[1] != '\n'))) ++line_;
            ++p_;
        }
        if (p_ == end_) return false;
        const char* b = p_;
        while (p_ < end_ && !is_space(*p_)) ++p_;
        out = std::string_view(b, static_cast<std::size_t>(p_ - b));
        return true;
    }
};

inline void ply_read_ascii_body(const FileBuffer& buf, const PlyHeader& h, const ReadOptions& options,
                                const std::string& path, RawGeometry& g) {
    AsciiCursor cur(buf.begin() + h.body_offset, buf.end(), h.body_first_line);
    bool vertices_done = false, deferred_faces = false;
    std::vector<std::size_t> face_of_triangle;
    std::vector<Index> poly;
    std::string_view tok;
    for (const PlyElement& e : h.elements) {
        // Fewest tokens of one item (a list may be empty: a face of fewer than 3 vertices is
        // reported by add_polygon(), not as a truncation), and of one with triangles.
        std::size_t min_tokens = e.props.size(), triangle_tokens = 0;
        for (const PlyProperty& prop : e.props) triangle_tokens += prop.role == PlyRole::indices ? 4 : 1;
        // Every token takes at least one character and one separator (but the very last).
        const std::size_t remaining = cur.remaining() + 1;
        if (min_tokens > 0 && e.count > remaining / (2 * min_tokens))
            throw io_error(path, "truncated PLY body: the header declares " + std::to_string(e.count) + " " + shown(e.name) +
                                     " elements but only " + std::to_string(cur.remaining()) +
                                     " bytes of text follow the header");
        const std::size_t count = static_cast<std::size_t>(e.count);
        auto next_token = [&](std::size_t item) {
            if (!cur.next(tok)) throw ply_truncated(path, e, item);
        };
        auto number = [&](std::size_t item, const PlyProperty& prop) {
            double d = 0;
            if (!parse_double(tok, d))
                throw io_error(path, "line " + std::to_string(cur.line()) + ": " + quote(tok) + " is not a number (" +
                                         shown(e.name) + " " + std::to_string(item) + ", property " + shown(prop.name) + ")");
            return d;
        };
        auto integer = [&](std::size_t item, const PlyProperty& prop) {
            long long v = 0;
            if (!parse_integer(tok, v))
                throw io_error(path, "line " + std::to_string(cur.line()) + ": " + quote(tok) +
                                         " is not an integer (" + shown(e.name) + " " + std::to_string(item) +
                                         ", property " + shown(prop.name) + ")");
            return v;
        };
        auto list_count = [&](std::size_t item, const PlyProperty& prop) {
            next_token(item);
            const long long n = integer(item, prop);
            if (n < 0 || static_cast<std::size_t>(n) > cur.remaining())
                throw io_error(path, "line " + std::to_string(cur.line()) + ": bad list length " + quote(tok) + " (" +
                                         shown(e.name) + " " + std::to_string(item) + ", property " + shown(prop.name) + ")");
            return static_cast<std::size_t>(n);
        };
        // Walks item `item`: a scalar's token goes to on_scalar(prop), a list's length to
        // on_list(prop, n), which reads its n tokens.
        auto walk = [&](std::size_t item, auto&& on_scalar, auto&& on_list) {
            for (const PlyProperty& prop : e.props) {
                if (prop.is_list) {
                    on_list(prop, list_count(item, prop));
                } else {
                    next_token(item);
                    on_scalar(prop);
                }
            }
        };
        auto skip = [&](std::size_t item) {
            return [&next_token, item](const PlyProperty&, std::size_t n) {
                for (std::size_t k = 0; k < n; ++k) next_token(item);
            };
        };
        if (e.name == "vertex") {
            const PlyVertexData has = ply_reserve_vertices(e, count, g);
            const bool normals = has.normals, radius = has.radius;
            PlyVertexValues val;
            for (std::size_t i = 0; i < count; ++i) {
                std::size_t line = 0;
                walk(
                    i,
                    [&](const PlyProperty& prop) {
                        if (line == 0) line = cur.line();
                        if (prop.role != PlyRole::ignored) {
                            double d = number(i, prop);
                            // Honour the declared type, as a binary file would: a `float` value is
                            // the float nearest to the text (so ascii and binary copies agree).
                            if (prop.type == PlyType::f32 && std::isfinite(d))
                                d = std::fabs(d) > static_cast<double>(std::numeric_limits<float>::max())
                                        ? std::numeric_limits<double>::infinity()  // rejected below
                                        : static_cast<double>(static_cast<float>(d));
                            val.v[static_cast<int>(prop.role)] = d;
                        }
                    },
                    skip(i));
                ply_store_vertex(g, val, normals, radius, i, line, path);
            }
            vertices_done = true;
        } else if (e.name == "face") {
            const std::size_t nv_known = vertices_done ? g.vertices.size() : static_cast<std::size_t>(-1);
            deferred_faces = !vertices_done;
            g.faces.reserve(std::min(count, remaining / (2 * triangle_tokens)));
            for (std::size_t f = 0; f < count; ++f)
                walk(f, [](const PlyProperty&) {}, [&](const PlyProperty& prop, std::size_t n) {
                    if (prop.role != PlyRole::indices) return skip(f)(prop, n);
                    const std::size_t line = cur.line();
                    poly.resize(n);
                    for (std::size_t k = 0; k < n; ++k) {
                        next_token(f);
                        const long long idx = integer(f, prop);
                        if (idx < 0)
                            throw io_error(path, face_where(f, cur.line()) + " uses a negative vertex index " +
                                                     std::to_string(idx));
                        poly[k] = static_cast<Index>(idx);
                    }
                    add_polygon(g, poly, options, path, f, line, nv_known, deferred_faces ? &face_of_triangle : nullptr);
                });
        } else {
            for (std::size_t i = 0; i < count; ++i) walk(i, [](const PlyProperty&) {}, skip(i));
        }
    }
    if (deferred_faces) check_face_indices(g, face_of_triangle, path);
}

/// Reads a PLY file already in memory.
inline RawGeometry read_ply(const FileBuffer& buf, const ReadOptions& options, const std::string& path) {
    RawGeometry g;
    const PlyHeader h = parse_ply_header(buf, path, g.info);
    constexpr bool little = std::endian::native == std::endian::little;
    switch (h.format) {
        case PlyFormat::ascii:
            g.info.format = "ply-ascii";
            ply_read_ascii_body(buf, h, options, path, g);
            break;
        case PlyFormat::binary_le:
            g.info.format = "ply-binary-le";
            ply_read_binary_body<!little>(buf, h, options, path, g);
            break;
        case PlyFormat::binary_be:
            g.info.format = "ply-binary-be";
            ply_read_binary_body<little>(buf, h, options, path, g);
            break;
    }
    finish(g);
    return g;
}

// ------------------------------------------------------------------ writer

/// What to write; pointers may be null (normals/radii empty means none).
struct PlyWriteData {
    const std::vector<Vec3>* vertices = nullptr;
    const std::vector<Vec3>* normals = nullptr;
    const std::vector<Scalar>* radii = nullptr;
    const std::vector<Face>* faces = nullptr;
    const std::vector<std::array<Index, 2>>* edges = nullptr;
};

/// Writes PLY: double x y z [nx ny nz] [radius], faces as `list uchar int vertex_indices`
/// (uint when the vertex count needs it), edges as `int vertex1, vertex2`.
inline void write_ply(AtomicOutputFile& out, const PlyWriteData& d, bool binary, bool big_endian) {
    const std::size_t nv = d.vertices->size();
    const bool normals = d.normals && !d.normals->empty();
    const bool radii = d.radii && !d.radii->empty();
    const std::size_t nf = d.faces ? d.faces->size() : 0;
    const std::size_t ne = d.edges ? d.edges->size() : 0;
    const bool wide = nv > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max());
    if ((nf > 0 || ne > 0) && nv > static_cast<std::size_t>(std::numeric_limits<std::uint32_t>::max()))
        throw invalid_input("kintsugi: PLY stores indices as 32-bit integers; " + std::to_string(nv) +
                            " vertices do not fit");
    const char* itype = wide ? "uint" : "int";

    out.write("ply\nformat ");
    out.write(!binary ? "ascii" : (big_endian ? "binary_big_endian" : "binary_little_endian"));
    out.write(" 1.0\ncomment written by kintsugi\nelement vertex ");
    out.put_uint(nv);
    out.write("\nproperty double x\nproperty double y\nproperty double z\n");
    if (normals) out.write("property double nx\nproperty double ny\nproperty double nz\n");
    if (radii) out.write("property double radius\n");
    if (d.faces) {
        out.write("element face ");
        out.put_uint(nf);
        out.write("\nproperty list uchar ");
        out.write(itype);
        out.write(" vertex_indices\n");
    }
    if (d.edges) {
        out.write("element edge ");
        out.put_uint(ne);
        out.write("\nproperty ");
        out.write(itype);
        out.write(" vertex1\nproperty ");
        out.write(itype);
        out.write(" vertex2\n");
    }
    out.write("end_header\n");

    const bool swap = binary && (big_endian != (std::endian::native == std::endian::big));
    auto put_index = [&](Index i) {
        if (wide) out.put_binary(static_cast<std::uint32_t>(i), swap);
        else out.put_binary(static_cast<std::int32_t>(i), swap);
    };
    for (std::size_t i = 0; i < nv; ++i) {
        const Vec3& p = (*d.vertices)[i];
        if (binary) {
            for (int c = 0; c < 3; ++c) out.put_binary(p[c], swap);
            if (normals)
                for (int c = 0; c < 3; ++c) out.put_binary((*d.normals)[i][c], swap);
            if (radii) out.put_binary((*d.radii)[i], swap);
        } else {
            for (int c = 0; c < 3; ++c) {
                if (c) out.put(' ');
                out.put_double(p[c]);
            }
            if (normals)
                for (int c = 0; c < 3; ++c) {
                    out.put(' ');
                    out.put_double((*d.normals)[i][c]);
                }
            if (radii) {
                out.put(' ');
                out.put_double((*d.radii)[i]);
            }
            out.put('\n');
        }
    }
    for (std::size_t f = 0; f < nf; ++f) {
        const Face& t = (*d.faces)[f];
        if (binary) {
            out.put_binary(static_cast<std::uint8_t>(3), swap);
            for (const Index v : t) put_index(v);
        } else {
            out.put('3');
            for (const Index v : t) {
                out.put(' ');
                out.put_uint(v);
            }
            out.put('\n');
        }
    }
    for (std::size_t k = 0; k < ne; ++k) {
        const auto& ed = (*d.edges)[k];
        if (binary) {
            put_index(ed[0]);
            put_index(ed[1]);
        } else {
            out.put_uint(ed[0]);
            out.put(' ');
            out.put_uint(ed[1]);
            out.put('\n');
        }
    }
}

}  // namespace kintsugi::detail::io
