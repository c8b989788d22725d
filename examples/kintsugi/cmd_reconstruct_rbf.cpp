// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi reconstruct --method rbf`: the octree triharmonic RBF surface (options and
// run; the command itself is registered in cmd_reconstruct.cpp).
#include "reconstruct_cli.hpp"

#include <kintsugi/rbf/rbf_octree.hpp>

#include <string>
#include <utility>

namespace kcli::reconstruct {

struct RbfOptions {
    kintsugi::RBFOctreeParams params;  // the library's defaults
    bool no_blend = !params.blend;
};

std::shared_ptr<RbfOptions> add_rbf_options(CLI::App& cmd, std::vector<CLI::Option*>& rbf_only) {
    auto o = std::make_shared<RbfOptions>();
    auto& r = o->params;
    const auto rbf_option = [&cmd, &rbf_only](const char* name, auto& value, const char* help,
                                              const CLI::Validator& check) {
        rbf_only.push_back(cmd.add_option(name, value, std::string("rbf: ") + help)->capture_default_str()->check(check));
    };
    rbf_option("--n-max", r.n_max, "a cell splits while more centres are assigned to it (>= 10)", count(10, 100000));
    rbf_option("--overlap", r.overlap, "overlap factor alpha of the cells (1 to 3; paper 1.3-1.4)", real(1.0, 3.0));
    rbf_option("--activity", r.activity, "activity factor beta of dead cells (1 to 3; paper 1.05)", real(1.0, 3.0));
    rbf_option("--resolution", r.resolution, "polygonisation cubes along the longest side", count(8, 4096));
    rbf_only.push_back(
        cmd.add_flag("--no-blend", o->no_blend, "rbf: the paper's single-cell evaluation (seams) instead of the blend"));
    return o;
}

double rbf_default_smoothing() { return kintsugi::RBFOctreeParams{}.smoothing; }

void run_rbf(const RbfOptions& options, const RbfRun& run, Context& ctx, kintsugi::PointCloud& cloud) {
    kintsugi::RBFOctreeParams p = options.params;
    if (run.smoothing) p.smoothing = *run.smoothing;
    p.blend = !options.no_blend;
    p.control = ctx.control("reconstruct");
    if (run.inward)
        for (kintsugi::Vec3& n : cloud.normals) n = -n;
    ctx.doing("reconstructing an RBF surface from the " + grouped(cloud.points.size()) + " points of " + run.input +
              " (--n-max " + std::to_string(p.n_max) + ", --resolution " + std::to_string(p.resolution) + ")");
    kintsugi::RBFReconstructResult r = kintsugi::reconstruct_rbf_octree(cloud, p);
    ctx.end_progress();
    if (r.status == kintsugi::Status::cancelled) throw interrupted();
    ctx.add_timings(r.timings);
    if (r.mesh.faces.empty()) {
        // An empty mesh is no result: the surface fell between the polygonisation's samples.
        kintsugi::BoundingBox box;
        for (const kintsugi::Vec3& q : cloud.points) box.extend(q);
        throw kintsugi::invalid_input(
            "no surface was found at --resolution " + std::to_string(p.resolution) + ": a polygonisation cube is " +
            kintsugi::detail::format_number(box.extent().maxCoeff() / p.resolution) +
            " wide, more than the points' features or the gaps between groups of them; raise --resolution, or "
            "reconstruct each group separately (--method pu-graphcut gives each group its own box)");
    }
    const kintsugi::TopologyReport rep = write_surface(ctx, run.output, r.mesh);
    const auto& st = r.stats;
    auto& j = ctx.json();
    const std::pair<const char*, Json> top[] = {{"command", "reconstruct"}, {"input", run.input}, {"output", run.output}};
    for (const auto& [key, value] : top) j[key] = value;
    const std::pair<const char*, Json> parameters[] = {
        {"method", "rbf"},        {"n_max", p.n_max},         {"overlap", p.overlap},
        {"activity", p.activity}, {"smoothing", p.smoothing}, {"resolution", p.resolution},
        {"blend", p.blend},       {"inward_normals", run.inward}};
    for (const auto& [key, value] : parameters) j["parameters"][key] = value;
    const std::pair<const char*, Json> counts[] = {
        {"normals_estimated", run.normals_estimated},
        {"points", st.points},
        {"merged_points", st.merged_points},
        {"offset_points", st.offset_points},
        {"cells", st.cells},
        {"live_cells", st.live_cells},
        {"dead_cells", st.dead_cells},
        {"max_points_per_cell", st.max_points_per_cell},
        {"mean_points_per_cell", st.mean_points_per_cell},
        {"ill_conditioned_cells", st.ill_conditioned_cells},
        {"padded_cells", st.padded_cells},
        {"capped_cells", st.capped_cells},
        {"capped_centres", st.capped_centres},
        {"crease_offsets", st.crease_offsets},
        {"field_evaluations", r.isosurface.field_evaluations},
        {"vertices", rep.vertices},
        {"faces", rep.faces},
        {"components", rep.components},
        {"genus", rep.genus},
        {"closed", rep.closed},
        {"manifold", rep.manifold}};
    for (const auto& [key, value] : counts) j[key] = value;
    ctx.info("reconstructed " + std::to_string(st.points) + " points (" + std::to_string(st.live_cells) +
             " live cells of " + std::to_string(st.cells) + ", at most " + std::to_string(st.max_points_per_cell) +
             " centres each, " + std::to_string(st.ill_conditioned_cells) + " ill-conditioned) -> " +
             std::to_string(rep.vertices) + " vertices, " + std::to_string(rep.faces) + " faces, " +
             std::to_string(rep.components) + " component(s), genus " + std::to_string(rep.genus) +
             (rep.closed && rep.manifold ? ", closed manifold" : "") + " -> " + run.output);
}

}  // namespace kcli::reconstruct
