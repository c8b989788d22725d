// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// `kintsugi info FILE [--json]`: the topology report of a mesh, or the summary
// of a point cloud.
#include "common.hpp"

#include <kintsugi/mesh/geometry.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include <memory>
#include <sstream>
#include <string>

namespace {

struct InfoOptions {
    std::string input;
};

kcli::Json vec_json(const kintsugi::Vec3& v) { return kcli::Json::Array{v.x(), v.y(), v.z()}; }

kcli::Action setup(CLI::App& cmd, kcli::Context& ctx) {
    auto o = std::make_shared<InfoOptions>();
    cmd.add_option("file", o->input, "Mesh or point cloud (PLY, OFF, OBJ, XYZ, PWN)")->required();
    return [o, &ctx] {
        kcli::Stopwatch sw;
        kintsugi::ReadInfo ri;
        ctx.doing("reading " + o->input);
        const kintsugi::IndexedMesh mesh = kcli::read_mesh(o->input, &ri);
        ctx.add_timing("read", sw.seconds());

        auto& j = ctx.json();
        j["command"] = "info";
        j["file"] = o->input;
        j["format"] = ri.format;
        const kintsugi::BoundingBox box = kintsugi::bounding_box(mesh.vertices);
        j["bbox_min"] = vec_json(box.min);
        j["bbox_max"] = vec_json(box.max);
        j["diagonal"] = box.diagonal();
        j["has_normals"] = ri.has_normals;
        if (ri.polygons_triangulated > 0) j["polygons_triangulated"] = ri.polygons_triangulated;

        std::ostringstream human;
        human << o->input << " (" << ri.format << ")\n";
        if (mesh.faces.empty()) {
            j["vertices"] = mesh.vertices.size();
            j["faces"] = 0;
            j["points_only"] = true;
            human << "  points             " << mesh.vertices.size() << (ri.has_normals ? " (with normals)" : "")
                  << "\n  faces              0 (point cloud)\n";
        } else {
            sw = kcli::Stopwatch();
            ctx.doing("computing the topology of the " + kcli::grouped(mesh.faces.size()) + " faces of " + o->input);
            const kintsugi::TopologyReport r = kintsugi::topology_report(mesh);
            ctx.add_timing("topology", sw.seconds());
            j["vertices"] = r.vertices;
            j["faces"] = r.faces;
            j["edges"] = r.edges;
            j["components"] = r.components;
            j["isolated_vertices"] = r.isolated_vertices;
            j["boundary_loops"] = r.boundary_loops;
            j["boundary_edges"] = r.boundary_edges;
            j["non_manifold_edges"] = r.non_manifold_edges;
            j["non_manifold_vertices"] = r.non_manifold_vertices;
            j["degenerate_faces"] = r.degenerate_faces;
            j["euler"] = r.euler;
            j["genus"] = r.genus;
            j["closed"] = r.closed;
            j["manifold"] = r.manifold;
            j["consistently_oriented"] = r.consistently_oriented;
            human << "  vertices           " << r.vertices << "\n"
                  << "  faces              " << r.faces << "\n"
                  << "  edges              " << r.edges << "\n"
                  << "  components         " << r.components << "\n"
                  << "  isolated vertices  " << r.isolated_vertices << "\n"
                  << "  boundary loops     " << r.boundary_loops << " (" << r.boundary_edges << " edges)\n"
                  << "  non-manifold       " << r.non_manifold_edges << " edges, " << r.non_manifold_vertices
                  << " vertices\n"
                  << "  degenerate faces   " << r.degenerate_faces << "\n"
                  << "  genus              " << (r.genus < 0 ? std::string("undefined") : std::to_string(r.genus))
                  << "\n"
                  << "  closed             " << (r.closed ? "yes" : "no") << "\n"
                  << "  oriented           " << (r.consistently_oriented ? "consistently" : "inconsistently")
                  << "\n";
        }
        human << "  bounding box       [" << box.min.transpose() << "] - [" << box.max.transpose()
              << "], diagonal " << box.diagonal();
        ctx.info(human.str());
    };
}

}  // namespace

KINTSUGI_REGISTER_COMMAND(info, "Report the topology of a mesh or the summary of a point cloud", setup)
