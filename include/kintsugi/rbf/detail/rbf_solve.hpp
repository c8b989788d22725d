// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file rbf_solve.hpp
/// @brief Internal to the octree RBF: the per-cell triharmonic fit
/// g(u) = Σ_j w_j |u - u_j|³ + a_0 + a·u in the cell's normalised coordinates, and its
/// evaluation. See docs/methods/rbf_octree.md for the choice of factorisation.

#include <kintsugi/core/stages.hpp>
#include <kintsugi/core/types.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace kintsugi::detail {

/// Outcome of one cell's solve.
struct RBFSolveInfo {
    bool ill_conditioned = false;  ///< jitter or the least-squares fallback was needed
};

/// Scratch memory of the per-cell solves, one per thread: grown to the largest cell seen
/// and never shrunk, so that a fit of 100K cells does not allocate (and, for cells above
/// the allocator's mmap threshold, page-fault) a fresh matrix per cell. Eigen's
/// allocator aligns the buffers alike in every thread, so the arithmetic (and its
/// rounding) does not depend on which thread solves a cell.
struct RBFSolveWorkspace {
    Eigen::MatrixXd sym;  ///< m x m: A, then QᵀAQ in its lower triangle, then B₂₂'s Cholesky factor
    Eigen::MatrixXd qr;   ///< m x 4: P, then its Householder QR (reflectors below, R above)
    Eigen::VectorXd vec;  ///< m: Qᵀv, then [Qᵀv head; z]
    Eigen::MatrixXd refl; ///< m x 16: the reflectors V, then W = AV T - ½V TᵀVᵀAV T, then [W V]
    Eigen::ArrayXd x, y, z, d;  ///< m: the centres' coordinates, one column of distances

    void reserve(Eigen::Index m) {
        if (sym.size() < m * m) sym.resize(m * m, 1);
        if (qr.size() < m * 4) qr.resize(m * 4, 1);
        if (refl.size() < m * 16) refl.resize(m * 16, 1);
        if (vec.size() < m) vec.resize(m);
        for (Eigen::ArrayXd* b : {&x, &y, &z, &d})
            if (b->size() < m) b->resize(m);
    }
};

/// The null-space solve (see rbf_solve_cell) with the jitter on B₂₂'s diagonal or
/// without; false when P is rank-deficient, the Cholesky fails, its reciprocal
/// condition estimate is below 1e-13 (without jitter) or the result is not finite.
KINTSUGI_STAGE bool rbf_null_space_solve(const std::vector<Vec3>& u, const std::vector<Scalar>& v, Scalar lambda,
                                         bool jitter, RBFSolveWorkspace& ws, std::vector<Scalar>& w,
                                         Eigen::Vector4d& a);

/// @brief Solves the saddle-point system [A + λI, P; Pᵀ, 0][w; a] = [v; 0] of the
/// centres u (normalised, |u_k| ≤ ~1) and values v, φ(r) = r³, P = [1 u].
/// Null-space method: P = Q[R; 0] (Householder), w = Q₂z with (Q₂ᵀAQ₂ + λI) z = Q₂ᵀv,
/// which is symmetric positive definite for distinct centres not all coplanar (r³ is
/// conditionally positive definite of order 2), so Cholesky applies (n³/3 flops
/// against LU's 2n³/3); then R a = Q₁ᵀ(v - A w). A failed or badly conditioned
/// Cholesky (reciprocal condition estimate below 1e-13) is retried with a diagonal
/// jitter; a rank-deficient P (coplanar centres) goes to a complete orthogonal
/// decomposition of the whole system. The output is always finite for finite input.
/// Works in a per-thread RBFSolveWorkspace.
KINTSUGI_STAGE RBFSolveInfo rbf_solve_cell(const std::vector<Vec3>& u, const std::vector<Scalar>& v, Scalar lambda,
                                           std::vector<Scalar>& w, Eigen::Vector4d& a);

}  // namespace kintsugi::detail

#ifndef KINTSUGI_SEPARATE_STAGES
#include <kintsugi/rbf/detail/rbf_solve.ipp>
#endif
