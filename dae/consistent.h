// Consistent initial values of a mechanical system and its redundant constraints.
//
// Positions are projected with least change onto C(q, t) = 0, then velocities onto
// C_q v + C_t = 0, then accelerations and multipliers solve
//   [M  C_q^T; C_q  0] [a; lambda] = [Q; gamma].
// Redundant constraint equations are found by a rank-revealing sparse QR (SPQR) of
// C_q^T at the projected positions.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "dae/integrator.h"
#include "dae/mechanical_system.h"

namespace mbdae::dae {

struct ConsistencyOptions {
  double position_tolerance = 1e-12;  // on max |C|
  int max_iterations = 50;
  // Relative threshold of the rank decision: an R diagonal entry below
  // rank_tolerance * max |R_ii| marks a dependent constraint.
  double rank_tolerance = 1e-9;
  // The order in which equations are eliminated in the rank decision (a permutation of
  // 0..nc-1; empty: the natural order). Of a group of dependent equations the ones that
  // come LATER in this order are flagged redundant, so list first the equations whose
  // multipliers must be kept (e.g. normalisations of Euler parameters).
  std::vector<int> elimination_order;
  bool IsValid(std::string* error) const;
};

struct ConsistencyReport {
  bool ok = false;
  std::string message;                 // why it failed
  std::vector<int> redundant;          // indices of dependent constraint equations
  std::vector<int> violated;           // equations with |C| > tolerance when it failed
  double max_position_change = 0;      // max |q - q0|
  double max_velocity_change = 0;      // max |v - v0|
  double initial_position_violation = 0;  // max |C(q0)|
  double initial_velocity_violation = 0;  // max |C_q v0 + C_t|
  int iterations = 0;
};

// Finds the constraint equations that are linearly dependent on others at (t, q).
std::vector<int> FindRedundantConstraints(MechanicalSystem& system, double t, const double* q,
                                          double rank_tolerance,
                                          const std::vector<int>& elimination_order = {});

// A view of `base` with only the constraint equations listed in `kept` (sorted).
std::unique_ptr<MechanicalSystem> KeepConstraints(MechanicalSystem& base, std::vector<int> kept);

// The acceleration-level equations of `system` at (t, q, v):
//   [M  C_q^T; C_q  0] [a; lambda] = [Q; gamma],
// with gamma the system's acc_rhs (C_q a = gamma is the second time derivative of
// C(q, t) = 0). The pattern is analysed once (KLU) at construction; each Solve evaluates
// M, C_q, Q and gamma and factorises (a refactorisation with the pivots of the previous
// call when KLU can). The system's constraints must be independent (a KeepConstraints
// view). Used for the consistent a and lambda of MakeConsistent, the output rows of the
// driver (a and lambda determined by (t, q, v) alone) and the perturbed start of HHT.
//
// With tree_elimination, the matrix is factorised by block elimination along the tree of
// bodies and joints (dae/tree_kkt.h, linear in the number of bodies) when the patterns
// form one; KLU factorises it instead (a) when they do not (closed loops, bodies of more
// than kMaxTreeNode unknowns, e.g. joint coordinates: tree_refusal() says why; decided
// once at construction), (b) for good when the first factorisation fails (a loop closed
// through the ground: two bodies tied to the ground and to each other are a tree in the
// patterns, but eliminating them meets a zero pivot) and (c) at a state where the
// elimination meets a zero pivot or its pivot ratio min |U_ii| / max |U_ii| is below
// 1e-14 or below 1e-6 times that of its first factorisation (a near-singular position).
// klu_fallbacks() counts (b) and (c).
class AccelerationSolver {
 public:
  static constexpr int kMaxTreeNode = 48;
  // growth_check_interval: see KluSolver (1: the pivot growth checked at every solve);
  // tree_elimination: above.
  explicit AccelerationSolver(MechanicalSystem& system, int growth_check_interval = 1,
                              bool tree_elimination = false);
  ~AccelerationSolver();
  AccelerationSolver(const AccelerationSolver&) = delete;
  AccelerationSolver& operator=(const AccelerationSolver&) = delete;

  // a (nq) and lambda (nc) at (t, q, v). Returns 0; the system's nonzero Evaluate code
  // when it cannot be evaluated; or 1 when the matrix is numerically singular (KLU). On a
  // nonzero return a and lambda are untouched and last_error() says why.
  int Solve(double t, const double* q, const double* v, double* a, double* lambda);
  // After a successful Solve: y = C_q x (x: nq, y: nc) with the C_q of that Solve, and
  // the solution of the same matrix for another right side (nq + nc, in place).
  void MultiplyConstraintJacobian(const double* x, double* y) const;
  void SolveAgain(double* rhs) const;
  const std::string& last_error() const;
  // Whether the last successful Solve used the tree elimination (else KLU).
  bool used_tree() const;
  // Empty when the tree elimination is available; else why not (or "not requested").
  const std::string& tree_refusal() const;
  // Solves that fell back from the tree elimination to KLU (cases (b) and (c) above).
  long klu_fallbacks() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Makes x consistent in place (x.t, x.q, x.v used as the initial guess; a and lambda
// computed). Positions and velocities are corrected with minimum-norm steps (SPQR),
// which stay valid when constraints are redundant; the redundant equations are then
// found at the projected positions and listed in the report, and a, lambda solve the
// acceleration-level system of the independent equations only (lambda of a redundant
// equation is 0). Callers that integrate then use KeepConstraints(system, kept).
ConsistencyReport MakeConsistent(MechanicalSystem& system, State& x,
                                 const ConsistencyOptions& options = {});

}  // namespace mbdae::dae
