// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file rbf_solve.hpp
/// @brief Internal to the octree RBF: the per-cell triharmonic fit
/// g(u) = Σ_j w_j |u - u_j|³ + a_0 + a·u in the cell's normalised coordinates, and its
/// evaluation. See docs/methods/rbf_octree.md for the choice of factorisation.

#include <kintsugi/core/types.hpp>

#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <Eigen/QR>

#include <cmath>
#include <cstdint>
#include <vector>

namespace kintsugi::detail {

/// Outcome of one cell's solve.
struct RBFSolveInfo {
    bool ill_conditioned = false;  ///< jitter or the least-squares fallback was needed
};

/// @brief Solves the saddle-point system [A + λI, P; Pᵀ, 0][w; a] = [v; 0] of the
/// centres u (normalised, |u_k| ≤ ~1) and values v, φ(r) = r³, P = [1 u].
/// Null-space method: P = Q[R; 0] (Householder), w = Q₂z with (Q₂ᵀAQ₂ + λI) z = Q₂ᵀv,
/// which is symmetric positive definite for distinct centres not all coplanar (r³ is
/// conditionally positive definite of order 2), so Cholesky applies (n³/3 flops
/// against LU's 2n³/3); then R a = Q₁ᵀ(v - A w). A failed or badly conditioned
/// Cholesky (reciprocal condition estimate below 1e-13) is retried with a diagonal
/// jitter; a rank-deficient P (coplanar centres) goes to a complete orthogonal
/// decomposition of the whole system. The output is always finite for finite input.
inline RBFSolveInfo rbf_solve_cell(const std::vector<Vec3>& u, const std::vector<Scalar>& v, Scalar lambda,
                                   std::vector<Scalar>& w, Eigen::Vector4d& a) {
    using Mat = Eigen::MatrixXd;
    using VecX = Eigen::VectorXd;
    const auto m = static_cast<Eigen::Index>(u.size());
    RBFSolveInfo info;
    Mat A(m, m);
    for (Eigen::Index i = 0; i < m; ++i) {
        A(i, i) = lambda;
        for (Eigen::Index j = 0; j < i; ++j) {
            const Scalar r = (u[static_cast<std::size_t>(i)] - u[static_cast<std::size_t>(j)]).norm();
            A(i, j) = A(j, i) = r * r * r;
        }
    }
    Mat P(m, 4);
    VecX rhs(m);
    for (Eigen::Index i = 0; i < m; ++i) {
        const Vec3& p = u[static_cast<std::size_t>(i)];
        P.row(i) << 1, p.x(), p.y(), p.z();
        rhs[i] = v[static_cast<std::size_t>(i)];
    }
    w.assign(static_cast<std::size_t>(m), 0);
    a.setZero();
    const Eigen::HouseholderQR<Mat> qr(P);
    const Mat R = qr.matrixQR().topLeftCorner(4, 4).triangularView<Eigen::Upper>();
    const Scalar r0 = std::abs(R(0, 0));
    bool full_rank = m >= 5;
    for (int k = 0; k < 4 && full_rank; ++k) full_rank = std::abs(R(k, k)) > Scalar(1e-9) * r0;
    bool solved = false;
    if (full_rank) {
        Mat B = A;
        B.applyOnTheLeft(qr.householderQ().adjoint());
        B.applyOnTheRight(qr.householderQ());
        VecX qv = rhs;
        qv.applyOnTheLeft(qr.householderQ().adjoint());
        const Eigen::Index n = m - 4;
        Mat B22 = B.bottomRightCorner(n, n);
        Eigen::LLT<Mat> llt(B22);
        bool good = llt.info() == Eigen::Success && llt.rcond() > Scalar(1e-13);
        if (!good) {
            info.ill_conditioned = true;
            const Scalar jitter = Scalar(1e-10) * B22.diagonal().cwiseAbs().maxCoeff() + Scalar(1e-300);
            B22.diagonal().array() += jitter;
            llt.compute(B22);
            good = llt.info() == Eigen::Success;
        }
        if (good) {
            VecX z = llt.solve(qv.tail(n));
            VecX full = VecX::Zero(m);
            full.tail(n) = z;
            full.applyOnTheLeft(qr.householderQ());  // w = Q [0; z]
            VecX res = rhs - A * full;
            res.applyOnTheLeft(qr.householderQ().adjoint());
            const Eigen::Vector4d coef = R.triangularView<Eigen::Upper>().solve(res.head(4));
            if (full.allFinite() && coef.allFinite()) {
                for (Eigen::Index i = 0; i < m; ++i) w[static_cast<std::size_t>(i)] = full[i];
                a = coef;
                solved = true;
            }
        }
    }
    if (!solved) {
        // Coplanar or too few centres: the least-squares, minimum-norm solution.
        info.ill_conditioned = true;
        Mat S = Mat::Zero(m + 4, m + 4);
        S.topLeftCorner(m, m) = A;
        S.topRightCorner(m, 4) = P;
        S.bottomLeftCorner(4, m) = P.transpose();
        VecX b = VecX::Zero(m + 4);
        b.head(m) = rhs;
        const VecX x = S.completeOrthogonalDecomposition().solve(b);
        if (x.allFinite()) {
            for (Eigen::Index i = 0; i < m; ++i) w[static_cast<std::size_t>(i)] = x[i];
            a = x.tail(4);
        } else {  // unreachable for finite input; keep the field finite anyway
            std::fill(w.begin(), w.end(), Scalar(0));
            a.setZero();
        }
    }
    return info;
}

}  // namespace kintsugi::detail
