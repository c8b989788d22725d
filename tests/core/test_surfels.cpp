// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Surfels (position, normal, radius): the SurfelSet / GrowableSurfelSet concepts,
// the PointCloud and projection adapters, and a PLY round trip of the radii.
#include <doctest/doctest.h>

#include <kintsugi/adapters/indexed_mesh.hpp>
#include <kintsugi/adapters/projection.hpp>
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/io/read.hpp>
#include <kintsugi/io/write.hpp>

#include <array>
#include <filesystem>
#include <string>
#include <unistd.h>
#include <vector>

namespace ks = kintsugi;

namespace user {
struct Disk {  // a renderer's surfel: float storage, radius in its own member
    std::array<float, 3> p;
    Eigen::Vector3f n;
    float r;
    int id = -1;
};
}  // namespace user

using Disks = std::vector<user::Disk>;
using DiskView = decltype(ks::project_surfels(std::declval<Disks&>(), &user::Disk::p, &user::Disk::n, &user::Disk::r));
using DiskViewConst =
    decltype(ks::project_surfels(std::declval<const Disks&>(), &user::Disk::p, &user::Disk::n, &user::Disk::r));
using DiskPoints = decltype(ks::project_points(std::declval<Disks&>(), &user::Disk::p, &user::Disk::n));
using DiskByValue = decltype(ks::project_surfels(std::declval<Disks&>(), &user::Disk::p, &user::Disk::n,
                                                 [](const user::Disk& d) { return 2 * d.r; }));

static_assert(ks::SurfelSet<ks::PointCloud> && ks::GrowableSurfelSet<ks::PointCloud>);
static_assert(ks::SurfelSet<DiskView> && ks::GrowableSurfelSet<DiskView>);
static_assert(ks::NormalWritablePointSet<DiskView>);
static_assert(ks::GrowablePointSet<DiskPoints> && !ks::SurfelSet<DiskPoints>);
static_assert(ks::SurfelSet<DiskViewConst> && !ks::GrowablePointSet<DiskViewConst>);
// A radius computed by value can be read but not written: readable surfels, not growable.
static_assert(ks::SurfelSet<DiskByValue> && !ks::GrowableSurfelSet<DiskByValue>);
static_assert(!ks::SurfelSet<std::vector<Eigen::Vector3d>> && !ks::GrowableSurfelSet<std::vector<Eigen::Vector3d>>);
static_assert(!ks::SurfelSet<ks::PointsWithNormals<std::vector<Eigen::Vector3d>, std::vector<Eigen::Vector3d>>>);

namespace {
const std::vector<ks::Vec3> kP = {{0, 0, 0}, {1, 2, 3}, {-1, 0.5, 2}};
const std::vector<ks::Vec3> kN = {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}};
const std::vector<ks::Scalar> kR = {0.5, 0.25, 0.125};

template <class S>
void check_surfels(const S& s) {
    REQUIRE(ks::num_points(s) == kP.size());
    REQUIRE(ks::has_normals(s));
    REQUIRE(ks::has_radii(s));
    for (std::size_t i = 0; i < kP.size(); ++i) {
        CHECK((ks::point_at(s, i) - kP[i]).norm() == doctest::Approx(0));
        CHECK((ks::normal_at(s, i) - kN[i]).norm() == doctest::Approx(0));
        CHECK(ks::radius_at(s, i) == kR[i]);
    }
    CHECK(ks::gather_radii(s) == kR);
}

struct CloudHolder {
    ks::PointCloud c;
    ks::PointCloud& view() { return c; }
    std::size_t stored() const { return c.points.size(); }
};
struct DiskHolder {
    Disks d;
    DiskView view() { return ks::project_surfels(d, &user::Disk::p, &user::Disk::n, &user::Disk::r); }
    std::size_t stored() const { return d.size(); }
};
}  // namespace

TEST_CASE_TEMPLATE("append_surfel grows any GrowableSurfelSet", H, CloudHolder, DiskHolder) {
    H h;
    auto&& s = h.view();
    ks::point_set_traits<std::remove_cvref_t<decltype(s)>>::clear(s);
    CHECK(h.stored() == 0);
    for (std::size_t i = 0; i < kP.size(); ++i) ks::append_surfel(s, kP[i], kN[i], kR[i]);
    CHECK(h.stored() == 3);
    check_surfels(s);
    // Copying into the built-in layout keeps the radii.
    const ks::PointCloud copy = ks::to_point_cloud(s);
    CHECK(copy.radii == kR);
    ks::point_set_traits<std::remove_cvref_t<decltype(s)>>::clear(s);
    CHECK(h.stored() == 0);
    CHECK_FALSE(ks::has_radii(ks::PointCloud{}));
}

TEST_CASE("projection view appends into the user's struct and leaves other members default") {
    Disks disks;
    auto view = ks::project_surfels(disks, &user::Disk::p, &user::Disk::n, &user::Disk::r);
    ks::append_surfel(view, ks::Vec3(1, 2, 3), ks::Vec3(0, 1, 0), 0.75);
    REQUIRE(disks.size() == 1);
    CHECK(disks[0].p == std::array<float, 3>{1, 2, 3});
    CHECK(disks[0].n == Eigen::Vector3f(0, 1, 0));
    CHECK(disks[0].r == 0.75f);
    CHECK(disks[0].id == -1);
}

TEST_CASE("a point cloud with a missing radius reports none") {
    ks::PointCloud c{kP, kN, {}};
    CHECK_FALSE(ks::has_radii(c));
    CHECK(ks::gather_radii(c).empty());
    c.radii = {1.0, 2.0};  // fewer radii than points
    CHECK_FALSE(ks::has_radii(c));
    ks::point_set_traits<ks::PointCloud>::push_back(c, kP[0], kN[0]);  // a point without radius
    CHECK_FALSE(ks::has_radii(c));
}

TEST_CASE_TEMPLATE("surfels round-trip through a PLY file with a radius property", H, CloudHolder, DiskHolder) {
    // One folder per process: CTest runs the two instantiations in parallel.
    const auto dir = std::filesystem::temp_directory_path() / ("kintsugi_test_surfels_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const auto file = dir / "surfels.ply";
    ks::PointCloud src{kP, kN, kR};
    ks::write_point_cloud(file, src);
    H h;
    auto&& s = h.view();
    ks::read_point_cloud(file, s);
    check_surfels(s);
    // Written back from the user's container, the radii are in the file again.
    const auto file2 = dir / "surfels2.ply";
    ks::write_point_cloud(file2, s);
    ks::ReadInfo info;
    const ks::PointCloud back = ks::read_point_cloud(file2, &info);
    CHECK(info.has_radii);
    CHECK(back.radii == kR);
    std::filesystem::remove_all(dir);
}
