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

// Makes x consistent in place (x.t, x.q, x.v used as the initial guess; a and lambda
// computed). Positions and velocities are corrected with minimum-norm steps (SPQR),
// which stay valid when constraints are redundant; the redundant equations are then
// found at the projected positions and listed in the report, and a, lambda solve the
// acceleration-level system of the independent equations only (lambda of a redundant
// equation is 0). Callers that integrate then use KeepConstraints(system, kept).
ConsistencyReport MakeConsistent(MechanicalSystem& system, State& x,
                                 const ConsistencyOptions& options = {});

}  // namespace mbdae::dae
