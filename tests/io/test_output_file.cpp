// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// The write path's edge cases: symbolic links and devices as targets, the longest
// legal file name, cancellation through the stop token, output batches,
// check_writable and the registry of temporary files.
#include "io_test_util.hpp"

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/io/write.hpp>

#include <array>
#include <iterator>
#include <limits>
#include <stop_token>
#include <string>
#include <thread>
#include <vector>

#include <sys/stat.h>

namespace ks = kintsugi;
using namespace io_test;

namespace {


ks::IndexedMesh tetrahedron() {
    ks::IndexedMesh m;
    m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    return m;
}

/// A point cloud of n points on a line (about 48 n bytes as binary PLY with normals).
ks::PointCloud line_cloud(std::size_t n) {
    ks::PointCloud c;
    c.points.resize(n);
    c.normals.assign(n, ks::Vec3::UnitZ());
    for (std::size_t i = 0; i < n; ++i) c.points[i] = ks::Vec3(static_cast<double>(i), 0, 0);
    return c;
}

}  // namespace

TEST_CASE("a symbolic link as the target is written through; the link stays") {
    TempDir dir;
    fs::create_directory(dir / "real");
    write_file(dir / "real" / "m.ply", "old");
    fs::create_symlink("real/m.ply", dir / "link.ply");
    ks::write_mesh(dir / "link.ply", tetrahedron());
    CHECK(fs::is_symlink(dir / "link.ply"));
    CHECK(ks::read_mesh(dir / "real" / "m.ply").faces.size() == 4);
    CHECK(dir.entries() == 2);  // no temporary file beside the link
    CHECK(fs::directory_iterator(dir / "real") != fs::directory_iterator());
    CHECK(std::distance(fs::directory_iterator(dir / "real"), fs::directory_iterator()) == 1);

    SUBCASE("a dangling link creates the file it names") {
        fs::create_symlink("real/new.off", dir / "dangling.off");
        ks::write_mesh(dir / "dangling.off", tetrahedron());
        CHECK(fs::is_symlink(dir / "dangling.off"));
        CHECK(ks::read_mesh(dir / "real" / "new.off").faces.size() == 4);
    }
    SUBCASE("a loop of links is an io_error") {
        fs::create_symlink("b.ply", dir / "a.ply");
        fs::create_symlink("a.ply", dir / "b.ply");
        check_io_error([&] { ks::write_mesh(dir / "a.ply", tetrahedron()); }, dir / "a.ply", "symbolic links");
    }
}

TEST_CASE("a character device or FIFO is written directly; an existing file keeps its permissions") {
    TempDir dir;
    fs::create_symlink("/dev/null", dir / "null.ply");
    ks::write_mesh(dir / "null.ply", tetrahedron());  // no temporary file in /dev, no replacement
    CHECK(fs::is_character_file("/dev/null"));
    CHECK(fs::is_symlink(dir / "null.ply"));
    ks::check_writable(dir / "null.ply", ks::OutputKind::point_cloud);
    {
        ks::OutputBatch batch;  // written at once, nothing waits
        ks::write_mesh(dir / "null.ply", tetrahedron(), {.batch = &batch});
        CHECK(batch.size() == 0);
    }

    REQUIRE(::mkfifo((dir / "pipe.xyz").c_str(), 0600) == 0);
    ks::check_writable(dir / "pipe.xyz", ks::OutputKind::point_cloud);  // does not open (it would block)
    std::string read_back;
    std::thread reader([&] { read_back = read_file(dir / "pipe.xyz"); });
    ks::write_point_cloud(dir / "pipe.xyz", line_cloud(3));
    reader.join();
    CHECK(read_back == "0 0 0 0 0 1\n1 0 0 0 0 1\n2 0 0 0 0 1\n");
    CHECK(fs::is_fifo(dir / "pipe.xyz"));

    write_file(dir / "private.ply", "old");
    fs::permissions(dir / "private.ply", fs::perms::owner_read | fs::perms::owner_write);
    ks::write_mesh(dir / "private.ply", tetrahedron());
    CHECK(fs::status(dir / "private.ply").permissions() == (fs::perms::owner_read | fs::perms::owner_write));
}

TEST_CASE("the longest legal file name can be written; a longer one is refused by name") {
    TempDir dir;
    const std::string name250 = std::string(246, 'n') + ".ply", name255 = std::string(251, 'n') + ".ply";
    ks::write_mesh(dir / name250, tetrahedron());
    ks::write_mesh(dir / name255, tetrahedron());
    CHECK(ks::read_mesh(dir / name255).faces.size() == 4);
    CHECK(dir.entries() == 2);
    const std::string name256 = std::string(252, 'n') + ".ply";
    check_io_error([&] { ks::write_mesh(dir / name256, tetrahedron()); }, dir / name256, "at most 255");
    check_io_error([&] { ks::check_writable(dir / name256, ks::OutputKind::mesh); }, dir / name256, "at most 255");
    CHECK(dir.entries() == 2);
}

TEST_CASE("a stop request interrupts a write; the target and the directory are as before") {
    TempDir dir;
    write_file(dir / "c.ply", "old");
    std::stop_source stop;
    stop.request_stop();
    {
        ks::OutputBatch batch(stop.get_token());
        check_io_error([&] { ks::write_point_cloud(dir / "c.ply", line_cloud(100000), {.batch = &batch}); },
                       dir / "c.ply", "interrupted");
        CHECK(batch.size() == 0);
    }
    CHECK(read_file(dir / "c.ply") == "old");
    CHECK(dir.entries() == 1);

    // Requested in the middle of a write: the next 1 MB block throws and the
    // temporary file, already 2 MB long, is removed.
    std::stop_source later;
    {
        ks::detail::io::AtomicOutputFile out(dir / "c.ply", later.get_token());
        const std::string block(1 << 20, 'x');
        out.write(block);
        out.write(block);
        out.write("y");
        CHECK(fs::file_size(out.temporary_path()) == 2u << 20);
        later.request_stop();
        check_io_error([&] { out.write(block); }, dir / "c.ply", "interrupted");
        CHECK(dir.entries() == 1);
    }
    CHECK(read_file(dir / "c.ply") == "old");
    CHECK(dir.entries() == 1);
}

TEST_CASE("an output batch makes its files appear together, or none of them") {
    TempDir dir;
    const ks::IndexedMesh mesh = tetrahedron();
    const std::vector<std::array<ks::Index, 2>> edges = {{0, 1}, {1, 2}};
    SUBCASE("committed: both appear") {
        ks::OutputBatch batch;
        ks::write_polylines(dir / "f.ply", mesh.vertices, edges, {.batch = &batch});
        ks::write_mesh(dir / "m.obj", mesh, {.batch = &batch});
        CHECK(batch.size() == 2);
        CHECK_FALSE(fs::exists(dir / "f.ply"));
        CHECK_FALSE(fs::exists(dir / "m.obj"));
        batch.commit();
        CHECK(ks::read_mesh(dir / "m.obj").faces.size() == 4);
        CHECK(fs::exists(dir / "f.ply"));
        CHECK(dir.entries() == 2);
    }
    SUBCASE("the second write fails: the first file is not left behind") {
        write_file(dir / "f.ply", "old features");
        {
            ks::OutputBatch batch;
            ks::write_polylines(dir / "f.ply", mesh.vertices, edges, {.batch = &batch});
            CHECK(dir.entries() == 2);  // the old file and the waiting temporary file
            ks::IndexedMesh bad = mesh;
            bad.vertices[2].x() = std::numeric_limits<double>::infinity();
            CHECK_THROWS_AS(ks::write_mesh(dir / "m.ply", bad, {.batch = &batch}), ks::invalid_input);
        }
        CHECK(read_file(dir / "f.ply") == "old features");
        CHECK(dir.entries() == 1);
    }
}

TEST_CASE("remove_temporary_outputs removes the files of writes under way, not finished ones") {
    TempDir dir;
    ks::write_mesh(dir / "done.ply", tetrahedron());
    ks::OutputBatch batch;
    ks::write_mesh(dir / "waiting.ply", tetrahedron(), {.batch = &batch});
    ks::detail::io::AtomicOutputFile open(dir / "open.ply");
    open.write("partial");
    CHECK(dir.entries() == 3);
    CHECK(ks::remove_temporary_outputs() == 2);
    CHECK(dir.entries() == 1);
    CHECK(fs::exists(dir / "done.ply"));
    CHECK(ks::remove_temporary_outputs() == 0);
}

TEST_CASE("check_writable names the file and the problem without creating anything") {
    TempDir dir;
    ks::check_writable(dir / "m.ply", ks::OutputKind::mesh);
    ks::check_writable(dir / "c.pwn", ks::OutputKind::point_cloud);
    CHECK(dir.entries() == 0);
    check_io_error([&] { ks::check_writable(dir / "m.xyz", ks::OutputKind::mesh); }, dir / "m.xyz",
                   "unsupported extension '.xyz' for a mesh");
    check_io_error([&] { ks::check_writable(dir / "e.off", ks::OutputKind::polylines); }, dir / "e.off",
                   "unsupported extension '.off' for polylines");
    check_io_error([&] { ks::check_writable(dir / "no" / "m.ply", ks::OutputKind::mesh); }, dir / "no" / "m.ply",
                   "does not exist");
    fs::create_directory(dir / "d.ply");
    check_io_error([&] { ks::check_writable(dir / "d.ply", ks::OutputKind::mesh); }, dir / "d.ply", "is a directory");
    CHECK(dir.entries() == 1);
}
