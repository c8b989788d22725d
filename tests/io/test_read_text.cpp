// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Readers on text as editors and other systems write it: a UTF-8 byte-order mark, CRLF and
// old-Mac CR line endings, UTF-16 text; files that are not regular files; and messages
// that name the real problem without echoing raw bytes.
#include "io_test_util.hpp"

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/io/read.hpp>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <sys/stat.h>
#include <sys/types.h>

namespace ks = kintsugi;
using namespace io_test;

namespace {

const std::string bom = "\xEF\xBB\xBF";

// `text` (LF endings) with every LF replaced by `eol`.
std::string with_eol(const std::string& text, const std::string& eol) {
    std::string out;
    for (const char c : text) {
        if (c == '\n') out += eol;
        else out += c;
    }
    return out;
}

// Reads `content` written to dir/name.
ks::IndexedMesh read_text(const TempDir& dir, const std::string& name, const std::string& content,
                          ks::ReadInfo* info = nullptr) {
    const fs::path f = dir / name;
    write_file(f, content);
    return ks::read_mesh(f, {}, info);
}

// The message of the io_error that reading `content` as dir/name throws ("" when none).
std::string error_of(const TempDir& dir, const std::string& name, const std::string& content) {
    const fs::path f = dir / name;
    write_file(f, content);
    try {
        (void)ks::read_mesh(f);
    } catch (const ks::io_error& e) {
        return e.what();
    }
    return "";
}

// True when every byte of `s` is printable ASCII.
bool all_printable(const std::string& s) {
    return std::all_of(s.begin(), s.end(), [](char c) {
        const auto u = static_cast<unsigned char>(c);
        return u >= 0x20 && u < 0x7F;
    });
}

// The reference content of each text format (LF endings), with the counts it must give.
struct TextCase {
    std::string name;
    std::string content;
    std::size_t vertices, faces;
    bool normals;
};

std::vector<TextCase> text_cases() {
    return {
        {"m.obj", "# comment\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\n"
                  "f 1//1 2//2 3//3\nf 2//2 4//4 3//3\n", 4, 2, true},
        {"m.off", "OFF\n# comment\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n", 4, 2, false},
        {"n.off", "NOFF 4 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n1 1 0 0 0 1\n4 0 1 3 2\n", 4, 2, true},
        {"m.ply", "ply\nformat ascii 1.0\ncomment c\nelement vertex 4\nproperty float x\nproperty float y\n"
                  "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
                  "0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n", 4, 2, false},
        {"p.xyz", "4\n# comment\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n", 4, 0, false},
        {"p.pwn", "0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n1 1 0 0 0 1\n", 4, 0, true},
    };
}

}  // namespace

TEST_CASE("text formats read the same with a UTF-8 BOM and with LF, CRLF or CR line endings") {
    TempDir dir;
    for (const TextCase& c : text_cases()) {
        CAPTURE(c.name);
        ks::ReadInfo ref_info;
        const ks::IndexedMesh ref = read_text(dir, c.name, c.content, &ref_info);
        REQUIRE(ref.vertices.size() == c.vertices);
        REQUIRE(ref.faces.size() == c.faces);
        REQUIRE(ref_info.has_normals == c.normals);
        for (const std::string& prefix : {std::string(), bom}) {
            for (const std::string eol : {"\n", "\r\n", "\r"}) {
                CAPTURE(prefix.size());
                CAPTURE(eol.size());
                CAPTURE(eol[0] == '\r');
                ks::ReadInfo info;
                const ks::IndexedMesh m = read_text(dir, c.name, prefix + with_eol(c.content, eol), &info);
                CHECK(m.vertices == ref.vertices);
                CHECK(m.faces == ref.faces);
                CHECK(m.normals == ref.normals);
                CHECK(info.ignored_properties == ref_info.ignored_properties);
                CHECK(info.polygons_triangulated == ref_info.polygons_triangulated);
            }
        }
    }
}

TEST_CASE("the two silent misreads: an OBJ after a BOM keeps its first vertex, CR-only XYZ is not one point") {
    TempDir dir;
    ks::ReadInfo info;
    const ks::IndexedMesh obj = read_text(dir, "bom.obj", bom + "v 1 2 3\nv 4 5 6\nv 7 8 9\nf 1 2 3\n", &info);
    REQUIRE(obj.vertices.size() == 3);
    CHECK(obj.vertices[0] == ks::Vec3(1, 2, 3));
    CHECK(obj.faces.size() == 1);
    CHECK(info.ignored_properties.empty());  // before: the BOM-prefixed 'v' was an ignored statement

    const ks::IndexedMesh xyz = read_text(dir, "mac.xyz", "0 0 0\r1 0 0\r0 1 0\r0 0 1\r");
    REQUIRE(xyz.vertices.size() == 4);
    CHECK(xyz.vertices[3] == ks::Vec3(0, 0, 1));
}

TEST_CASE("line numbers in messages count CR and CRLF line endings") {
    TempDir dir;
    for (const std::string eol : {"\n", "\r\n", "\r"}) {
        CAPTURE(eol.size());
        const std::string obj = error_of(dir, "l.obj", with_eol("v 0 0 0\nv 1 0 0\n\nv 0 one 0\n", eol));
        CHECK(obj.find("malformed OBJ (line 4): 'one' is not a number") != std::string::npos);
        const std::string xyz = error_of(dir, "l.xyz", with_eol("# c\n0 0 0\n1 1 x\n", eol));
        CHECK(xyz.find("(line 3): 'x' is not a number") != std::string::npos);
        const std::string ply = error_of(dir, "l.ply",
                                         with_eol("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                                                  "property float y\nproperty float z\nend_header\n0 0 0\n1 x 0\n",
                                                  eol));
        CHECK(ply.find("line 9: 'x' is not a number (vertex 1, property y)") != std::string::npos);
        const std::string header = error_of(dir, "h.ply", with_eol("ply\nformat ascii 1.0\nfoo\nend_header\n", eol));
        CHECK(header.find("malformed PLY header (line 3): unknown keyword 'foo'") != std::string::npos);
    }
}

TEST_CASE("binary PLY: the header's line ending is its first line's, so a body starting with 0x0A is kept") {
    TempDir dir;
    // x of vertex 0 is the float whose first little-endian byte is 0x0A (an LF).
    const std::uint32_t bits = 0x3F80000A;
    float first = 0;
    std::memcpy(&first, &bits, 4);
    std::string body;
    auto put = [&](float v) {
        char b[4];
        std::memcpy(b, &v, 4);
        if constexpr (std::endian::native == std::endian::big) std::reverse(b, b + 4);
        body.append(b, 4);
    };
    for (float v : {first, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put(v);
    REQUIRE(body[0] == '\n');
    const std::string header = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                               "property float y\nproperty float z\nend_header\n";
    for (const std::string& prefix : {std::string(), bom}) {
        for (const std::string eol : {"\n", "\r\n", "\r"}) {
            CAPTURE(eol.size());
            CAPTURE(prefix.size());
            const ks::IndexedMesh m = read_text(dir, "b.ply", prefix + with_eol(header, eol) + body);
            REQUIRE(m.vertices.size() == 3);
            CHECK(m.vertices[0] == ks::Vec3(static_cast<double>(first), 0, 0));
            CHECK(m.vertices[2] == ks::Vec3(0, 1, 0));
        }
    }
}

TEST_CASE("UTF-16 and UTF-32 text is refused with a message saying so") {
    TempDir dir;
    auto expect = [&](const std::string& name, const std::string& content, const std::string& what) {
        const fs::path f = dir / name;
        write_file(f, content);
        CAPTURE(name);
        check_io_error([&] { (void)ks::read_mesh(f); }, f, what);
    };
    const std::string utf16le("\xFF\xFEv\0 \0" "1\0 \0" "2\0 \0" "3\0\n\0", 16);
    expect("a.obj", utf16le, "the file is UTF-16 text (it starts with a UTF-16 byte-order mark); save it as UTF-8");
    expect("b.off", std::string("\xFE\xFF\0O\0F\0F", 8), "UTF-16 text");
    expect("c.ply", std::string("\xFF\xFE\0\0p\0\0\0", 8), "UTF-32 text");
    expect("d.xyz", std::string("\xFF\xFE" "0\0 \0" "0\0 \0" "0\0", 12), "UTF-16 text");
}

TEST_CASE("files that are not regular files are refused, never read without end") {
    TempDir dir;
    SUBCASE("a symbolic link to /dev/zero") {
        const fs::path link = dir / "zero.ply";
        fs::create_symlink("/dev/zero", link);
        check_io_error([&] { (void)ks::read_mesh(link); }, link,
                       "is a character device, not a regular file; kintsugi reads regular files only");
        check_io_error([&] { (void)ks::read_point_cloud(link); }, link, "character device");
    }
    SUBCASE("a FIFO with no writer (opening it would block)") {
        const fs::path fifo = dir / "pipe.xyz";
        REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
        check_io_error([&] { (void)ks::read_point_cloud(fifo); }, fifo, "is a FIFO (named pipe), not a regular file");
    }
    SUBCASE("a dangling symbolic link") {
        const fs::path link = dir / "gone.off";
        fs::create_symlink(dir / "nothing_here.off", link);
        check_io_error([&] { (void)ks::read_mesh(link); }, link, "is a symbolic link to a file that does not exist");
    }
    SUBCASE("a symbolic link to a regular file is read") {
        const fs::path target = dir / "t.xyz";
        write_file(target, "0 0 0\n1 1 1\n");
        const fs::path link = dir / "link.xyz";
        fs::create_symlink(target, link);
        CHECK(ks::read_point_cloud(link).points.size() == 2);
    }
}

TEST_CASE("a face with fewer than 3 vertices is reported as such, not as a truncated file") {
    TempDir dir;
    auto expect = [&](const std::string& name, const std::string& content, const std::string& what) {
        const fs::path f = dir / name;
        write_file(f, content);
        CAPTURE(name);
        check_io_error([&] { (void)ks::read_mesh(f); }, f, what);
        const std::string msg = error_of(dir, name, content);
        CHECK(msg.find("truncated") == std::string::npos);
    };
    const std::string tri = "0 0 0\n1 0 0\n0 1 0\n";
    for (int n : {0, 1, 2}) {
        CAPTURE(n);
        std::string idx = std::to_string(n);
        for (int k = 0; k < n; ++k) idx.append(" ").append(std::to_string(k));
        const std::string what = "face 1 (counting from 0) on line ";
        const std::string has = " has " + std::to_string(n) + " vertices; a face needs at least 3";
        // Several short faces: the header's face count exceeds what full triangles would need.
        expect("a.off", "OFF\n3 3 0\n" + tri + "3 0 1 2\n" + idx + "\n" + idx + "\n", has);
        expect("b.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                        "element face 3\nproperty list uchar int vertex_indices\nend_header\n" +
                            tri + "3 0 1 2\n" + idx + "\n" + idx + "\n",
               what + "14" + has);
        std::string objf = "f";
        for (int k = 1; k <= n; ++k) objf.append(" ").append(std::to_string(k));
        expect("c.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n" + objf + "\n", what + "5" + has);
        // Binary: 3 float vertices, a triangle, then two faces of n vertices.
        std::string body;
        auto put = [&](const void* p, std::size_t size) {
            char b[8];
            std::memcpy(b, p, size);
            if constexpr (std::endian::native == std::endian::big) std::reverse(b, b + size);
            body.append(b, size);
        };
        for (float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put(&v, 4);
        const std::uint8_t three = 3, count = static_cast<std::uint8_t>(n);
        put(&three, 1);
        for (std::int32_t v : {0, 1, 2}) put(&v, 4);
        for (int face = 0; face < 2; ++face) {
            put(&count, 1);
            for (std::int32_t v = 0; v < n; ++v) put(&v, 4);
        }
        expect("d.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                        "property float z\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n" + body,
               "face 1 (counting from 0)" + has);
    }
}

TEST_CASE("messages and ReadInfo escape raw bytes and control characters of the file") {
    TempDir dir;
    const std::string bad_number = error_of(dir, "a.obj", "v 0 0 \xFF\x01\x1B[31m\n");
    CHECK(bad_number.find("'\\xFF\\x01\\x1B[31m' is not a number") != std::string::npos);
    CHECK(all_printable(bad_number));

    const std::string bom_in_middle = error_of(dir, "b.off", "OFF\n1 0 0\n\xEF\xBB\xBF" "0 0 0\n");
    CHECK(bom_in_middle.find("'\\xEF\\xBB\\xBF0' is not a number") != std::string::npos);
    CHECK(all_printable(bom_in_middle));

    const std::string element = error_of(dir, "c.ply", "ply\nformat ascii 1.0\nelement \x7Fv\x01 1\nproperty float x\n"
                                                       "element \x7Fv\x01 1\nend_header\n");
    CHECK(element.find("element '\\x7Fv\\x01' is declared twice") != std::string::npos);
    CHECK(all_printable(element));

    const std::string truncated =
        error_of(dir, "d.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                               "property float z\nelement \xC3\xA9l\xC3\xA9ment 5\nproperty int \xE2\x80\x8B" "a\n"
                               "end_header\n0 0 0\n1\n");
    CHECK(truncated.find("the header declares 5 \\xC3\\xA9l\\xC3\\xA9ment elements") != std::string::npos);
    CHECK(all_printable(truncated));

    const std::string extension = error_of(dir, "e.p\x01ly", "ply\n");
    CHECK(extension.find("unsupported file extension '.p\\x01ly'") != std::string::npos);
    CHECK(extension.find("e.p\\x01ly: ") != std::string::npos);  // the file name too
    CHECK(all_printable(extension));

    // Statements and properties that are ignored are listed escaped.
    ks::ReadInfo info;
    (void)read_text(dir, "f.obj", "v 0 0 0\n\x01w 1\n\xE2\x80\x8Bv 1 1 1\n", &info);
    CHECK(info.ignored_properties == std::vector<std::string>{"\\x01w", "\\xE2\\x80\\x8Bv"});
    (void)read_text(dir, "g.ply",
                    "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                    "property uchar r\xFF\nend_header\n0 0 0 1\n",
                    &info);
    CHECK(info.ignored_properties == std::vector<std::string>{"vertex.r\\xFF"});
}

// Both inputs took minutes when each new name was compared with every earlier one.
TEST_CASE("ignored statements are listed up to 64, then '...'; many names cost linear time") {
    TempDir dir;
    std::string content = "v 0 0 0\n";
    for (int i = 0; i < 200000; ++i) content.append("k").append(std::to_string(i)).append(" 1\n");
    ks::ReadInfo info;
    (void)read_text(dir, "many.obj", content, &info);
    REQUIRE(info.ignored_properties.size() == 65);
    CHECK(info.ignored_properties[63] == "k63");
    CHECK(info.ignored_properties[64] == "...");
}

TEST_CASE("OBJ: the most negative relative index is an error, not an overflow") {
    TempDir dir;
    const fs::path f = dir / "n.obj";
    write_file(f, "v 0 0 0\nf 1 1 -9223372036854775808\n");
    check_io_error([&] { (void)ks::read_mesh(f); }, f,
                   "relative vertex index -9223372036854775808 points before the first vertex (only 1 defined so far)");
}

TEST_CASE("a PLY header declaring 200,000 elements is read in linear time") {
    TempDir dir;
    std::string content = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                          "property float z\n";
    for (int i = 0; i < 200000; ++i) content += "element e" + std::to_string(i) + " 0\n";
    content += "end_header\n1 2 3\n";
    ks::ReadInfo info;
    const ks::IndexedMesh m = read_text(dir, "many.ply", content, &info);
    REQUIRE(m.vertices.size() == 1);
    CHECK(m.vertices[0] == ks::Vec3(1, 2, 3));
    const std::string twice = error_of(dir, "twice.ply", content.substr(0, content.size() - 17) +
                                                            "element e7 0\nend_header\n1 2 3\n");
    CHECK(twice.find("(line 200007): element 'e7' is declared twice") != std::string::npos);
}
