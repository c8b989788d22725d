// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
// Example: estimate oriented normals directly on a user's own point struct,
// without copying it into a kintsugi type: a view through projections.
#include <kintsugi/adapters/projection.hpp>
#include <kintsugi/normals/estimate_normals.hpp>

#include <cmath>
#include <cstdio>
#include <vector>

// The user's own type: kintsugi does not ask it to change.
struct ScanSample {
    float position[3];
    std::array<float, 3> normal;
    unsigned char intensity;
};

int main() {
    // A unit sphere sampled on a Fibonacci spiral.
    std::vector<ScanSample> samples;
    const int n = 2000;
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - 2.0 * (i + 0.5) / n, r = std::sqrt(1.0 - z * z);
        const double phi = i * 2.399963229728653;
        samples.push_back({{float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)}, {0, 0, 0}, 0});
    }

    auto view = kintsugi::project_points(samples, &ScanSample::position, &ScanSample::normal);
    const kintsugi::NormalResult result = kintsugi::estimate_normals(view, {.k = 12});

    // Outward orientation: the normal agrees with the position on a centred sphere.
    int outward = 0;
    for (const auto& s : samples)
        outward += (s.position[0] * s.normal[0] + s.position[1] * s.normal[1] + s.position[2] * s.normal[2]) > 0;
    std::printf("%zu points, %zu component(s); %d of %d normals point outward\n", result.points, result.components,
                outward, n);
    return outward == n ? 0 : 1;
}
