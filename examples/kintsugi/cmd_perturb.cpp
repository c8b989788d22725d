// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi perturb IN OUT [--outliers 0.1] [--noise 0] [--seed S]`: a documented,
// seeded way to make test and demo inputs harder: Gaussian noise on every point and
// extra outliers drawn uniformly in the bounding box enlarged by 10 %.
#include "common.hpp"


#include <cmath>
#include <memory>
#include <random>
#include <string>

namespace {

struct PerturbOptions {
    std::string input, output;
    double outliers = 0.1;
    double noise = 0.0;
};

kcli::Action setup(CLI::App& cmd, kcli::Context& ctx) {
    auto o = std::make_shared<PerturbOptions>();
    cmd.add_option("input", o->input, "Point cloud or mesh (its vertices are used)")->required();
    cmd.add_option("output", o->output, "Point cloud to write (PLY, XYZ, PWN, OFF)")->required();
    cmd.add_option("--outliers", o->outliers,
                   "Outliers to add, as a fraction of the input point count, uniform in the bounding box "
                   "enlarged by 10 % (each side), with random unit normals")
        ->capture_default_str()
        ->check(kcli::real(0.0, 10.0));
    cmd.add_option("--noise", o->noise,
                   "Gaussian noise on every input point: sigma = noise x bounding-box diagonal (isotropic)")
        ->capture_default_str()
        ->check(kcli::real(0.0, 1.0));
    return [o, &ctx] {
        ctx.check_output(o->output, kintsugi::OutputKind::point_cloud);
        ctx.doing("reading " + o->input);
        kintsugi::PointCloud cloud = kcli::read_point_cloud(o->input);
        if (cloud.points.empty()) throw kintsugi::invalid_input(o->input + ": the file holds no points");
        const bool normals = kintsugi::has_normals(cloud);
        cloud.radii.clear();
        kintsugi::BoundingBox box;
        for (const auto& p : cloud.points) box.extend(p);
        // One generator, consumed in a fixed order: noise for every point, then outliers.
        std::mt19937_64 rng(ctx.common.seed);
        std::normal_distribution<double> gauss(0.0, 1.0);
        std::uniform_real_distribution<double> uni(0.0, 1.0);
        const double sigma = o->noise * box.diagonal() / std::sqrt(3.0);
        const std::size_t n = cloud.points.size();
        // Options are finite and in range (kcli::real), so m <= 10 n.
        const auto m = static_cast<std::size_t>(std::llround(o->outliers * static_cast<double>(n)));
        ctx.doing("adding " + kcli::grouped(m) + " outliers to the " + kcli::grouped(n) + " points of " + o->input);
        constexpr std::size_t poll = 1 << 16;  // points between two looks at Ctrl-C
        if (sigma > 0)
            for (std::size_t i = 0; i < n; ++i) {
                if (i % poll == 0) ctx.check_interrupted();
                cloud.points[i] += sigma * kintsugi::Vec3(gauss(rng), gauss(rng), gauss(rng));
            }
        const kintsugi::Vec3 c = box.center(), e = 1.1 * box.extent();
        cloud.points.reserve(n + m);
        if (normals) cloud.normals.reserve(n + m);
        for (std::size_t i = 0; i < m; ++i) {
            if (i % poll == 0) ctx.check_interrupted();
            cloud.points.push_back(c + kintsugi::Vec3((uni(rng) - 0.5) * e.x(), (uni(rng) - 0.5) * e.y(),
                                                      (uni(rng) - 0.5) * e.z()));
            kintsugi::Vec3 d(gauss(rng), gauss(rng), gauss(rng));
            if (normals) cloud.normals.push_back(d.normalized());
        }
        ctx.check_interrupted();
        ctx.doing("writing " + o->output);
        kcli::write_point_cloud(o->output, cloud, ctx.write_options());
        auto& j = ctx.json();
        j["command"] = "perturb";
        j["input"] = o->input;
        j["output"] = o->output;
        j["parameters"]["outliers"] = o->outliers;
        j["parameters"]["noise"] = o->noise;
        j["parameters"]["seed"] = ctx.common.seed;
        j["input_points"] = n;
        j["outliers_added"] = m;
        j["points"] = cloud.points.size();
        ctx.info("added " + std::to_string(m) + " outliers" +
                 (sigma > 0 ? " and noise sigma " + std::to_string(sigma) : std::string()) + " to " +
                 std::to_string(n) + " points (seed " + std::to_string(ctx.common.seed) + ") -> " + o->output);
    };
}

}  // namespace

KINTSUGI_REGISTER_COMMAND(perturb, "Add seeded noise and uniform outliers to a point cloud (test/demo inputs)", setup)
