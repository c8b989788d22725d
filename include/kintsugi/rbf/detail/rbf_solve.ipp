// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file rbf_solve.ipp
/// @brief The bodies of the octree RBF's per-cell solve (declared and documented in
/// rbf_solve.hpp). Included by rbf_solve.hpp, or, with KINTSUGI_SEPARATE_STAGES, by the one
/// file of the program that compiles it (kintsugi/core/stages.hpp): the dense solvers it
/// instantiates (Householder QR, Cholesky, the complete orthogonal decomposition) are then
/// compiled once, apart from the fit.

#include <kintsugi/rbf/detail/rbf_solve.hpp>

#include <Eigen/Cholesky>
#include <Eigen/QR>

namespace kintsugi::detail {

/// Applies the k-th reflector of the QR in `qr` (H_k = I - τ_k h hᵀ, h = [0…0 1 essential])
/// to the vector x.
inline void rbf_apply_reflector(const Eigen::Ref<const Eigen::MatrixXd>& qr, Eigen::Index k, double tau,
                                Eigen::Ref<Eigen::VectorXd> x) {
    const Eigen::Index m = x.size();
    const double s = tau * (x[k] + qr.col(k).tail(m - k - 1).dot(x.tail(m - k - 1)));
    x[k] -= s;
    x.tail(m - k - 1) -= s * qr.col(k).tail(m - k - 1);
}

/// See rbf_solve.hpp.
KINTSUGI_STAGE bool rbf_null_space_solve(const std::vector<Vec3>& u, const std::vector<Scalar>& v, Scalar lambda,
                                         bool jitter, RBFSolveWorkspace& ws, std::vector<Scalar>& w,
                                         Eigen::Vector4d& a) {
    const auto m = static_cast<Eigen::Index>(u.size());
    const Eigen::Index n = m - 4;
    ws.reserve(m);
    // P = [1 u] and its Householder QR in place (Eigen's unblocked algorithm, 4 columns).
    Eigen::Map<Eigen::MatrixXd> P(ws.qr.data(), m, 4);
    for (Eigen::Index i = 0; i < m; ++i) {
        const Vec3& p = u[static_cast<std::size_t>(i)];
        P(i, 0) = 1;
        P(i, 1) = ws.x[i] = p.x();
        P(i, 2) = ws.y[i] = p.y();
        P(i, 3) = ws.z[i] = p.z();
    }
    double tau[4];
    double work[4];
    for (Eigen::Index k = 0; k < 4; ++k) {
        double beta = 0;
        P.col(k).tail(m - k).makeHouseholderInPlace(tau[k], beta);
        P(k, k) = beta;
        if (k < 3) P.bottomRightCorner(m - k, 3 - k).applyHouseholderOnTheLeft(P.col(k).tail(m - k - 1), tau[k], work);
    }
    const double r0 = std::abs(P(0, 0));
    for (Eigen::Index k = 0; k < 4; ++k)
        if (!(std::abs(P(k, k)) > 1e-9 * r0)) return false;

    // A (lower triangle), one column at a time: r³ of the distances below the diagonal.
    Eigen::Map<Eigen::MatrixXd> B(ws.sym.data(), m, m);
    for (Eigen::Index j = 0; j < m; ++j) {
        const Eigen::Index t = m - j - 1;
        auto d = ws.d.head(t);
        d = (ws.x.segment(j + 1, t) - ws.x[j]).square() + (ws.y.segment(j + 1, t) - ws.y[j]).square() +
            (ws.z.segment(j + 1, t) - ws.z[j]).square();
        d = d * d.sqrt();
        B(j, j) = lambda;
        B.col(j).tail(t) = d.matrix();
    }
    // QᵀAQ with Q = H₀H₁H₂H₃ = I - V T Vᵀ (compact WY form: V the unit reflectors, T upper
    // triangular 4 x 4): with Y = AV and M = VᵀY, QᵀAQ = A - V Wᵀ - W Vᵀ where
    // W = Y T - ½ V (Tᵀ M T). One symmetric product and one rank-8 update of the lower
    // triangle (two passes over the matrix, blocked) instead of four rank-2 updates
    // (eight passes); the same 16m² flops.
    Eigen::Map<Eigen::MatrixXd> V(ws.refl.data(), m, 4);
    Eigen::Map<Eigen::MatrixXd> Y(ws.refl.data() + 4 * m, m, 4);
    for (Eigen::Index k = 0; k < 4; ++k) {
        V.col(k).head(k).setZero();
        V(k, k) = 1;
        V.col(k).tail(m - k - 1) = P.col(k).tail(m - k - 1);
    }
    Eigen::Matrix4d T = Eigen::Matrix4d::Zero();
    for (Eigen::Index k = 0; k < 4; ++k) {
        T(k, k) = tau[k];
        double vtv[4];  // T(0:k, k) = -τ_k T(0:k, 0:k) V(:, 0:k)ᵀ v_k
        for (Eigen::Index j = 0; j < k; ++j) vtv[j] = V.col(j).tail(m - k).dot(V.col(k).tail(m - k));
        for (Eigen::Index i = 0; i < k; ++i) {
            double t = 0;
            for (Eigen::Index j = i; j < k; ++j) t += T(i, j) * vtv[j];
            T(i, k) = -tau[k] * t;
        }
    }
    Y.noalias() = B.selfadjointView<Eigen::Lower>() * V;
    const Eigen::Matrix4d M = V.transpose() * Y;
    const Eigen::Matrix4d TMT = T.transpose() * M * T;
    // W (in Y's place, after V: X = [V W]), Z = [W V]; the lower triangle of B -= X Zᵀ.
    Eigen::Map<Eigen::MatrixXd> Z(ws.refl.data() + 8 * m, m, 8);
    Z.leftCols(4).noalias() = Y * T;
    Z.leftCols(4).noalias() -= V * (0.5 * TMT);
    Y = Z.leftCols(4);
    Z.rightCols(4) = V;
    Eigen::Map<Eigen::MatrixXd> X(ws.refl.data(), m, 8);  // V then W, already in place
    B.triangularView<Eigen::Lower>() -= X * Z.transpose();
    // Qᵀv.
    auto qv = ws.vec.head(m);
    for (Eigen::Index i = 0; i < m; ++i) qv[i] = v[static_cast<std::size_t>(i)];
    for (Eigen::Index k = 0; k < 4; ++k) rbf_apply_reflector(P, k, tau[k], qv);

    // (Q₂ᵀAQ₂ + λI) z = Q₂ᵀv by a Cholesky factorisation in place.
    auto B22 = B.bottomRightCorner(n, n);
    if (jitter) B22.diagonal().array() += 1e-10 * B22.diagonal().cwiseAbs().maxCoeff() + 1e-300;
    // ‖B₂₂‖₁ for the condition estimate, from the lower triangle column by column
    // (contiguous reads; Eigen's LLT reads a row of it per column).
    double l1 = 0;
    if (!jitter) {
        auto cs = ws.d.head(n);
        cs.setZero();
        for (Eigen::Index j = 0; j < n; ++j) {
            const auto col = B22.col(j).tail(n - j).array().abs();
            cs[j] += col.sum();
            cs.segment(j + 1, n - j - 1) += col.tail(n - j - 1);
        }
        l1 = cs.maxCoeff();
    }
    Eigen::Ref<Eigen::MatrixXd> L(B22);
    if (Eigen::internal::llt_inplace<double, Eigen::Lower>::blocked(L) != -1) return false;
    auto solve = [&L](auto x) {
        L.triangularView<Eigen::Lower>().solveInPlace(x);
        L.triangularView<Eigen::Lower>().adjoint().solveInPlace(x);
    };
    if (!jitter) {
        // Reciprocal condition estimate (1/‖B₂₂‖₁)/‖B₂₂⁻¹‖₁, the inverse's norm by Hager's
        // estimate as Eigen's rcond() but one ascent step (3 solves against its 4 to 10):
        // the lower bound of x = B₂₂⁻¹ 1/n, then of the column B₂₂⁻¹e_j that the sign
        // vector's gradient points to.
        Eigen::Map<Eigen::VectorXd> e(ws.refl.data(), n);
        e.setConstant(1.0 / static_cast<double>(n));
        solve(e);
        double inv1 = e.lpNorm<1>();
        for (Eigen::Index i = 0; i < n; ++i) e[i] = e[i] >= 0 ? 1.0 : -1.0;
        solve(e);
        Eigen::Index j = 0;
        e.cwiseAbs().maxCoeff(&j);
        e.setZero();
        e[j] = 1;
        solve(e);
        inv1 = std::max(inv1, e.lpNorm<1>());
        if (!(l1 > 0) || !((1 / l1) / inv1 > 1e-13)) return false;
    }
    auto z = qv.tail(n);
    solve(z);
    // R a = Q₁ᵀ(v - A w) = (Qᵀv)₁ - B₁₂ z, B₁₂ = B₂₁ᵀ (the lower triangle's first 4 columns).
    Eigen::Vector4d rhs1 = qv.head(4) - B.bottomLeftCorner(n, 4).transpose() * z;
    const Eigen::Vector4d coef = P.topRows(4).triangularView<Eigen::Upper>().solve(rhs1);
    // w = Q [0; z].
    qv.head(4).setZero();
    for (Eigen::Index k = 3; k >= 0; --k) rbf_apply_reflector(P, k, tau[k], qv);
    if (!qv.allFinite() || !coef.allFinite()) return false;
    w.assign(qv.data(), qv.data() + m);
    a = coef;
    return true;
}


/// See rbf_solve.hpp.
KINTSUGI_STAGE RBFSolveInfo rbf_solve_cell(const std::vector<Vec3>& u, const std::vector<Scalar>& v, Scalar lambda,
                                           std::vector<Scalar>& w, Eigen::Vector4d& a) {
    using Mat = Eigen::MatrixXd;
    using VecX = Eigen::VectorXd;
    const auto m = static_cast<Eigen::Index>(u.size());
    RBFSolveInfo info;
    thread_local RBFSolveWorkspace ws;
    a.setZero();
    if (m >= 5) {
        if (rbf_null_space_solve(u, v, lambda, false, ws, w, a)) return info;
        info.ill_conditioned = true;
        if (rbf_null_space_solve(u, v, lambda, true, ws, w, a)) return info;
    }
    // Coplanar or too few centres: the least-squares, minimum-norm solution.
    info.ill_conditioned = true;
    w.assign(static_cast<std::size_t>(m), 0);
    a.setZero();
    Mat S = Mat::Zero(m + 4, m + 4);
    VecX b = VecX::Zero(m + 4);
    for (Eigen::Index i = 0; i < m; ++i) {
        const Vec3& pi = u[static_cast<std::size_t>(i)];
        S(i, i) = lambda;
        for (Eigen::Index j = 0; j < i; ++j) {
            const Scalar r = (pi - u[static_cast<std::size_t>(j)]).norm();
            S(i, j) = S(j, i) = r * r * r;
        }
        S(i, m) = S(m, i) = 1;
        for (int k = 0; k < 3; ++k) S(i, m + 1 + k) = S(m + 1 + k, i) = pi[k];
        b[i] = v[static_cast<std::size_t>(i)];
    }
    const VecX x = S.completeOrthogonalDecomposition().solve(b);
    if (x.allFinite()) {
        for (Eigen::Index i = 0; i < m; ++i) w[static_cast<std::size_t>(i)] = x[i];
        a = x.tail(4);
    }  // else unreachable for finite input; w and a stay 0, the field finite
    return info;
}

}  // namespace kintsugi::detail
