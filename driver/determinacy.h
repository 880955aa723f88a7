// Determinacy of the accelerations: is [M C_q^T; C_q 0] of a multibody system regular,
// and if not, which bodies' coordinates lie in its null space.
//
// With M symmetric positive semi-definite (masses >= 0, inertias positive
// semi-definite), K = [M C_q^T; C_q 0] K [z; mu] = 0 gives z^T M z = -(C_q z)^T mu = 0,
// so M z = 0 and C_q^T mu = 0: the null space of K is
//     { (z, mu) : z in ker M and ker C_q,  mu in ker C_q^T }.
// K is singular exactly when C_q has dependent rows or ker M and ker C_q meet. A body
// with a positive mass and a positive definite inertia ("regular") contributes no z: M z
// = 0 leaves only a change of its Euler parameters along themselves, which its
// normalisation equation forbids. So only the coordinates of the other bodies (zero mass
// or a singular inertia) need a numeric test, on the stacked matrix [M; C_q] restricted
// to their columns, one connected group of them at a time (bodies sharing a constraint
// equation). The cost is linear in the number of bodies when the irregular groups are
// small; a chain of N regular bodies needs no factorisation at all.
#pragma once

#include <string>
#include <vector>

#include "dae/integrator.h"
#include "dae/mechanical_system.h"
#include "mbs/model.h"

namespace mbdae::driver {

struct DeterminacyOptions {
  // Relative rank threshold (FullPivLU on the equilibrated matrix).
  double tolerance = 1e-10;
  // A body is regular when its mass is > 0 and the smallest principal moment of its
  // inertia exceeds regular_inertia_ratio times the largest.
  double regular_inertia_ratio = 1e-6;
  // Groups of irregular bodies with more coordinates than this are tested by a sparse
  // rank-revealing QR that decides singularity only; it then names the group's bodies
  // with zero mass or a singular inertia.
  int max_dense_columns = 1400;
  // Where C_q's rows may be dependent (the full system before redundant equations are
  // set aside), the rank of C_q is checked too (SPQR, normalisations first); false for
  // a system of independent equations (Assembly::kept_system).
  bool check_constraint_rank = true;
};

struct DeterminacyResult {
  bool singular = false;
  std::vector<std::string> bodies;  // in model order
  int irregular_bodies = 0;         // bodies given to the numeric test
  int largest_group = 0;            // coordinates of the largest group tested
};

// Evaluates M and C_q of `system` (coordinates 7 per body of `model`, in body order) at
// x. Throws std::runtime_error when the system cannot be evaluated there.
DeterminacyResult AnalyseDeterminacy(const mbs::Model& model, dae::MechanicalSystem& system,
                                     const dae::State& x, const DeterminacyOptions& options = {});

// The dense reference: FullPivLU of the whole equilibrated K (O((nq + nc)^3)); bodies
// from its kernel. Kept for the tests that compare AnalyseDeterminacy with it.
DeterminacyResult DenseDeterminacy(const mbs::Model& model, dae::MechanicalSystem& system,
                                   const dae::State& x, double tolerance);

}  // namespace mbdae::driver
