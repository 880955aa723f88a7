// What every integrator offers: a state (q, v, a, lambda) at the current time,
// advanced to a requested time, with counters and the reason it stopped.
#pragma once

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
  double h_last = 0;         // last step size used

  std::string BriefReport() const;
};

class Integrator {
 public:
  virtual ~Integrator() = default;

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
};

}  // namespace mbdae::dae
