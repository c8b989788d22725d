// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Example: read a mesh in any supported format and print its topology report.
//   example_read_mesh_report tests/data/bunny.off
#include <kintsugi/io/read.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: %s MESH\n", argv[0]);
        return 2;
    }
    try {
        const kintsugi::IndexedMesh mesh = kintsugi::read_mesh(argv[1]);
        const kintsugi::TopologyReport r = kintsugi::topology_report(mesh);
        std::printf("%zu vertices, %zu faces, %zu component(s), %zu boundary loop(s), genus %ld, %s\n", r.vertices,
                    r.faces, r.components, r.boundary_loops, r.genus, r.closed ? "closed" : "open");
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
    return 0;
}
