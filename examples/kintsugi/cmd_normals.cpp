// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi normals IN OUT [--k N] [--method pca|jet] [--no-orient]`: estimate
// (and consistently orient) point normals.
#include "common.hpp"

#include <kintsugi/io/read.hpp>
#include <kintsugi/io/write.hpp>
#include <kintsugi/normals/estimate_normals.hpp>

#include <map>
#include <memory>
#include <string>

namespace {

struct NormalsOptions {
    std::string input, output;
    std::size_t k = 18;
    std::string method = "pca";
    bool no_orient = false;
};

kcli::Action setup(CLI::App& cmd, kcli::Context& ctx) {
    auto o = std::make_shared<NormalsOptions>();
    cmd.add_option("input", o->input, "Point cloud or mesh (PLY, OFF, OBJ, XYZ, PWN)")->required();
    cmd.add_option("output", o->output, "Oriented point cloud to write (PLY, XYZ, PWN, OFF)")->required();
    cmd.add_option("--k", o->k, "Neighbours per estimate")->capture_default_str()->check(CLI::Range(3, 1000));
    cmd.add_option("--method", o->method, "pca or jet")
        ->capture_default_str()
        ->check(CLI::IsMember({"pca", "jet"}));
    cmd.add_flag("--no-orient", o->no_orient, "Keep the estimated directions without consistent orientation");
    return [o, &ctx] {
        kcli::Stopwatch sw;
        kintsugi::PointCloud cloud = kintsugi::read_point_cloud(o->input);
        ctx.add_timing("read", sw.seconds());

        kintsugi::NormalParams params;
        params.k = o->k;
        params.method = o->method == "jet" ? kintsugi::NormalMethod::jet : kintsugi::NormalMethod::pca;
        params.orient = !o->no_orient;
        params.control = ctx.control("normals");
        const kintsugi::NormalResult r = kintsugi::estimate_normals(cloud, params);
        ctx.end_progress();
        if (r.status == kintsugi::Status::cancelled) throw std::runtime_error("cancelled; nothing written");
        ctx.add_timings(r.timings);

        sw = kcli::Stopwatch();
        kintsugi::write_point_cloud(o->output, cloud);
        ctx.add_timing("write", sw.seconds());

        auto& j = ctx.json();
        j["command"] = "normals";
        j["input"] = o->input;
        j["output"] = o->output;
        j["parameters"]["k"] = o->k;
        j["parameters"]["method"] = o->method;
        j["parameters"]["orient"] = !o->no_orient;
        j["points"] = cloud.points.size();
        j["components"] = r.components;
        ctx.info("estimated " + std::string(o->no_orient ? "" : "and oriented ") + "normals of " +
                 std::to_string(cloud.points.size()) + " points (k = " + std::to_string(o->k) + ", " + o->method +
                 (o->no_orient ? "" : ", " + std::to_string(r.components) + " component(s)") + ") -> " + o->output);
    };
}

}  // namespace

KINTSUGI_REGISTER_COMMAND(normals, "Estimate and consistently orient point normals", setup)
