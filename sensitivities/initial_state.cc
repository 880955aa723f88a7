#include "sensitivities/initial_state.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <utility>

#include "dae/klu_solver.h"
#include "sensitivities/system_matrices.h"

namespace mbdae::sens {

namespace {

using dae::Matrix;
using dae::ParameterMatrix;

// [top C_q^T; C_q 0] with top = I (identity) or M, factorised with KLU.
class Kkt {
 public:
  Kkt(dae::MechanicalSystem& system, bool identity_top) : nq_(system.num_coordinates()) {
    const int nc = system.num_constraints();
    std::vector<std::pair<int, int>> diag;
    for (int i = 0; i < nq_ + nc; ++i) diag.push_back({i, i});
    b_diag_ = asmb_.AddEntries(diag);
    if (!identity_top) b_mass_ = asmb_.AddBlock(system.pattern(Matrix::kMass), 0, 0);
    b_cqt_ = asmb_.AddBlock(system.pattern(Matrix::kConstraintDq), 0, nq_, true);
    b_cq_ = asmb_.AddBlock(system.pattern(Matrix::kConstraintDq), nq_, 0);
    asmb_.Finalize(nq_ + nc, nq_ + nc);
    values_.assign(asmb_.pattern().nnz(), 0.0);
    ones_.assign(nq_ + nc, 0.0);
    std::fill(ones_.begin(), ones_.begin() + nq_, identity_top ? 1.0 : 0.0);
    klu_ = std::make_unique<dae::KluSolver>(asmb_.pattern());
  }
  bool Factor(const SystemMatrices& sm, std::string* error) {
    asmb_.SetZero(values_.data());
    asmb_.Accumulate(b_diag_, ones_.data(), 1.0, values_.data());
    if (b_mass_ >= 0) asmb_.Accumulate(b_mass_, sm.values(Matrix::kMass).data(), 1.0, values_.data());
    asmb_.Accumulate(b_cqt_, sm.values(Matrix::kConstraintDq).data(), 1.0, values_.data());
    asmb_.Accumulate(b_cq_, sm.values(Matrix::kConstraintDq).data(), 1.0, values_.data());
    return klu_->Factor(values_.data(), error);
  }
  void Solve(double* b) const { klu_->Solve(b); }

 private:
  int nq_;
  dae::BlockAssembler asmb_;
  int b_diag_ = -1, b_mass_ = -1, b_cqt_ = -1, b_cq_ = -1;
  std::vector<double> values_, ones_;
  std::unique_ptr<dae::KluSolver> klu_;
};

}  // namespace

bool ConsistentInitialStateDerivatives(dae::MechanicalSystem& system, const dae::State& x0,
                                       const std::vector<double>& v_raw,
                                       const std::vector<double>& dq_raw,
                                       const std::vector<double>& dv_raw,
                                       InitialStateDerivatives* out, std::string* error) {
  const int nq = system.num_coordinates(), nc = system.num_constraints();
  const int np = system.num_parameters();
  const size_t nqp = static_cast<size_t>(nq) * np;
  if (dq_raw.size() != nqp || dv_raw.size() != nqp || v_raw.size() != static_cast<size_t>(nq)) {
    *error = "initial state derivatives: the raw derivatives must be nq x np";
    return false;
  }
  out->np = np;
  out->dq.assign(nqp, 0.0);
  out->dv.assign(nqp, 0.0);
  out->da.assign(nqp, 0.0);
  out->dlambda.assign(static_cast<size_t>(nc) * np, 0.0);
  if (np == 0) return true;
  auto fail = [&](const std::string& why) {
    *error = "initial state derivatives: " + why;
    return false;
  };

  const double t = x0.t;
  const double* q = x0.q.data();
  const double* v = x0.v.data();
  const double* a = x0.a.data();
  const double* lam = x0.lambda.data();
  SystemMatrices sm(system), sm_nu(system), sm_a(system), sm_0(system);
  std::string err;
  SystemMatrices::Request all;
  all.All();
  if (sm.Evaluate(all, t, q, v, a, lam, &err) != 0) return fail(err);
  std::vector<double> zero(nq, 0.0);

  // 1. Positions.
  Kkt kkt_i(system, true);
  if (!kkt_i.Factor(sm, &err)) return fail("[I C_q^T; C_q 0]: " + err);
  std::vector<double> rhs(nq + nc);
  for (int k = 0; k < np; ++k) {
    std::fill(rhs.begin(), rhs.end(), 0.0);
    std::copy(&dq_raw[k * size_t(nq)], &dq_raw[k * size_t(nq)] + nq, rhs.begin());
    sm.AddColumn(ParameterMatrix::kConstraintDp, k, -1.0, rhs.data() + nq);
    kkt_i.Solve(rhs.data());
    std::copy(rhs.begin(), rhs.begin() + nq, &out->dq[k * size_t(nq)]);
  }

  // 2. Velocities: nu from v_raw - v = C_q^T nu, then the differentiated projection.
  std::fill(rhs.begin(), rhs.end(), 0.0);
  for (int i = 0; i < nq; ++i) rhs[i] = v_raw[i] - v[i];
  kkt_i.Solve(rhs.data());
  const std::vector<double> nu(rhs.begin() + nq, rhs.end());
  SystemMatrices::Request r_nu;
  r_nu.matrices[static_cast<int>(Matrix::kConstraintTDq)] = true;
  r_nu.parameters[static_cast<int>(ParameterMatrix::kConstraintTDp)] = true;
  if (sm_nu.Evaluate(r_nu, t, q, v, a, nu.data(), &err) != 0) return fail(err);
  for (int k = 0; k < np; ++k) {
    const double* dq = &out->dq[k * size_t(nq)];
    std::fill(rhs.begin(), rhs.end(), 0.0);
    std::copy(&dv_raw[k * size_t(nq)], &dv_raw[k * size_t(nq)] + nq, rhs.begin());
    sm_nu.Mul(Matrix::kConstraintTDq, -1.0, dq, rhs.data());
    sm_nu.AddColumn(ParameterMatrix::kConstraintTDp, k, -1.0, rhs.data());
    sm.Mul(Matrix::kConstraintVelDq, -1.0, dq, rhs.data() + nq);
    sm.AddColumn(ParameterMatrix::kConstraintVelDp, k, -1.0, rhs.data() + nq);
    kkt_i.Solve(rhs.data());
    std::copy(rhs.begin(), rhs.begin() + nq, &out->dv[k * size_t(nq)]);
  }

  // 3. Accelerations and multipliers. d(C_q a)/dq and d(C_q a)/dp come from the velocity
  // outputs evaluated with v := a (minus C_t's parameter derivative, from v := 0).
  SystemMatrices::Request r_a;
  r_a.matrices[static_cast<int>(Matrix::kConstraintVelDq)] = true;
  r_a.parameters[static_cast<int>(ParameterMatrix::kConstraintVelDp)] = true;
  if (sm_a.Evaluate(r_a, t, q, a, a, lam, &err) != 0) return fail(err);
  if (sm_0.Evaluate(r_a, t, q, zero.data(), a, lam, &err) != 0) return fail(err);
  Kkt kkt_m(system, false);
  if (!kkt_m.Factor(sm, &err)) return fail("[M C_q^T; C_q 0]: " + err);
  std::vector<double> qs(nq), gp(nc), gm(nc), dgamma(nc);
  SystemMatrices probe(system);
  SystemMatrices::Request r_g;
  r_g.acc_rhs = true;
  auto gamma_at = [&](const double* dq, double eps, std::vector<double>* g) {
    for (int i = 0; i < nq; ++i) qs[i] = q[i] + eps * dq[i];
    if (probe.Evaluate(r_g, t, qs.data(), v, a, lam, &err) != 0) return false;
    *g = probe.acc_rhs();
    return true;
  };
  for (int k = 0; k < np; ++k) {
    const double* dq = &out->dq[k * size_t(nq)];
    const double* dv = &out->dv[k * size_t(nq)];
    // d(gamma)/dq dq: Richardson-extrapolated central differences (steps eps, 2 eps).
    double dq_max = 0;
    for (int i = 0; i < nq; ++i) dq_max = std::max(dq_max, std::abs(dq[i]));
    std::fill(dgamma.begin(), dgamma.end(), 0.0);
    if (dq_max > 0) {
      const double eps = 1e-3 / dq_max;
      std::vector<double> g1p, g1m, g2p, g2m;
      if (!gamma_at(dq, eps, &g1p) || !gamma_at(dq, -eps, &g1m) || !gamma_at(dq, 2 * eps, &g2p) ||
          !gamma_at(dq, -2 * eps, &g2m))
        return fail(err);
      for (int j = 0; j < nc; ++j)
        dgamma[j] = (8 * (g1p[j] - g1m[j]) - (g2p[j] - g2m[j])) / (12 * eps);
    }
    std::fill(rhs.begin(), rhs.end(), 0.0);
    double* r1 = rhs.data();
    double* r2 = rhs.data() + nq;
    sm.Mul(Matrix::kMassTimesAccDq, -1.0, dq, r1);
    sm.Mul(Matrix::kConstraintTDq, -1.0, dq, r1);
    sm.Mul(Matrix::kForceDq, 1.0, dq, r1);
    sm.Mul(Matrix::kForceDv, 1.0, dv, r1);
    sm.AddColumn(ParameterMatrix::kMassTimesAccDp, k, -1.0, r1);
    sm.AddColumn(ParameterMatrix::kConstraintTDp, k, -1.0, r1);
    sm.AddColumn(ParameterMatrix::kForceDp, k, 1.0, r1);
    for (int j = 0; j < nc; ++j) r2[j] = dgamma[j];
    sm.Mul(Matrix::kConstraintVelDq, -2.0, dv, r2);
    sm.AddColumn(ParameterMatrix::kAccRhsDp, k, 1.0, r2);
    sm_a.Mul(Matrix::kConstraintVelDq, -1.0, dq, r2);
    sm_a.AddColumn(ParameterMatrix::kConstraintVelDp, k, -1.0, r2);
    sm_0.AddColumn(ParameterMatrix::kConstraintVelDp, k, 1.0, r2);
    kkt_m.Solve(rhs.data());
    std::copy(rhs.begin(), rhs.begin() + nq, &out->da[k * size_t(nq)]);
    std::copy(rhs.begin() + nq, rhs.end(), &out->dlambda[k * size_t(nc)]);
  }
  return true;
}

}  // namespace mbdae::sens
