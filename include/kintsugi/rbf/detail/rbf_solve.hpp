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

/// Scratch memory of the per-cell solves, one per thread: grown to the largest cell seen
/// and never shrunk, so that a fit of 100K cells does not allocate (and, for cells above
/// the allocator's mmap threshold, page-fault) a fresh matrix per cell. Eigen's
/// allocator aligns the buffers alike in every thread, so the arithmetic (and its
/// rounding) does not depend on which thread solves a cell.
struct RBFSolveWorkspace {
    Eigen::MatrixXd sym;  ///< m x m: A, then QᵀAQ in its lower triangle, then B₂₂'s Cholesky factor
    Eigen::MatrixXd qr;   ///< m x 4: P, then its Householder QR (reflectors below, R above)
    Eigen::VectorXd vec;  ///< m: Qᵀv, then [Qᵀv head; z]
    Eigen::VectorXd tmp;  ///< m: one reflector, padded with zeros
    Eigen::VectorXd tmp2; ///< m: A times that reflector
    Eigen::ArrayXd x, y, z, d;  ///< m: the centres' coordinates, one column of distances

    void reserve(Eigen::Index m) {
        if (sym.size() < m * m) sym.resize(m * m, 1);
        if (qr.size() < m * 4) qr.resize(m * 4, 1);
        for (Eigen::VectorXd* b : {&vec, &tmp, &tmp2})
            if (b->size() < m) b->resize(m);
        for (Eigen::ArrayXd* b : {&x, &y, &z, &d})
            if (b->size() < m) b->resize(m);
    }
};

/// Applies the k-th reflector of the QR in `qr` (H_k = I - τ_k h hᵀ, h = [0…0 1 essential])
/// to the vector x.
inline void rbf_apply_reflector(const Eigen::Ref<const Eigen::MatrixXd>& qr, Eigen::Index k, double tau,
                                Eigen::Ref<Eigen::VectorXd> x) {
    const Eigen::Index m = x.size();
    const double s = tau * (x[k] + qr.col(k).tail(m - k - 1).dot(x.tail(m - k - 1)));
    x[k] -= s;
    x.tail(m - k - 1) -= s * qr.col(k).tail(m - k - 1);
}

/// The null-space solve (see rbf_solve_cell) with the jitter on B₂₂'s diagonal or
/// without; false when P is rank-deficient, the Cholesky fails, its reciprocal
/// condition estimate is below 1e-13 (without jitter) or the result is not finite.
inline bool rbf_null_space_solve(const std::vector<Vec3>& u, const std::vector<Scalar>& v, Scalar lambda,
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
    // QᵀAQ = H₃H₂H₁H₀ A H₀H₁H₂H₃, each two-sided reflection as a symmetric rank-2 update
    // of the lower triangle (H A H = A - h qᵀ - q hᵀ, p = τAh, q = p - (τ/2)(hᵀp)h):
    // 4m² flops per reflector against 8m² for applying it on each side of the full matrix.
    auto& h = ws.tmp;
    auto& p = ws.tmp2;
    for (Eigen::Index k = 0; k < 4; ++k) {
        auto hm = h.head(m);
        hm.head(k).setZero();
        hm[k] = 1;
        hm.tail(m - k - 1) = P.col(k).tail(m - k - 1);
        auto pm = p.head(m);
        pm.noalias() = tau[k] * (B.selfadjointView<Eigen::Lower>() * hm);
        const double K = 0.5 * tau[k] * hm.dot(pm);
        pm -= K * hm;
        B.selfadjointView<Eigen::Lower>().rankUpdate(hm, pm, -1.0);
    }
    // Qᵀv.
    auto qv = ws.vec.head(m);
    for (Eigen::Index i = 0; i < m; ++i) qv[i] = v[static_cast<std::size_t>(i)];
    for (Eigen::Index k = 0; k < 4; ++k) rbf_apply_reflector(P, k, tau[k], qv);

    // (Q₂ᵀAQ₂ + λI) z = Q₂ᵀv by a Cholesky factorisation in place.
    auto B22 = B.bottomRightCorner(n, n);
    if (jitter) B22.diagonal().array() += 1e-10 * B22.diagonal().cwiseAbs().maxCoeff() + 1e-300;
    Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(B22);
    if (llt.info() != Eigen::Success) return false;
    if (!jitter && !(llt.rcond() > 1e-13)) return false;
    auto z = qv.tail(n);
    llt.solveInPlace(z);
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
inline RBFSolveInfo rbf_solve_cell(const std::vector<Vec3>& u, const std::vector<Scalar>& v, Scalar lambda,
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
