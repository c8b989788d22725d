// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// libFuzzer harness for one of kintsugi's readers, chosen at compile time with
// KINTSUGI_FUZZ_READER = 1 PLY (ascii and binary), 2 OFF, 3 OBJ, 4 XYZ and PWN.
// Built with clang's -fsanitize=fuzzer,address,undefined (tests/fuzz/CMakeLists.txt).
// A finding is a crash, a sanitizer report, an exception other than io_error, a result
// that breaks the readers' contract (index out of range, non-finite value, counts that
// disagree), or a message or ReadInfo entry holding a byte outside printable ASCII.
#include <kintsugi/io/detail/common.hpp>
#include <kintsugi/io/detail/obj.hpp>
#include <kintsugi/io/detail/off.hpp>
#include <kintsugi/io/detail/ply.hpp>
#include <kintsugi/io/detail/xyz.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace {

namespace kio = kintsugi::detail::io;

[[noreturn]] void finding(const char* what, const std::string& detail = {}) {
    std::fprintf(stderr, "kintsugi fuzz finding: %s %s\n", what, detail.c_str());
    std::abort();
}

bool printable(const std::string& s) {
    for (const char c : s)
        if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7F) return false;
    return true;
}

void check(const kio::RawGeometry& g) {
    const std::size_t nv = g.vertices.size();
    for (const auto& f : g.faces)
        for (const kintsugi::Index v : f)
            if (v >= nv) finding("face index out of range");
    for (const auto& p : g.vertices)
        if (!kio::all_finite(p)) finding("non-finite vertex");
    if (!g.normals.empty() && g.normals.size() != nv) finding("normal count differs from vertex count");
    for (const auto& n : g.normals)
        if (!kio::all_finite(n)) finding("non-finite normal");
    if (!g.radii.empty() && g.radii.size() != nv) finding("radius count differs from vertex count");
    for (const double r : g.radii)
        if (!std::isfinite(r)) finding("non-finite radius");
    if (g.info.vertices != nv || g.info.faces != g.faces.size()) finding("ReadInfo counts disagree");
    if (g.info.has_normals != (nv > 0 && g.normals.size() == nv)) finding("ReadInfo::has_normals disagrees");
    if (g.info.ignored_properties.size() > 65) finding("ReadInfo::ignored_properties too long");
    for (const std::string& s : g.info.ignored_properties)
        if (!printable(s)) finding("raw byte in ReadInfo::ignored_properties:", s);
}

template <class Read>
void run(const char* path, Read&& read) {
    try {
        check(read());
    } catch (const kintsugi::io_error& e) {
        const std::string msg = e.what();
        if (msg.rfind(std::string(path) + ": ", 0) != 0) finding("message does not start with the file name:", msg);
        if (!printable(msg)) finding("raw byte in message:", msg);
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const kio::FileBuffer buf = kio::FileBuffer::from_memory(data, size);
    // One input in four also runs with polygons rejected (deterministic per input).
    [[maybe_unused]] const kintsugi::ReadOptions options{.triangulate = size % 4 != 0};
#if KINTSUGI_FUZZ_READER == 1
    run("fuzz.ply", [&] { return kio::read_ply(buf, options, "fuzz.ply"); });
#elif KINTSUGI_FUZZ_READER == 2
    run("fuzz.off", [&] { return kio::read_off(buf, options, "fuzz.off"); });
#elif KINTSUGI_FUZZ_READER == 3
    run("fuzz.obj", [&] { return kio::read_obj(buf, options, "fuzz.obj"); });
#elif KINTSUGI_FUZZ_READER == 4
    run("fuzz.xyz", [&] { return kio::read_xyz(buf, false, "fuzz.xyz"); });
    run("fuzz.pwn", [&] { return kio::read_xyz(buf, true, "fuzz.pwn"); });
#else
#error "define KINTSUGI_FUZZ_READER to 1 (PLY), 2 (OFF), 3 (OBJ) or 4 (XYZ/PWN)"
#endif
    return 0;
}
