#include "dae/kinematic.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include "dae/consistent.h"
#include "dae/format.h"
#include "dae/klu_solver.h"

namespace mbdae::dae {

bool KinematicOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& why) {
    if (error) *error = "KinematicOptions: " + why;
    return false;
  };
  if (!(tolerance > 0) || !std::isfinite(tolerance)) return fail("tolerance must be positive and finite");
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (!(singular_rcond >= 0 && singular_rcond < 1)) return fail("singular_rcond must be in [0, 1)");
  if (!(quadrature_tolerance > 0) || !std::isfinite(quadrature_tolerance))
    return fail("quadrature_tolerance must be positive and finite");
  if (max_quadrature_depth < 0 || max_quadrature_depth > 40)
    return fail("max_quadrature_depth must be in [0, 40]");
  return true;
}

namespace {

std::string Num(double x) { return FormatG(x, 9); }

double MaxAbs(const std::vector<double>& x) {
  double m = 0;
  for (double e : x) m = std::max(m, std::abs(e));
  return m;
}

class Kinematic final : public KinematicSolver {
 public:
  Kinematic(MechanicalSystem& system, const KinematicOptions& options)
      : system_(system),
        options_(options),
        nq_(system.num_coordinates()),
        nc_(system.num_constraints()),
        pcq_(system.pattern(Matrix::kConstraintDq)) {
    std::string error;
    if (!options_.IsValid(&error)) throw std::invalid_argument(error);
    if (nc_ != nq_) {
      const int dof = nq_ - nc_;
      throw std::invalid_argument(
          "kinematic analysis needs a system without degrees of freedom: " + std::to_string(nq_) +
          " coordinates and " + std::to_string(nc_) + " independent constraint equations give " +
          std::to_string(dof) + " degree" + (dof == 1 || dof == -1 ? "" : "s") + " of freedom");
    }
    klu_ = std::make_unique<KluSolver>(pcq_);
    acceleration_ = std::make_unique<AccelerationSolver>(system_);
    c_.assign(nc_, 0.0);
    ct_.assign(nc_, 0.0);
    cq_.assign(pcq_.nnz(), 0.0);
    work_.assign(nq_, 0.0);
    state_.Resize(nq_, nc_);
    EliminationOrder();
  }

  std::string name() const override {
    char buf[160];
    std::snprintf(buf, sizeof buf, "kinematic analysis (Newton on C(q, t) = 0, tolerance %g)",
                  options_.tolerance);
    return buf;
  }

  void SetQuadrature(Quadrature quadrature) override { quad_ = std::move(quadrature); }
  const std::vector<double>& quadrature() const override { return integrals_; }
  void SetStepObserver(StepObserver observer) override { observer_ = std::move(observer); }

  void Initialize(const State& x0) override {
    if (static_cast<int>(x0.q.size()) != nq_ || static_cast<int>(x0.v.size()) != nq_ ||
        static_cast<int>(x0.a.size()) != nq_ || static_cast<int>(x0.lambda.size()) != nc_)
      throw std::invalid_argument("kinematic analysis: the initial state does not have the system's sizes");
    state_ = x0;
    summary_ = Summary();
    summary_.status = Summary::Status::kRunning;
    summary_.t_reached = x0.t;
    statistics_ = KinematicStatistics();
    integrals_.assign(quad_.size, 0.0);
    g0_.assign(quad_.size, 0.0);
    if (quad_.size > 0 && !Integrand(state_, &g0_)) {
      Fail("the quadrature's integrand failed at t = " + Num(state_.t));
      return;
    }
    if (observer_) observer_(state_, 0.0);
  }

  bool AdvanceTo(double t_target) override {
    if (summary_.status != Summary::Status::kRunning) {
      if (summary_.status == Summary::Status::kNotStarted)
        throw std::logic_error("kinematic analysis: AdvanceTo before Initialize");
      if (summary_.status == Summary::Status::kFailed) return false;
      summary_.status = Summary::Status::kRunning;
    }
    if (!(t_target > state_.t) || !std::isfinite(t_target)) {
      Fail("the target time " + Num(t_target) + " is not after the current time " + Num(state_.t));
      return false;
    }
    const double h = t_target - state_.t;
    if (quad_.size > 0) {
      // Adaptive Simpson on [t, t + h], started from the midpoint.
      Node left{state_, g0_}, mid, right;
      if (!SolveNode(state_.t + 0.5 * h, state_, &mid)) return false;
      if (!SolveNode(t_target, mid.x, &right)) return false;
      std::vector<double> whole(quad_.size), whole_abs(quad_.size);
      Simpson(left, mid, right, &whole, &whole_abs);
      if (!AdaptiveSimpson(left, mid, right, whole, whole_abs, 0)) return false;
      next_ = std::move(right.x);
      g0_ = std::move(right.g);
    } else if (!SolveAt(t_target, state_, &next_)) {
      return false;
    }
    std::swap(state_, next_);
    state_.t = t_target;
    summary_.t_reached = t_target;
    summary_.h_last = h;
    summary_.status = Summary::Status::kDone;
    if (observer_) observer_(state_, h);
    return true;
  }

  const State& state() const override { return state_; }
  const Summary& summary() const override { return summary_; }
  const KinematicStatistics& statistics() const override { return statistics_; }

 private:
  // Of a group of dependent equations MakeConsistent sets aside the later ones in this
  // order: the Euler-parameter normalisations (equations whose C_q row lies within one
  // quaternion's four columns) come first, so that they keep their multipliers.
  void EliminationOrder() {
    std::vector<int> group(nq_, -1);
    const std::vector<int>& offsets = system_.quaternion_offsets();
    for (size_t g = 0; g < offsets.size(); ++g)
      for (int k = 0; k < 4; ++k)
        if (offsets[g] + k < nq_) group[offsets[g] + k] = static_cast<int>(g);
    std::vector<int> row_group(nc_, -2);  // -2: no entry yet, -1: not within one quaternion
    for (int c = 0; c < pcq_.cols; ++c)
      for (int k = pcq_.col_start[c]; k < pcq_.col_start[c + 1]; ++k) {
        int& rg = row_group[pcq_.row_index[k]];
        if (rg == -2) rg = group[c];
        else if (rg != group[c]) rg = -1;
      }
    for (int r = 0; r < nc_; ++r)
      if (row_group[r] >= 0) order_.push_back(r);
    for (int r = 0; r < nc_; ++r)
      if (row_group[r] < 0) order_.push_back(r);
  }

  void Fail(const std::string& why) {
    summary_.status = Summary::Status::kFailed;
    summary_.message = why;
  }

  // A solved time of the quadrature: the state and the integrand there.
  struct Node {
    State x;
    std::vector<double> g;
  };

  bool SolveNode(double t, const State& from, Node* node) {
    if (!SolveAt(t, from, &node->x)) return false;
    node->g.assign(quad_.size, 0.0);
    if (!Integrand(node->x, &node->g)) {
      Fail("the quadrature's integrand failed at t = " + Num(t));
      return false;
    }
    return true;
  }

  // Simpson's rule over [a.t, c.t] of g and of |g|.
  void Simpson(const Node& a, const Node& b, const Node& c, std::vector<double>* s,
               std::vector<double>* s_abs) const {
    const double h = c.x.t - a.x.t;
    for (int i = 0; i < quad_.size; ++i) {
      (*s)[i] = h / 6 * (a.g[i] + 4 * b.g[i] + c.g[i]);
      (*s_abs)[i] = h / 6 * (std::abs(a.g[i]) + 4 * std::abs(b.g[i]) + std::abs(c.g[i]));
    }
  }

  // Adds the integral over [a.t, c.t] (b the midpoint, whole its Simpson value) to the
  // integrals: both halves by Simpson's rule, their sum accepted with Richardson's
  // correction when it differs from `whole` by at most 15 quadrature_tolerance (|g|
  // integrated + the interval's length), else each half in turn the same way (at most
  // max_quadrature_depth halvings; the deepest are accepted as they are).
  bool AdaptiveSimpson(const Node& a, const Node& b, const Node& c, const std::vector<double>& whole,
                       const std::vector<double>& whole_abs, int depth) {
    Node ab, bc;
    if (!SolveNode(0.5 * (a.x.t + b.x.t), a.x, &ab)) return false;
    if (!SolveNode(0.5 * (b.x.t + c.x.t), b.x, &bc)) return false;
    const int n = quad_.size;
    std::vector<double> left(n), left_abs(n), right(n), right_abs(n);
    Simpson(a, ab, b, &left, &left_abs);
    Simpson(b, bc, c, &right, &right_abs);
    bool accept = depth >= options_.max_quadrature_depth;
    if (!accept) {
      accept = true;
      const double length = c.x.t - a.x.t;
      for (int i = 0; i < n && accept; ++i)
        accept = std::abs(left[i] + right[i] - whole[i]) <=
                 15 * options_.quadrature_tolerance * (left_abs[i] + right_abs[i] + length);
    }
    if (accept) {
      for (int i = 0; i < n; ++i)
        integrals_[i] += left[i] + right[i] + (left[i] + right[i] - whole[i]) / 15;
      if (depth > statistics_.max_quadrature_depth) statistics_.max_quadrature_depth = depth;
      return true;
    }
    return AdaptiveSimpson(a, ab, b, left, left_abs, depth + 1) &&
           AdaptiveSimpson(b, bc, c, right, right_abs, depth + 1);
  }

  bool Integrand(const State& x, std::vector<double>* g) {
    return quad_.integrand(x.t, x.q.data(), x.v.data(), x.a.data(), x.lambda.data(), g->data()) == 0;
  }

  // C, C_t and C_q at (t, q).
  bool EvaluateConstraints(double t, const std::vector<double>& q) {
    EvalInput in;
    in.t = t;
    in.q = q.data();
    in.v = work_.data();  // not used by these outputs; a valid array all the same
    EvalOutput out;
    out.constraint = c_.data();
    out.constraint_dt = ct_.data();
    out[Matrix::kConstraintDq] = cq_.data();
    ++summary_.residual_evaluations;
    ++summary_.jacobian_evaluations;
    if (system_.Evaluate(in, out) != 0) {
      Fail("kinematic analysis: the system cannot be evaluated at t = " + Num(t) + ": " +
           system_.last_error());
      return false;
    }
    return true;
  }

  // Factorises C_q; false when KLU finds it singular or its condition estimate is below
  // singular_rcond.
  bool FactorConstraintJacobian() {
    ++summary_.factorizations;
    return klu_->Factor(cq_.data()) && klu_->rcond() >= options_.singular_rcond;
  }

  // How a Newton iteration on C(q, t) = 0 ended.
  enum class Newton { kConverged, kNotConverged, kSingular, kError };

  // Newton on C(q, t) = 0 from *q (changed in place); *iterations counts the updates,
  // *residual is the smallest max |C| seen. On kConverged C, C_t and C_q are those of
  // the final *q.
  Newton NewtonIteration(double t, std::vector<double>* q, int* iterations, double* residual) {
    *iterations = 0;
    *residual = std::numeric_limits<double>::infinity();
    for (;;) {
      if (!EvaluateConstraints(t, *q)) return Newton::kError;
      const double r = MaxAbs(c_);
      if (!std::isfinite(r)) return Newton::kNotConverged;
      *residual = std::min(*residual, r);
      if (r <= options_.tolerance * std::max(1.0, MaxAbs(*q))) return Newton::kConverged;
      if (*iterations == options_.max_iterations) return Newton::kNotConverged;
      if (!FactorConstraintJacobian()) return Newton::kSingular;
      for (int i = 0; i < nc_; ++i) work_[i] = -c_[i];
      klu_->Solve(work_.data());
      for (int i = 0; i < nq_; ++i) (*q)[i] += work_[i];
      ++*iterations;
    }
  }

  // The state at t from the solved state `from`. Newton starts from from.q + h from.v +
  // h^2/2 from.a; if that fails, once more from from.q (the extrapolation is poor where
  // the velocities grow without bound, at a dead centre); where C_q is singular the point
  // is solved as the assembly solves the initial state (SolveSingular).
  bool SolveAt(double t, const State& from, State* x) {
    const double h = t - from.t;
    x->t = t;
    x->q.resize(nq_);
    x->v.resize(nq_);
    x->a.resize(nq_);
    x->lambda.resize(nc_);
    for (int i = 0; i < nq_; ++i) x->q[i] = from.q[i] + h * from.v[i] + 0.5 * h * h * from.a[i];
    int iterations = 0, total = 0;
    double residual = 0, best = std::numeric_limits<double>::infinity();
    Newton end = NewtonIteration(t, &x->q, &iterations, &residual);
    total += iterations;
    best = std::min(best, residual);
    if (end == Newton::kNotConverged || end == Newton::kSingular) {
      x->q = from.q;
      end = NewtonIteration(t, &x->q, &iterations, &residual);
      total += iterations;
      best = std::min(best, residual);
    }
    if (end == Newton::kError) return false;
    if (end == Newton::kNotConverged) {
      Fail("kinematic analysis: Newton on the position constraints did not converge at t = " + Num(t) +
           ": smallest max |C| = " + Num(best) + " in " + std::to_string(total) +
           " iterations (a position the driven motion cannot reach, or a lock-up)");
      return false;
    }
    if (end == Newton::kSingular) return SolveSingular(t, from, x, total, best);
    // C_q at the converged positions, factorised for the velocities, C_q v = -C_t; with
    // it one more Newton correction of the positions, which costs one solve and brings
    // max |C| from the tolerance to the rounding level (Newton converges quadratically).
    if (!FactorConstraintJacobian()) return SolveSingular(t, from, x, total, 0.0);
    Count(total);
    for (int i = 0; i < nc_; ++i) work_[i] = -c_[i];
    klu_->Solve(work_.data());
    for (int i = 0; i < nq_; ++i) x->q[i] += work_[i];
    for (int i = 0; i < nc_; ++i) x->v[i] = -ct_[i];
    klu_->Solve(x->v.data());
    return Accelerations(x);
  }

  bool Accelerations(State* x) {
    ++summary_.factorizations;
    if (acceleration_->Solve(x->t, x->q.data(), x->v.data(), x->a.data(), x->lambda.data()) != 0) {
      Fail("kinematic analysis: accelerations and multipliers at t = " + Num(x->t) + ": " +
           acceleration_->last_error());
      return false;
    }
    return true;
  }

  void Count(int iterations) {
    summary_.newton_iterations += iterations;
    ++summary_.steps_accepted;
    statistics_.max_newton_iterations = std::max(statistics_.max_newton_iterations, iterations);
  }

  // C_q singular (a dead centre, a passage through a singular position): the point as
  // the consistent initial values are found (dae::MakeConsistent: minimum-norm
  // Gauss-Newton steps from the previous positions, the velocities projected from the
  // previous ones), with the normalisations kept first.
  bool SolveSingular(double t, const State& from, State* x, int iterations, double newton_residual) {
    State y;
    y.t = t;
    y.q = from.q;
    y.v = from.v;
    ConsistencyOptions co;
    co.position_tolerance = options_.tolerance * std::max(1.0, MaxAbs(y.q));
    co.max_iterations = options_.max_iterations;
    co.elimination_order = order_;
    const ConsistencyReport report = MakeConsistent(system_, y, co);
    if (!report.ok) {
      Fail("kinematic analysis: the constraint Jacobian is singular at t = " + Num(t) +
           " (a dead centre or lock-up: Newton reached max |C| = " + Num(newton_residual) +
           ") and the minimum-norm solve failed there: " + report.message);
      return false;
    }
    ++statistics_.singular_points;
    Count(iterations + report.iterations);
    *x = std::move(y);
    return true;
  }

  MechanicalSystem& system_;
  KinematicOptions options_;
  const int nq_, nc_;
  const CscPattern& pcq_;
  std::unique_ptr<KluSolver> klu_;
  std::unique_ptr<AccelerationSolver> acceleration_;
  std::vector<double> c_, ct_, cq_, work_;
  std::vector<int> order_;
  State state_, next_;
  Summary summary_;
  KinematicStatistics statistics_;
  Quadrature quad_;
  std::vector<double> integrals_, g0_;
  StepObserver observer_;
};

}  // namespace

std::unique_ptr<KinematicSolver> MakeKinematicSolver(MechanicalSystem& system,
                                                     const KinematicOptions& options) {
  return std::make_unique<Kinematic>(system, options);
}

}  // namespace mbdae::dae
