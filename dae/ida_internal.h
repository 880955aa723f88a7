// The stabilised index-2 (Gear-Gupta-Leimkuhler) residual of a mechanical system and
// its sparse iteration matrix, as IDA sees them. Internal to dae/; exposed for tests.
//
// Unknowns y = (q, v, lambda, mu), sizes (nq, nq, nc, nc), and the residual
//   F1 = q' - v + C_q^T mu
//   F2 = M(q) v' + C_q^T lambda - Q(q, v, t)
//   F3 = C(q, t)
//   F4 = C_q v + C_t
// (C. W. Gear, B. Leimkuhler, G. K. Gupta, J. Comput. Appl. Math. 12-13 (1985) 77-90).
// At a solution mu = 0, so q' = v.
#pragma once

#include <string>
#include <vector>

#include "dae/mechanical_system.h"
#include "dae/sparse.h"

namespace mbdae::dae::internal {

// The name of an IDA(S) return flag ("IDA_CONV_FAIL"). IDAGetReturnFlagName returns a
// string it allocated; this copies and frees it.
std::string IdaFlagName(int flag);

class GglResidual {
 public:
  explicit GglResidual(MechanicalSystem& system);

  int size() const { return 2 * nq_ + 2 * nc_; }
  int nq() const { return nq_; }
  int nc() const { return nc_; }

  // F(t, y, y'); returns the system's Evaluate code (0, > 0 recoverable, < 0 fatal).
  int Residual(double t, const double* y, const double* yp, double* F);

  // dF/dy + cj dF/dy' in the pattern of jacobian_pattern() (values in pattern order).
  int Jacobian(double t, double cj, const double* y, const double* yp, double* values);

  const CscPattern& jacobian_pattern() const { return assembler_.pattern(); }

  // dF/dp at (t, y, y') for the system's num_parameters() parameters: dense,
  // column-major, size() x np (column k: dF/dp_k), for sensitivity analysis:
  //   dF1/dp = d(C_q^T mu)/dp,  dF2/dp = d(M a)/dp|a=v' + d(C_q^T lambda)/dp - dQ/dp,
  //   dF3/dp = dC/dp,           dF4/dp = d(C_q v + C_t)/dp.
  int ParameterJacobian(double t, const double* y, const double* yp, double* dense);
  MechanicalSystem& system() { return system_; }

 private:
  MechanicalSystem& system_;
  int nq_ = 0, nc_ = 0;
  BlockAssembler assembler_;
  // Block ids in the assembler.
  int b_cj_q_ = -1, b_minus_i_v_ = -1;
  int b_tdq_mu_ = -1, b_cqt_mu_ = -1;
  int b_madq_ = -1, b_tdq_lambda_ = -1, b_fdq_ = -1, b_fdv_ = -1, b_mass_ = -1, b_cqt_lambda_ = -1;
  int b_cq3_ = -1, b_veldq_ = -1, b_cq4_ = -1;
  // Workspace, sized once.
  std::vector<double> ones_;
  std::vector<double> force_, constraint_, constraint_dt_;
  std::vector<double> val_[kNumMatrices];
  std::vector<double> tdq_mu_;
  std::vector<double> pval_[kNumParameterMatrices], ptdp_mu_;
};

}  // namespace mbdae::dae::internal
