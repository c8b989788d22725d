// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi compare A B [--samples N] [--threshold T] [--json]`: distances of A
// against the reference mesh B, both directions, relative to B's diagonal.
#include "common.hpp"

#include <kintsugi/metrics/distance.hpp>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

namespace {

struct CompareOptions {
    std::string a, b;
    kintsugi::DistanceParams params;  // the library's defaults
};

/// Largest --samples: kintsugi::compare holds about 180 bytes per sample and mesh at
/// its peak (samples, their Morton order, closest points, distances), so 10 million
/// take about 2 GB; more would not fit next to the meshes on a small machine, and the
/// measures no longer change (200,000 give the mean to about 0.3 %).
constexpr std::uint64_t kMaxSamples = 10000000;

kcli::Json directed_json(const kintsugi::DirectedDistance& d) {
    auto j = kcli::Json::object();
    j["mean"] = d.mean;
    j["rms"] = d.rms;
    j["p99"] = d.p99;
    j["hausdorff"] = d.hausdorff;
    j["fscore"] = d.fscore_part;
    return j;
}

std::string directed_line(const char* name, const kintsugi::DirectedDistance& d) {
    char buf[256];
    std::snprintf(buf, sizeof buf, "  %-8s mean %.4e  rms %.4e  p99 %.4e  hausdorff %.4e  (relative to diagonal)",
                  name, d.mean, d.rms, d.p99, d.hausdorff);
    return buf;
}

kcli::Action setup(CLI::App& cmd, kcli::Context& ctx) {
    auto o = std::make_shared<CompareOptions>();
    cmd.add_option("a", o->a, "Mesh or point cloud to measure")->required();
    cmd.add_option("b", o->b, "Reference mesh")->required();
    cmd.add_option("--samples", o->params.samples, "Surface samples per mesh (at most 10 million: ~180 bytes each)")
        ->capture_default_str()
        ->check(kcli::count(1, kMaxSamples));
    cmd.add_option("--threshold", o->params.fscore_threshold, "F-score threshold, fraction of the reference diagonal")
        ->capture_default_str()
        ->check(kcli::real(1e-9, 1.0));
    return [o, &ctx] {
        kcli::Stopwatch sw;
        kintsugi::ReadInfo ia, ib;
        ctx.doing("reading " + o->a);
        const kintsugi::IndexedMesh a = kcli::read_mesh(o->a, &ia);
        ctx.doing("reading " + o->b);
        const kintsugi::IndexedMesh b = kcli::read_mesh(o->b, &ib);
        ctx.add_timing("read", sw.seconds());
        if (b.faces.empty())
            throw kintsugi::invalid_input(o->b + ": the reference has no faces; compare needs a reference mesh");

        kintsugi::DistanceParams params = o->params;
        params.seed = ctx.common.seed;
        params.control = ctx.control("compare");
        ctx.doing("comparing " + o->a + " with " + o->b + " (" + kcli::grouped(params.samples) + " samples)");
        const kintsugi::DistanceReport r = a.faces.empty() ? kintsugi::compare_points(kintsugi::PointCloud{a.vertices, a.normals, {}}, b, params)
                                                           : kintsugi::compare(a, b, params);
        ctx.end_progress();
        if (r.status == kintsugi::Status::cancelled) throw kcli::interrupted();
        ctx.add_timings(r.timings);

        const auto ab = r.relative(r.a_to_b), ba = r.relative(r.b_to_a);
        kintsugi::DirectedDistance chamfer{};
        chamfer.mean = (ab.mean + ba.mean) / 2;
        chamfer.rms = std::sqrt((ab.rms * ab.rms + ba.rms * ba.rms) / 2);
        chamfer.p99 = std::max(ab.p99, ba.p99);
        chamfer.hausdorff = std::max(ab.hausdorff, ba.hausdorff);
        chamfer.fscore_part = r.fscore;

        auto& j = ctx.json();
        j["command"] = "compare";
        j["a"] = o->a;
        j["b"] = o->b;
        j["parameters"]["samples"] = params.samples;
        j["parameters"]["threshold"] = params.fscore_threshold;
        j["parameters"]["seed"] = static_cast<unsigned long long>(ctx.common.seed);
        j["diagonal"] = r.diagonal;
        j["a_to_b"] = directed_json(ab);
        j["b_to_a"] = directed_json(ba);
        j["chamfer"] = directed_json(chamfer);
        j["normal_consistency"] = r.normal_consistency;
        auto& abs = j["absolute"];
        abs["a_to_b"] = directed_json(r.a_to_b);
        abs["b_to_a"] = directed_json(r.b_to_a);
        abs["chamfer"] = r.chamfer;
        j["samples_a"] = r.samples_a;
        j["samples_b"] = r.samples_b;

        char fs[160];
        std::snprintf(fs, sizeof fs, "  F-score %.4f at %.4g x diagonal; normal consistency %.4f", r.fscore,
                      params.fscore_threshold, r.normal_consistency);
        ctx.info(o->a + " against " + o->b + " (diagonal " + std::to_string(r.diagonal) + ")\n" +
                 directed_line("A->B", ab) + "\n" + directed_line("B->A", ba) + "\n" +
                 directed_line("chamfer", chamfer) + "\n" + fs);
    };
}

}  // namespace

KINTSUGI_REGISTER_COMMAND(compare, "Distances of a mesh or point cloud against a reference mesh", setup)
