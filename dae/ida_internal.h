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

#include <algorithm>
#include <functional>
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

  // The rounding level of every row of F at the last Residual call, for an iteration
  // matrix of this cj (size() values into level): machine epsilon times the magnitude of
  // the row's terms, F1 max(|q'|, |v|, |C_q|^T |mu|, cj |q|), F2 |Q| + |M| |v'| +
  // |C_q|^T |lambda| or cj |M| |v| if larger, F3 |C_q| |q| (constraints are of the size
  // of the positions), F4 |C_q| |v| + |C_t|; cj |q| and cj |M| |v| are what one unit in
  // the last place of q and v changes through q' and v' = cj (y - y_predicted) + ...
  void RoundingLevel(double cj, double* level) const;

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
  std::vector<double> fixed_, scaled_;  // RoundingLevel's magnitudes
};

// Two rules for IDA's Newton iteration on the GGL form near singular positions.
//
// Near a singular position (C_q losing rank: all links of a parallelogram horizontal)
// the iteration matrix J = dF/dy + cj dF/dy' is nearly singular: with s the distance to
// the singular configuration, the corrections of the velocities along the lost
// direction are about (residual) / s^2. Once the iterate solves F = 0 up to its rounding
// error, these corrections are that rounding amplified (1e-15 / s^2, above a tolerance
// of 1e-10 for s < 3e-3): the Newton iteration cannot satisfy IDA's convergence test,
// and the amplified rounding in the solution fails its error test; IDA cuts the step
// until the run fails.
//  1. ZeroIfRounding: when every row of the right side b = -F is within `factor` times
//     its rounding level (GglResidual::RoundingLevel), the iterate solves F = 0 as well
//     as the arithmetic can tell and the correction is zero (a converged iteration). In
//     a regular configuration this only ends an iteration that has converged anyway.
//  2. resolution(): |J^-1 b| for right sides b at `factor` times the rounding level of
//     each row with pseudo-random signs, in two of the four solves also with
//     pseudo-random sizes in [0.5, 1) (the largest of the four, component by component;
//     with equal sizes only, a mode made of a few rows of equal level, such as one loop
//     of a chain of loops, can cancel exactly and come out at zero), computed after
//     every factorisation (Update): the smallest change of y
//     the arithmetic can tell from zero. Far from singular positions it is at the
//     rounding level of y; near one it grows like 1/s^2 in the velocities. IDA's error
//     weights add it to rtol |y| + atol.
class GglRounding {
 public:
  GglRounding(const GglResidual& ggl, double factor);

  // After a factorisation of the iteration matrix of this cj: the resolution, with
  // solve(x) solving J x = b in place (size ggl.size()), at the rounding level of ggl's
  // last residual.
  void Update(double cj, const std::function<void(double*)>& solve);
  // Rule 1 for b (size ggl.size()) at the rounding level of ggl's last residual and the
  // cj of the last Update: returns true, with b set to zero, when it applies.
  bool ZeroIfRounding(double* b);

  const std::vector<double>& resolution() const { return resolution_; }
  void Clear() { std::fill(resolution_.begin(), resolution_.end(), 0.0); }
  long stops() const { return stops_; }  // rule 1 applied

 private:
  const GglResidual& ggl_;
  double factor_ = 0;
  double cj_ = 0;
  long stops_ = 0;
  std::vector<double> resolution_, work_, level_;
};

}  // namespace mbdae::dae::internal
