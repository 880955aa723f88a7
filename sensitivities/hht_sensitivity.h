// Exact gradients of the discrete objective of an HHT run (dae/hht.h, docs/hht.md):
// the discrete adjoint (a backward sweep over the stored steps with the transposed
// Newton matrices) and direct differentiation (a forward sweep), both of the very step
// sequence the run took (fixed or adaptive step: the accepted steps frozen), for the
// classical and the modified scheme and both residual forms. Equations:
// docs/sensitivities.md.
//
// The objective's integral is the HHT quadrature: the trapezoidal rule over the
// accepted steps (dae::Quadrature), the terminal part is taken at the last state.
#pragma once

#include <string>
#include <vector>

#include "dae/hht.h"
#include "dae/integrator.h"
#include "dae/mechanical_system.h"
#include "sensitivities/hht_checkpoint.h"
#include "sensitivities/objective.h"

namespace mbdae::sens {

// Derivatives of the consistent initial state with respect to the system's parameters:
// dense, column-major (column k: d/dp_k), nq x np for q, v, a and nc x np for lambda.
struct InitialStateDerivatives {
  int np = 0;
  std::vector<double> dq, dv, da, dlambda;
};

// The record of an HHT run that the sweeps replay: the time and step size of every
// accepted step (h(0) = 0) and either every state (q, v, a, lambda) or, under a memory
// budget, checkpoints from which the sweeps recompute the others (docs/
// sensitivities.md, "Memory and checkpoints").
//
//   HhtTrajectory trajectory(nq, nc);
//   trajectory.set_memory_budget(512 << 20);   // optional; 0 (default): every state
//   trajectory.Attach(*integrator);            // before integrator->Initialize
//
// Under a budget B the record stores every state while they fit (and, every s1-th step,
// the integrator's history: s1 the smallest power of two with checkpoint bytes / s1 <=
// state bytes / 2). When the next record would exceed B it keeps only the states at
// multiples of s1 with their histories: checkpoints, every s steps (s = s1); from then
// on it takes a checkpoint every s steps and, when B is full again, drops every other
// one and doubles s. It never holds more than B bytes (memory()), unless B is too
// small even for the times and step sizes with one checkpoint (exceeded_budget()).
class HhtTrajectory {
 public:
  HhtTrajectory(int nq, int nc);

  // Bytes the record may hold; 0 (the default): every state. Call before recording.
  // Throws std::logic_error once something is recorded, std::invalid_argument for a
  // budget below minimum_budget() (nor 0).
  void set_memory_budget(size_t bytes);
  size_t memory_budget() const { return budget_; }
  // The smallest budget accepted: 16 checkpoints of the largest HHT history nq
  // coordinates allow (nq / 4 Euler-parameter groups): 16 x 8 (3 nq + nc +
  // dae::HhtHistory::Size(nq, nc, nq / 4)) bytes.
  size_t minimum_budget() const;

  // Records the integrator's run (sets its step observer; call before Initialize; starts
  // a new record). The integrator must outlive the recording and support SaveSnapshot
  // (HHT). Throws std::logic_error when it cannot save its state.
  void Attach(dae::Integrator& integrator);
  // A step observer that stores every state, for recording without a budget (throws
  // std::logic_error if a budget is set: checkpoints need Attach).
  dae::StepObserver Recorder();
  // Forgets the run (keeps the budget and the attached integrator).
  void Clear();

  int nq() const { return nq_; }
  int nc() const { return nc_; }
  int size() const { return static_cast<int>(times_.size()); }
  double t(int n) const { return times_[n][0]; }
  double h(int n) const { return times_[n][1]; }
  // The stored state n, or nullptr when it is not stored (checkpointed record, n not a
  // checkpoint step).
  const double* q(int n) const;
  const double* v(int n) const;
  const double* a(int n) const;
  const double* lambda(int n) const;

  // true while every state is stored (always without a budget).
  bool stores_every_step() const { return dense_; }
  // Checkpoints (0 while every state is stored): checkpoint i is step
  // i * checkpoint_interval(), with the integrator's history.
  int num_checkpoints() const { return dense_ ? 0 : static_cast<int>(states_.size()); }
  int checkpoint_interval() const { return dense_ ? 1 : interval_; }
  // The snapshot to restore checkpoint i from (dae::Integrator::RestoreSnapshot).
  void GetCheckpoint(int i, dae::IntegratorSnapshot* snapshot) const;
  // How often the checkpoints were thinned (every other one dropped).
  int thinning_rounds() const { return thinning_rounds_; }

  // Bytes held now (the blocks of the times, states and histories), and at most.
  size_t memory() const;
  size_t peak_memory() const { return peak_; }
  bool exceeded_budget() const { return exceeded_; }
  // Bytes of one stored state (q, v, a, lambda) and of one checkpoint (that state and
  // the integrator's history; 0 before Attach); 16 more bytes a step for t and h.
  size_t state_bytes() const { return sizeof(double) * (3 * size_t(nq_) + nc_); }
  size_t checkpoint_bytes() const {
    return history_ > 0 ? state_bytes() + sizeof(double) * history_ : 0;
  }

 private:
  void Record(const dae::State& x, double h);
  void Reset();
  bool Shrink();

  int nq_, nc_;
  size_t budget_ = 0;
  dae::Integrator* integrator_ = nullptr;
  int history_ = 0;  // doubles of the integrator's history (0 before Attach)
  dae::IntegratorSnapshot scratch_;
  RecordStore times_;   // (t, h) of every step
  RecordStore states_;  // every state (dense_) or the checkpoints' states
  RecordStore hist_;    // histories of steps 0, interval_, 2 interval_, ...
  bool dense_ = true;
  int interval_ = 1;
  int thinning_rounds_ = 0;
  bool exceeded_ = false;
  size_t peak_ = 0;
};

struct HhtSensitivityResult {
  std::vector<double> values;    // G_i of the discrete run (n objectives)
  std::vector<double> gradient;  // dG_i/dp_k at [i * np + k]
  long linear_solves = 0;        // transposed (adjoint) or plain (forward) solves
  long factorizations = 0;
  // Checkpointed trajectories: steps recomputed from checkpoints (at most one forward
  // run; 0 when every state is stored), and the largest relative difference between a
  // recomputed state and the stored checkpoint it ran into (q and v; HhtStateWindow).
  long recomputed_steps = 0;
  double recompute_deviation = 0;
  // The most bytes the trajectory took: its peak while recording, or its memory plus the
  // states of the recomputed segment and the replayed step list during the sweep.
  size_t peak_trajectory_bytes = 0;
};

// The discrete adjoint. options: those of the run (a checkpointed trajectory is
// recomputed with them). Returns false with *error set when an evaluation fails, a
// transposed step system cannot be solved, or a segment cannot be recomputed.
bool HhtAdjointGradient(dae::MechanicalSystem& system, const dae::HhtOptions& options,
                        ObjectiveFunction& objective, const HhtTrajectory& trajectory,
                        const InitialStateDerivatives& dx0, HhtSensitivityResult* result,
                        std::string* error);

// Direct differentiation (forward sensitivities, np directions at once); the same
// numbers as the adjoint up to round-off. A checkpointed trajectory is recomputed
// segment by segment, as for the adjoint.
bool HhtForwardGradient(dae::MechanicalSystem& system, const dae::HhtOptions& options,
                        ObjectiveFunction& objective, const HhtTrajectory& trajectory,
                        const InitialStateDerivatives& dx0, HhtSensitivityResult* result,
                        std::string* error);

}  // namespace mbdae::sens
