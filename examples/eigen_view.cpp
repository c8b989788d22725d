// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Example: libigl-style Eigen V/F matrices used in place, without copies.
#include <kintsugi/adapters/eigen.hpp>
#include <kintsugi/metrics/topology_report.hpp>

#include <Eigen/Core>

#include <cstdio>

int main() {
    // An octahedron as V (6x3) and F (8x3), the layout libigl uses.
    Eigen::MatrixXd V(6, 3);
    V << 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1;
    Eigen::MatrixXi F(8, 3);
    F << 0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5;

    auto mesh = kintsugi::eigen_mesh(V, F);  // a non-owning, writable view
    const kintsugi::TopologyReport r = kintsugi::topology_report(mesh);
    std::printf("octahedron: %zu vertices, %zu faces, genus %ld, %s, %s\n", r.vertices, r.faces, r.genus,
                r.closed ? "closed" : "open", r.consistently_oriented ? "consistently oriented" : "inconsistent");

    // Writes through the view reach the matrix.
    kintsugi::set_vertex_position(mesh, 4, kintsugi::Vec3(0, 0, 2));
    std::printf("V(4, 2) is now %g\n", V(4, 2));
    return r.closed && r.genus == 0 ? 0 : 1;
}
