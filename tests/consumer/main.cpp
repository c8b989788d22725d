// Uses the installed headers: builds a kd-tree over a std::vector and checks a query.
#include <kintsugi/adapters/std_vector.hpp>
#include <kintsugi/spatial/kd_tree.hpp>

#include <cstdio>
#include <vector>

int main() {
    std::vector<Eigen::Vector3d> pts;
    for (int i = 0; i < 100; ++i) pts.emplace_back(i, 0.0, 0.0);
    const kintsugi::KdTree tree(pts);
    const auto n = tree.nearest(Eigen::Vector3d(41.2, 1.0, 0.0));
    std::printf("nearest index %zu\n", n.index);
    return n.index == 41 ? 0 : 1;
}
