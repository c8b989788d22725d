// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi normals IN OUT [--k N] [--method pca|jet] [--no-orient]`: estimate
// (and consistently orient) point normals.
#include "reconstruct_cli.hpp"

#include <kintsugi/normals/estimate_normals.hpp>

#include <memory>
#include <string>

namespace {

struct NormalsOptions {
    std::string input, output;
    kintsugi::NormalParams params;  // the library's defaults
    std::string method = params.method == kintsugi::NormalMethod::jet ? "jet" : "pca";
    bool no_orient = !params.orient;
};

/// Jet fitting needs the point and 5 neighbours for the quadric's 6 coefficients
/// (kintsugi::estimate_normals refuses a smaller k).
constexpr std::size_t kJetMinK = 5;

kcli::Action setup(CLI::App& cmd, kcli::Context& ctx) {
    auto o = std::make_shared<NormalsOptions>();
    cmd.add_option("input", o->input, "Point cloud or mesh (PLY, OFF, OBJ, XYZ, PWN)")->required();
    cmd.add_option("output", o->output, "Oriented point cloud to write (PLY, XYZ, PWN, OFF, OBJ)")->required();
    cmd.add_option("--k", o->params.k, "Neighbours per estimate (jet: at least 5)")
        ->capture_default_str()
        ->check(kcli::count(3, 1000));
    cmd.add_option("--method", o->method, "pca or jet")
        ->capture_default_str()
        ->check(CLI::IsMember({"pca", "jet"}));
    cmd.add_flag("--no-orient", o->no_orient, "Keep the estimated directions without consistent orientation");
    return [o, &ctx] {
        if (o->method == "jet" && o->params.k < kJetMinK)
            throw kcli::usage_error("--k " + std::to_string(o->params.k) + " is too small for --method jet, which " +
                                    "needs --k " + std::to_string(kJetMinK) + " or more (a quadric has 6 coefficients)");
        ctx.check_output(o->output, kintsugi::OutputKind::point_cloud);
        kcli::Stopwatch sw;
        ctx.doing("reading " + o->input);
        kintsugi::PointCloud cloud = kcli::read_point_cloud(o->input);
        ctx.add_timing("read", sw.seconds());
        if (cloud.points.size() < o->params.k)
            throw kintsugi::invalid_input(o->input + " has " + kcli::grouped(cloud.points.size()) +
                                          " points, fewer than --k " + std::to_string(o->params.k) +
                                          "; lower --k or give more points");

        kintsugi::NormalParams params = o->params;
        params.method = o->method == "jet" ? kintsugi::NormalMethod::jet : kintsugi::NormalMethod::pca;
        params.orient = !o->no_orient;
        params.control = ctx.control("normals");
        ctx.doing("estimating the normals of " + kcli::grouped(cloud.points.size()) + " points of " + o->input);
        const kintsugi::NormalResult r = kintsugi::estimate_normals(cloud, params);
        ctx.end_progress();
        if (r.status == kintsugi::Status::cancelled) throw kcli::interrupted();
        ctx.add_timings(r.timings);

        sw = kcli::Stopwatch();
        ctx.doing("writing " + o->output);
        kcli::write_point_cloud(o->output, cloud, ctx.write_options());
        ctx.add_timing("write", sw.seconds());

        auto& j = ctx.json();
        j["command"] = "normals";
        j["input"] = o->input;
        j["output"] = o->output;
        j["parameters"]["k"] = o->params.k;
        j["parameters"]["method"] = o->method;
        j["parameters"]["orient"] = !o->no_orient;
        j["points"] = cloud.points.size();
        j["components"] = r.components;
        ctx.info("estimated " + std::string(o->no_orient ? "" : "and oriented ") + "normals of " +
                 std::to_string(cloud.points.size()) + " points (k = " + std::to_string(o->params.k) + ", " + o->method +
                 (o->no_orient ? "" : ", " + std::to_string(r.components) + " component(s)") + ") -> " + o->output);
    };
}

}  // namespace

namespace kcli::reconstruct {

bool estimate_missing_normals(Context& ctx, kintsugi::PointCloud& cloud, const std::string& input) {
    if (kintsugi::has_normals(cloud)) return false;
    kintsugi::NormalParams np;  // the library's defaults
    ctx.notice(input + " has no normals; estimating and orienting them (" +
               (np.method == kintsugi::NormalMethod::jet ? "jet" : "PCA") + ", k = " + std::to_string(np.k) +
               ", outward)");
    np.control = ctx.control("normals");
    ctx.doing("estimating the normals of " + grouped(cloud.points.size()) + " points of " + input);
    const auto nr = kintsugi::estimate_normals(cloud, np);
    ctx.end_progress();
    if (nr.status == kintsugi::Status::cancelled) throw interrupted();
    ctx.add_timings(nr.timings, "normals_");
    return true;
}

}  // namespace kcli::reconstruct

KINTSUGI_REGISTER_COMMAND(normals, "Estimate and consistently orient point normals", setup)
