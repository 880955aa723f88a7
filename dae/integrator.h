// What every integrator offers: a state (q, v, a, lambda) at the current time,
// advanced to a requested time, with counters and the reason it stopped.
#pragma once

#include <cstddef>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "dae/mechanical_system.h"

namespace mbdae::dae {

struct State {
  double t = 0;
  std::vector<double> q, v, a, lambda;  // nq, nq, nq, nc

  void Resize(int nq, int nc) {
    q.assign(nq, 0.0);
    v.assign(nq, 0.0);
    a.assign(nq, 0.0);
    lambda.assign(nc, 0.0);
  }
};

// Counters and how the last call ended. Counters accumulate from Initialize().
// The linear solver of an implicit integrator's Newton matrix (HHT, IDA): KLU's sparse
// LU, or the block elimination along the tree of bodies (dae/block_tree_lu.h), which
// uses KLU where the system is no tree (docs/hht.md, "Linear solver").
enum class LinearSolverKind { kKlu, kTree };

struct Summary {
  enum class Status { kNotStarted, kRunning, kDone, kFailed };
  Status status = Status::kNotStarted;
  std::string message;       // why it failed, empty on success
  double t_reached = 0;      // time of the last state reached
  long steps_accepted = 0;
  long steps_rejected = 0;   // error test failures and Newton failures
  long newton_iterations = 0;
  long jacobian_evaluations = 0;
  long factorizations = 0;   // numeric (re)factorisations
  long residual_evaluations = 0;
  long newton_noise_stops = 0;  // HHT: Newton iterations accepted at the round-off floor
  // HHT and IDA: the linear solver of the Newton matrix ("klu", "tree", or "klu (no tree:
  // REASON)" when the tree was asked for; "tree" also when some factorisations fell back
  // to KLU), and how many did.
  std::string linear_solver;
  long klu_fallbacks = 0;
  // HHT: the cost of a fresh Newton matrix its refresh rule used at the end of the run
  // (HhtOptions::jacobian_cost resolved; 0: the rate and age rules alone); -1 elsewhere.
  double jacobian_cost = -1;
  // HHT: the predictor of its Newton iteration ("constant" or "linear",
  // HhtOptions::predictor resolved); empty elsewhere.
  std::string predictor;
  // HHT: the Newton matrix's rotation columns ("first-order" or "exact",
  // HhtOptions::rotation_jacobian resolved; "first-order" for the classical scheme and
  // systems without Euler parameters); empty elsewhere.
  std::string rotation_jacobian;
  double h_last = 0;         // last step size used

  std::string BriefReport() const;
};

// Extra quantities integrated along a run, e.g. the integral parts of objectives:
// size integrands g(t, q, v, a, lambda) (lambda of the system's constraint equations),
// each integrated from the initial time by the integrator's own rule (HHT: the
// trapezoidal rule over its accepted steps; IDA: quadrature variables of IDAS, in its
// error test). The integrand returns 0 on success, nonzero to fail the run.
struct Quadrature {
  int size = 0;
  std::function<int(double t, const double* q, const double* v, const double* a,
                    const double* lambda, double* g)>
      integrand;
};

// Called after Initialize with (x0, 0) and after every accepted step with the new state
// and the step size that produced it (state.t - h is the previous step's time up to
// rounding), for callers that replay the steps (sensitivities/).
using StepObserver = std::function<void(const State& state, double h)>;

// An integrator's whole state between two steps, for checkpointing (sensitivities/):
// the State plus what the scheme carries from one step to the next (`history`, in a
// layout the integrator documents; HHT: dae/hht.h). Quadrature integrals are not part
// of it.
struct IntegratorSnapshot {
  State state;
  std::vector<double> history;
  // Bytes of the numbers held: 8 (1 + 3 nq + nc + history.size()).
  size_t bytes() const {
    return sizeof(double) * (1 + state.q.size() + state.v.size() + state.a.size() +
                             state.lambda.size() + history.size());
  }
};

class Integrator {
 public:
  virtual ~Integrator() = default;

  // Sets the quadrature before Initialize (replacing any earlier one); quadrature()
  // then holds the integrals from the initial time to state().t. Throws
  // std::logic_error if the integrator has no quadrature support.
  virtual void SetQuadrature(Quadrature quadrature);
  virtual const std::vector<double>& quadrature() const { return no_quadrature_; }
  // Sets a step observer before Initialize (an empty function removes it). Throws
  // std::logic_error if the integrator cannot report its steps.
  virtual void SetStepObserver(StepObserver observer);

  // Writes the current state and history into *snapshot (allowed any time after
  // construction: the sizes are final; before Initialize the values are zeros). No
  // allocation when *snapshot already has the sizes. Throws std::logic_error if the
  // integrator cannot.
  virtual void SaveSnapshot(IntegratorSnapshot* snapshot) const {
    (void)snapshot;
    throw std::logic_error(name() + " cannot save its state (SaveSnapshot)");
  }
  // Continues from a snapshot taken by an integrator of the same kind on the same system
  // with the same options, as Initialize does from a state: counters reset, the
  // quadrature restarts from zero at the snapshot's time, the observer is not called.
  // The steps that follow are those the saved integrator would have taken, to the
  // Newton tolerance (the Newton matrix is evaluated afresh). Throws
  // std::invalid_argument for a snapshot of another size or kind, std::logic_error if
  // the integrator cannot.
  virtual void RestoreSnapshot(const IntegratorSnapshot& snapshot) {
    (void)snapshot;
    throw std::logic_error(name() + " cannot restore a state (RestoreSnapshot)");
  }

  // Starts at x0, which must be consistent (C = 0, C_q v + C_t = 0, and a, lambda the
  // solution of the acceleration-level system). Resets the counters.
  virtual void Initialize(const State& x0) = 0;

  // Integrates from the current time to exactly t_target (> current time). On success
  // returns true and state() is at t_target. On failure returns false, summary() says
  // why, and state() is the last state reached.
  virtual bool AdvanceTo(double t_target) = 0;

  virtual const State& state() const = 0;
  virtual const Summary& summary() const = 0;
  virtual std::string name() const = 0;

 private:
  std::vector<double> no_quadrature_;
};

}  // namespace mbdae::dae
