// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Analytic fields with kintsugi's sign (< 0 inside) and known zero sets, for the
// iso-surface tests and benchmark.
#pragma once

#include <kintsugi/core/types.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <numbers>
#include <vector>

namespace kintsugi_test {

using kintsugi::Scalar;
using kintsugi::Vec3;

/// Sphere of radius 1 centred off the grid's symmetry (exact signed distance).
struct SphereField {
    Vec3 c{0.013, -0.021, 0.007};
    Scalar operator()(const Vec3& x) const { return (x - c).norm() - 1; }
    kintsugi::BoundingBox box() const { return {c - Vec3::Constant(1), c + Vec3::Constant(1)}; }
    long genus() const { return 0; }
};

/// Torus R = 1, r = 0.4 around z (exact signed distance).
struct TorusField {
    Scalar operator()(const Vec3& x) const { return std::hypot(std::hypot(x.x(), x.y()) - 1, x.z()) - Scalar(0.4); }
    kintsugi::BoundingBox box() const { return {Vec3(-1.4, -1.4, -0.4), Vec3(1.4, 1.4, 0.4)}; }
    long genus() const { return 1; }
};

/// Three tori (R = 1, r = 0.35) in a row along x, each ring touching the next: their
/// union is one solid of genus 3. min() of exact distances: exact outside.
struct Genus3Field {
    Scalar torus(const Vec3& x, Scalar cx) const {
        return std::hypot(std::hypot(x.x() - cx, x.y()) - 1, x.z()) - Scalar(0.35);
    }
    Scalar operator()(const Vec3& x) const { return std::min({torus(x, -2), torus(x, 0), torus(x, 2)}); }
    kintsugi::BoundingBox box() const { return {Vec3(-3.35, -1.35, -0.35), Vec3(3.35, 1.35, 0.35)}; }
    long genus() const { return 3; }
};

/// Points on the zero set of a field: lattice points of the box projected along the
/// numerical gradient by a few Newton steps (enough for seeds of a narrow band).
template <class F>
std::vector<Vec3> surface_samples(const F& f, int per_axis) {
    const auto b = f.box();
    std::vector<Vec3> out;
    const Scalar h = 1e-6;
    for (int i = 0; i < per_axis; ++i)
        for (int j = 0; j < per_axis; ++j)
            for (int k = 0; k < per_axis; ++k) {
                Vec3 x = b.min + (b.max - b.min).cwiseProduct(Vec3(i + 0.5, j + 0.5, k + 0.5) / per_axis);
                for (int it = 0; it < 20; ++it) {
                    Vec3 g;
                    for (int a = 0; a < 3; ++a) {
                        Vec3 e = Vec3::Zero();
                        e[a] = h;
                        g[a] = (f(x + e) - f(x - e)) / (2 * h);
                    }
                    if (!(g.squaredNorm() > 1e-12)) break;
                    x -= f(x) * g / g.squaredNorm();
                }
                if (std::abs(f(x)) < 1e-9) out.push_back(x);
            }
    return out;
}

}  // namespace kintsugi_test
