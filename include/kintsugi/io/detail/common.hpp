// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file common.hpp
/// @brief Shared pieces of kintsugi's file readers: the whole file in memory, number
/// parsing, line splitting, and the raw geometry every reader fills.
///
/// Why kintsugi parses files itself instead of calling CGAL's readers
/// (CGAL::IO::read_PLY / read_OFF / read_OBJ / read_XYZ):
///  - CGAL's readers return only a bool, and print their reason (when they give one) to
///    std::cerr. kintsugi must throw an io_error naming the file and what is wrong
///    (which line, which face, which index), and a library must never print.
///  - They do not check coordinates for NaN/Inf, nor header counts against the file size
///    before allocating, nor face indices against the vertex count in every path.
///  - Speed: bench/bench_io.cpp reads the same 1M-point binary PLY (float32 x y z nx ny nz,
///    24 MB) with both in the same run: kintsugi 68 ms CPU, CGAL::IO::read_PLY 269 ms for
///    the points alone and 454 ms with normals, read_point_set 347 ms (details there).
/// So the parsing is written once, here and in the per-format headers next to this one:
/// the whole file is read with one call, binary PLY is decoded straight from that buffer,
/// text is parsed with std::from_chars (locale-independent, exact).

#include <kintsugi/core/error.hpp>
#include <kintsugi/core/types.hpp>
#include <kintsugi/io/options.hpp>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <new>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#if defined(__unix__) || defined(__APPLE__)
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#endif

namespace kintsugi::detail::io {

/// The whole content of a file, read with one call. `data()[size()]` is a '\0' sentinel.
class FileBuffer {
public:
    FileBuffer() = default;
    [[nodiscard]] const char* data() const { return data_.get(); }
    [[nodiscard]] std::size_t size() const { return size_; }
    [[nodiscard]] const char* begin() const { return data_.get(); }
    [[nodiscard]] const char* end() const { return data_.get() + size_; }

    /// Reads `path`; throws io_error when it is missing, not a regular file (a FIFO or a
    /// device may never end, so it is refused rather than read), unreadable or empty.
    /// Reads at most the size the file had when it was opened.
    static FileBuffer read(const std::filesystem::path& path) {
        const std::string name = path.string();
        std::error_code ec;
        const auto status = std::filesystem::status(path, ec);
        if (ec || !std::filesystem::exists(status)) {
            std::error_code lec;
            if (std::filesystem::is_symlink(std::filesystem::symlink_status(path, lec)))
                throw io_error(name, "is a symbolic link to a file that does not exist");
            throw io_error(name, "file does not exist");
        }
        if (std::filesystem::is_directory(status)) throw io_error(name, "is a directory, not a file");
        if (!std::filesystem::is_regular_file(status)) throw not_regular(name, status.type());
        FileBuffer buf;
#if defined(__unix__) || defined(__APPLE__)
        // O_NONBLOCK: if the path was swapped for a FIFO since the check above, open() must
        // not wait for a writer; fstat() on the descriptor then refuses it.
        const int fd = ::open(name.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
        if (fd < 0) throw io_error(name, "cannot open for reading: " + std::generic_category().message(errno));
        struct Closer {
            int fd;
            ~Closer() { ::close(fd); }
        } closer{fd};
        struct stat st {};
        if (::fstat(fd, &st) != 0) throw io_error(name, "cannot read: " + std::generic_category().message(errno));
        if (!S_ISREG(st.st_mode))
            throw not_regular(name, S_ISDIR(st.st_mode)    ? std::filesystem::file_type::directory
                                    : S_ISFIFO(st.st_mode) ? std::filesystem::file_type::fifo
                                    : S_ISCHR(st.st_mode)  ? std::filesystem::file_type::character
                                    : S_ISBLK(st.st_mode)  ? std::filesystem::file_type::block
                                    : S_ISSOCK(st.st_mode) ? std::filesystem::file_type::socket
                                                           : std::filesystem::file_type::unknown);
        const std::size_t file_size = static_cast<std::size_t>(st.st_size);
        if (file_size == 0) throw io_error(name, "file is empty");
        buf.allocate(name, file_size);
        while (buf.size_ < file_size) {
            const ssize_t n = ::read(fd, buf.data_.get() + buf.size_, file_size - buf.size_);
            if (n < 0 && errno == EINTR) continue;
            if (n < 0) throw io_error(name, "read error: " + std::generic_category().message(errno));
            if (n == 0) break;  // the file shrank while being read: keep what is there
            buf.size_ += static_cast<std::size_t>(n);
        }
#else
        const auto file_size = std::filesystem::file_size(path, ec);
        if (ec) throw io_error(name, "cannot read: " + ec.message());
        if (file_size == 0) throw io_error(name, "file is empty");
        std::FILE* f = std::fopen(name.c_str(), "rb");
        if (!f) throw io_error(name, "cannot open for reading: " + std::generic_category().message(errno));
        struct Closer {
            std::FILE* f;
            ~Closer() { std::fclose(f); }
        } closer{f};
        buf.allocate(name, static_cast<std::size_t>(file_size));
        buf.size_ = std::fread(buf.data_.get(), 1, static_cast<std::size_t>(file_size), f);
        if (buf.size_ != file_size && std::ferror(f))
            throw io_error(name, "read error: " + std::generic_category().message(errno));
#endif
        if (buf.size_ == 0) throw io_error(name, "file is empty");
        buf.data_[buf.size_] = '\0';
        return buf;
    }

    /// A copy of `size` bytes already in memory (the fuzzing harnesses use this).
    static FileBuffer from_memory(const void* data, std::size_t size) {
        FileBuffer buf;
        buf.allocate("memory", size);
        if (size > 0) std::memcpy(buf.data_.get(), data, size);
        buf.size_ = size;
        buf.data_[size] = '\0';
        return buf;
    }

private:
    void allocate(const std::string& name, std::size_t size) {
        try {
            data_.reset(new char[size + 1]);
        } catch (const std::bad_alloc&) {
            throw io_error(name, "the file's " + std::to_string(size) + " bytes do not fit in memory");
        }
    }
    [[nodiscard]] static io_error not_regular(const std::string& name, std::filesystem::file_type type) {
        using ft = std::filesystem::file_type;
        const char* kind = type == ft::fifo        ? "a FIFO (named pipe)"
                           : type == ft::character ? "a character device"
                           : type == ft::block     ? "a block device"
                           : type == ft::socket    ? "a socket"
                           : type == ft::directory ? "a directory"
                                                   : "an unknown kind of file";
        return io_error(name, std::string("is ") + kind +
                                  ", not a regular file; kintsugi reads regular files only (a pipe or a device "
                                  "may never end): copy the data to a file first");
    }

    std::unique_ptr<char[]> data_;
    std::size_t size_ = 0;
};

/// Everything a reader extracts; converted into the public types by read.hpp.
struct RawGeometry {
    std::vector<Vec3> vertices;
    std::vector<Vec3> normals;  ///< empty or one per vertex
    std::vector<Scalar> radii;  ///< empty or one per vertex
    std::vector<Face> faces;
    ReadInfo info;
};

/// An empty RawGeometry read from a file of `format` (ReadInfo::format).
[[nodiscard]] inline RawGeometry raw_geometry(const char* format) {
    RawGeometry g;
    g.info.format = format;
    return g;
}

/// Adds `raw` (escaped by printable()) to info.ignored_properties once. The list keeps at
/// most 64 names, then ends with "..." (a garbage file must not make it quadratic).
inline void note_ignored(ReadInfo& info, std::string_view raw) {
    constexpr std::size_t max_names = 64;
    auto& v = info.ignored_properties;
    if (v.size() > max_names) return;
    std::string what = printable(raw);
    if (std::find(v.begin(), v.end(), what) != v.end()) return;
    v.push_back(v.size() < max_names ? std::move(what) : std::string("..."));
}

[[nodiscard]] inline bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f'; }
[[nodiscard]] inline bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

/// Parses the whole token as a double (a leading '+' is accepted; "nan"/"inf" parse and
/// are rejected later by the finiteness checks). Returns false when it is not a number.
[[nodiscard]] inline bool parse_double(std::string_view tok, double& out) {
    if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
    if (tok.empty()) return false;
    const char* b = tok.data();
    const char* e = b + tok.size();
    const auto r = std::from_chars(b, e, out);
    if (r.ptr != e) return false;
    if (r.ec == std::errc::result_out_of_range) {
        // Over- or underflow (1e999, 1e-999): let strtod decide between +-inf and 0.
        const std::string s(tok);
        out = std::strtod(s.c_str(), nullptr);
        return true;
    }
    return r.ec == std::errc();
}

/// Parses the whole token as an integer; "3.0"-style integral decimals are accepted.
[[nodiscard]] inline bool parse_integer(std::string_view tok, long long& out) {
    if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
    if (tok.empty()) return false;
    const char* b = tok.data();
    const char* e = b + tok.size();
    const auto r = std::from_chars(b, e, out);
    if (r.ec == std::errc() && r.ptr == e) return true;
    double d = 0;
    if (!parse_double(tok, d) || !std::isfinite(d) || d != std::floor(d) || std::fabs(d) > 9.0e15) return false;
    out = static_cast<long long>(d);
    return true;
}

/// Where the text of `buf` starts: past a UTF-8 byte-order mark (which some editors
/// write). UTF-16 and UTF-32 text is refused with a message saying so.
[[nodiscard]] inline const char* text_begin(const FileBuffer& buf, const std::string& path) {
    const auto* u = reinterpret_cast<const unsigned char*>(buf.begin());
    const std::size_t n = buf.size();
    if (n >= 3 && u[0] == 0xEF && u[1] == 0xBB && u[2] == 0xBF) return buf.begin() + 3;
    const bool utf32 = n >= 4 && ((u[0] == 0xFF && u[1] == 0xFE && u[2] == 0 && u[3] == 0) ||
                                  (u[0] == 0 && u[1] == 0 && u[2] == 0xFE && u[3] == 0xFF));
    if (utf32) throw io_error(path, "the file is UTF-32 text (it starts with a UTF-32 byte-order mark); save it as UTF-8 or ASCII");
    if (n >= 2 && ((u[0] == 0xFF && u[1] == 0xFE) || (u[0] == 0xFE && u[1] == 0xFF)))
        throw io_error(path, "the file is UTF-16 text (it starts with a UTF-16 byte-order mark); save it as UTF-8 or ASCII");
    return buf.begin();
}

/// A read position in a text buffer and the number of the current line: what the line
/// reader below and PLY's token cursor share.
class TextPosition {
public:
    /// Number of the current line (1-based; 0 before the first line is read).
    [[nodiscard]] std::size_t line() const { return line_; }
    /// Bytes not yet consumed.
    [[nodiscard]] std::size_t remaining() const { return static_cast<std::size_t>(end_ - p_); }

protected:
    TextPosition(const char* begin, const char* end, std::size_t line) : p_(begin), end_(end), line_(line) {}
    const char* p_;
    const char* end_;
    std::size_t line_;
};

/// Splits a text buffer into lines; tracks 1-based line numbers. A line ends at LF, CRLF
/// or a lone CR (old Mac files). Strips surrounding whitespace and, when `comment` is
/// not '\0', everything from the comment character on.
class LineReader : public TextPosition {
public:
    LineReader(const char* begin, const char* end, char comment, std::size_t first_line = 1)
        : TextPosition(begin, end, first_line - 1), comment_(comment) {}

    /// Next line with content (blank and comment-only lines skipped); false at the end.
    bool next(std::string_view& out) {
        while (p_ < end_) {
            const char* b = p_;
            // The next LF is cached: a file with CR endings only would otherwise be
            // searched to its end for every line.
            if (!nl_ || nl_ < p_) {
                nl_ = static_cast<const char*>(std::memchr(p_, '\n', static_cast<std::size_t>(end_ - p_)));
                if (!nl_) nl_ = end_;
            }
            const char* e = nl_;
            p_ = nl_ < end_ ? nl_ + 1 : end_;
            const char* cr = static_cast<const char*>(std::memchr(b, '\r', static_cast<std::size_t>(nl_ - b)));
            if (cr && cr + 1 < nl_) {  // a lone CR, not the CR of a CRLF, ends the line
                e = cr;
                p_ = cr + 1;
            }
            ++line_;
            if (comment_ != '\0') {
                const char* c = static_cast<const char*>(std::memchr(b, comment_, static_cast<std::size_t>(e - b)));
                if (c) e = c;
            }
            while (b < e && is_space(*b)) ++b;
            while (e > b && is_space(e[-1])) --e;
            if (b == e) continue;
            out = std::string_view(b, static_cast<std::size_t>(e - b));
            return true;
        }
        return false;
    }
private:
    const char* nl_ = nullptr;  ///< next LF at or after p_ (end_ when none), null before the first search
    char comment_;
};

/// The lines of a text format (OBJ, OFF, XYZ, PWN): past a UTF-8 byte-order mark, '#'
/// comments skipped, and its one form of syntax error.
class TextLines : public LineReader {
public:
    TextLines(const FileBuffer& buf, const std::string& path, const char* format)
        : LineReader(text_begin(buf, path), buf.end(), '#'), path_(path), format_(format) {}
    /// "malformed <format> (line N): <what>", N the line last returned by next().
    [[nodiscard]] io_error malformed(const std::string& what) const {
        return io_error(path_, "malformed " + std::string(format_) + " (line " + std::to_string(line()) + "): " + what);
    }

private:
    const std::string& path_;
    const char* format_;
};

/// Splits one line into whitespace-separated tokens.
class Tokens {
public:
    explicit Tokens(std::string_view s) : p_(s.data()), end_(s.data() + s.size()) {}
    bool next(std::string_view& out) {
        while (p_ < end_ && is_space(*p_)) ++p_;
        if (p_ == end_) return false;
        const char* b = p_;
        while (p_ < end_ && !is_space(*p_)) ++p_;
        out = std::string_view(b, static_cast<std::size_t>(p_ - b));
        return true;
    }
    /// Collects all remaining tokens.
    void all(std::vector<std::string_view>& out) {
        out.clear();
        std::string_view t;
        while (next(t)) out.push_back(t);
    }

private:
    const char* p_;
    const char* end_;
};

/// A token or name of the file for an error message: shortened to 40 characters, bytes
/// outside printable ASCII escaped (see printable()).
[[nodiscard]] inline std::string shown(std::string_view tok) {
    return tok.size() > 40 ? printable(tok.substr(0, 37)) + "..." : printable(tok);
}
/// shown() in single quotes.
[[nodiscard]] inline std::string quote(std::string_view tok) {
    std::string s(1, '\'');
    s += shown(tok);
    s += '\'';
    return s;
}

[[nodiscard]] inline bool all_finite(const Vec3& v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

/// Where a vertex comes from, for messages (line 0 = binary).
[[nodiscard]] inline std::string vertex_where(std::size_t i, std::size_t line) {
    std::string s = "vertex " + std::to_string(i) + " (counting from 0)";
    if (line > 0) s += " on line " + std::to_string(line);
    return s;
}

/// Where a face comes from, for messages: "face 12 (counting from 0)" plus ", line 40"
/// for text formats (line 0 = binary).
[[nodiscard]] inline std::string face_where(std::size_t face, std::size_t line) {
    std::string s = "face " + std::to_string(face) + " (counting from 0)";
    if (line > 0) s += " on line " + std::to_string(line);
    return s;
}

/// Appends polygon `poly` (0-based indices) as fan triangles. Throws when it has fewer
/// than 3 vertices, more than 3 and options.triangulate is false, or (when the vertex
/// count is already known, `nv_known != npos`) an index out of range. When the vertex
/// count is not known yet, `face_of_triangle` records the face number of each triangle
/// for check_face_indices().
inline void add_polygon(RawGeometry& g, const std::vector<Index>& poly, const ReadOptions& options,
                        const std::string& path, std::size_t face, std::size_t line, std::size_t nv_known,
                        std::vector<std::size_t>* face_of_triangle) {
    const std::size_t n = poly.size();
    if (n < 3)
        throw io_error(path, face_where(face, line) + " has " + std::to_string(n) +
                                 " vertices; a face needs at least 3");
    if (n > 3) {
        if (!options.triangulate)
            throw io_error(path, face_where(face, line) + " has " + std::to_string(n) +
                                     " vertices, but triangles are required (ReadOptions::triangulate is false)");
        ++g.info.polygons_triangulated;
    }
    if (nv_known != static_cast<std::size_t>(-1)) {
        for (const Index v : poly)
            if (v >= nv_known)
                throw io_error(path, face_where(face, line) + " uses vertex index " + std::to_string(v) +
                                         ", out of range: the file has " + std::to_string(nv_known) + " vertices");
    }
    for (std::size_t i = 1; i + 1 < n; ++i) {
        g.faces.push_back(Face{poly[0], poly[i], poly[i + 1]});
        if (face_of_triangle) face_of_triangle->push_back(face);
    }
}

/// Final consistency checks shared by every reader; fills the counts of info.
inline void finish(RawGeometry& g) {
    const std::size_t nv = g.vertices.size();
    if (!g.normals.empty() && g.normals.size() != nv) g.normals.clear();
    if (!g.radii.empty() && g.radii.size() != nv) g.radii.clear();
    g.info.vertices = nv;
    g.info.faces = g.faces.size();
    g.info.has_normals = nv > 0 && g.normals.size() == nv;
    g.info.has_radii = nv > 0 && g.radii.size() == nv;
}

/// Throws unless every face index is below the vertex count (for faces read before the
/// vertex count was known). `face_of_triangle` maps each triangle to its face number.
inline void check_face_indices(const RawGeometry& g, const std::vector<std::size_t>& face_of_triangle,
                               const std::string& path) {
    const std::size_t nv = g.vertices.size();
    for (std::size_t t = 0; t < g.faces.size(); ++t) {
        for (const Index v : g.faces[t]) {
            if (v >= nv) {
                const std::size_t f = t < face_of_triangle.size() ? face_of_triangle[t] : t;
                throw io_error(path, face_where(f, 0) + " uses vertex index " + std::to_string(v) +
                                         ", out of range: the file has " + std::to_string(nv) + " vertices");
            }
        }
    }
}

/// Lower-case extension with the dot, e.g. ".ply".
[[nodiscard]] inline std::string lower_extension(const std::filesystem::path& path) {
    std::string ext = path.extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

}  // namespace kintsugi::detail::io
