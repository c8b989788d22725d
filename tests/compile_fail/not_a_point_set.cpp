// This file must NOT compile: a type with no point_set_traits specialisation is
// not a PointSet, and the error names the concept. Checked by CTest.
#include <kintsugi/spatial/kd_tree.hpp>

struct NotAPointSet {
    int count = 3;
};

int main() {
    NotAPointSet s;
    kintsugi::KdTree tree(s);
    return static_cast<int>(tree.size());
}
