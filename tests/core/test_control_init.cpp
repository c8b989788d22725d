// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// RunControl is filled with designated initializers in user code compiled with -Wall -Wextra:
// every member has a default initialiser, so leaving one out is not a warning. This file turns
// -Wmissing-field-initializers into an error: it does not compile if a member loses its default.
#pragma GCC diagnostic error "-Wmissing-field-initializers"

#include <doctest/doctest.h>

#include <kintsugi/core/control.hpp>
#include <kintsugi/mesh/taubin.hpp>

#include <stop_token>

namespace ks = kintsugi;

namespace {
// A Params aggregate in the house style (the real ones append fields the same way).
struct UserParams {
    int k = 18;
    ks::RunControl control{};
};
}  // namespace

TEST_CASE("RunControl compiles with designated initializers that leave members out") {
    std::stop_source src;
    const ks::RunControl only_stop{.stop = src.get_token()};
    const ks::RunControl only_progress{.progress = [](const ks::ProgressEvent&) { return true; }};
    const UserParams p{.control = {.stop = src.get_token()}};
    const ks::TaubinParams tp{.iterations = 3, .control = {.stop = src.get_token()}};
    CHECK(!only_stop.progress);
    CHECK(!only_progress.stop.stop_possible());
    CHECK(p.k == 18);
    CHECK(tp.iterations == 3);
    src.request_stop();
    CHECK(only_stop.stop.stop_requested());
    CHECK(p.control.stop.stop_requested());
    CHECK(tp.control.stop.stop_requested());
}
