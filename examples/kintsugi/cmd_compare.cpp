// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi compare A B [--samples N] [--threshold T] [--json]`: distances of A
// against the reference mesh B, both directions, relative to B's diagonal.
#include "common.hpp"

#include <kintsugi/io/read.hpp>
#include <kintsugi/metrics/distance.hpp>

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

namespace {

struct CompareOptions {
    std::string a, b;
    std::size_t samples = 200000;
    double threshold = 0.01;
};

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
    cmd.add_option("--samples", o->samples, "Surface samples per mesh")
        ->capture_default_str()
        ->check(CLI::Range(std::size_t{1}, std::size_t{100000000}));
    cmd.add_option("--threshold", o->threshold, "F-score threshold, fraction of the reference diagonal")
        ->capture_default_str()
        ->check(CLI::Range(1e-9, 1.0));
    return [o, &ctx] {
        kcli::Stopwatch sw;
        kintsugi::ReadInfo ia, ib;
        const kintsugi::IndexedMesh a = kintsugi::read_mesh(o->a, {}, &ia);
        const kintsugi::IndexedMesh b = kintsugi::read_mesh(o->b, {}, &ib);
        ctx.add_timing("read", sw.seconds());
        if (b.faces.empty())
            throw kintsugi::invalid_input(o->b + ": the reference has no faces; compare needs a reference mesh");

        kintsugi::DistanceParams params;
        params.samples = o->samples;
        params.seed = ctx.common.seed;
        params.fscore_threshold = o->threshold;
        params.control = ctx.control("compare");
        const kintsugi::DistanceReport r = a.faces.empty() ? kintsugi::compare_points(kintsugi::PointCloud{a.vertices, a.normals, {}}, b, params)
                                                           : kintsugi::compare(a, b, params);
        ctx.end_progress();
        if (r.status == kintsugi::Status::cancelled) throw std::runtime_error("cancelled");
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
        j["parameters"]["samples"] = o->samples;
        j["parameters"]["threshold"] = o->threshold;
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
                      o->threshold, r.normal_consistency);
        ctx.info(o->a + " against " + o->b + " (diagonal " + std::to_string(r.diagonal) + ")\n" +
                 directed_line("A->B", ab) + "\n" + directed_line("B->A", ba) + "\n" +
                 directed_line("chamfer", chamfer) + "\n" + fs);
    };
}

}  // namespace

KINTSUGI_REGISTER_COMMAND(compare, "Distances of a mesh or point cloud against a reference mesh", setup)
