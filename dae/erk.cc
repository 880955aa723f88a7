// Dormand-Prince 5(4) on the index-1 form with coordinate projection (dae/erk.h).
#include "dae/erk.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include "dae/consistent.h"
#include "dae/format.h"

namespace mbdae::dae {

namespace {

std::string Num(double x) { return FormatG(x, 6); }

// Dormand & Prince (1980), Hairer, Norsett, Wanner (1993) Table 5.2: nodes c, the
// coupling coefficients A (lower triangle, row i has i entries), the 5th-order weights
// b (= row 7 of A: first same as last) and e = b - bhat, bhat the 4th-order weights.
constexpr int kStages = 7;
constexpr double kC[kStages] = {0.0, 1.0 / 5, 3.0 / 10, 4.0 / 5, 8.0 / 9, 1.0, 1.0};
constexpr double kA[kStages][kStages - 1] = {
    {0, 0, 0, 0, 0, 0},
    {1.0 / 5, 0, 0, 0, 0, 0},
    {3.0 / 40, 9.0 / 40, 0, 0, 0, 0},
    {44.0 / 45, -56.0 / 15, 32.0 / 9, 0, 0, 0},
    {19372.0 / 6561, -25360.0 / 2187, 64448.0 / 6561, -212.0 / 729, 0, 0},
    {9017.0 / 3168, -355.0 / 33, 46732.0 / 5247, 49.0 / 176, -5103.0 / 18656, 0},
    {35.0 / 384, 0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84}};
constexpr double kB[kStages] = {35.0 / 384, 0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84, 0};
constexpr double kE[kStages] = {71.0 / 57600,      0,           -71.0 / 16695, 71.0 / 1920,
                                -17253.0 / 339200, 22.0 / 525, -1.0 / 40};

// Step-size control (Hairer et al. II.4, the code DOPRI5): h_new = h / fac with
// fac = clamp(err^(1/5 - 0.75 beta) / err_old^beta / safety, 1/10, 5): a PI controller
// with beta = 0.04 (Gustafsson's stabilisation), safety 0.9, growth at most 10, decrease
// at most 5 per step; no growth right after a rejection.
constexpr double kBeta = 0.04;
constexpr double kSafety = 0.9;
constexpr double kFacMin = 0.2;   // h_new >= 0.2 h
constexpr double kFacMax = 10.0;  // h_new <= 10 h
// The pivot growth of KLU's refactorisations is checked once per step (6 factorisations)
// rather than at each: it cost 9 % of a run on the 1000-body chain (bench/peers); the
// condition estimate is checked at every one, and a stage solved with poor pivots shows
// in the step's error estimate.
constexpr int kGrowthCheckInterval = kStages - 1;

class ErkIntegrator final : public Integrator {
 public:
  ErkIntegrator(MechanicalSystem& system, const ErkOptions& options)
      : sys_(system), opt_(options),
        acc_(system, kGrowthCheckInterval, /*tree_elimination=*/true),
        nq_(system.num_coordinates()), nc_(system.num_constraints()) {
    std::string why;
    if (!opt_.IsValid(&why)) throw std::invalid_argument(why);
    for (int s = 0; s < kStages; ++s) {
      kq_[s].assign(nq_, 0.0);
      kv_[s].assign(nq_, 0.0);
    }
    for (auto* v : {&yq_, &yv_, &q1_, &v1_, &eq_, &ev_}) v->assign(nq_, 0.0);
    lam_.assign(nc_, 0.0);
    con_.assign(nc_, 0.0);
    con_dt_.assign(nc_, 0.0);
    cqv_.assign(nc_, 0.0);
    rhs_.assign(nq_ + nc_, 0.0);
    cq_values_.assign(sys_.pattern(Matrix::kConstraintDq).nnz(), 0.0);
    state_.Resize(nq_, nc_);
  }

  void SetQuadrature(Quadrature quadrature) override {
    if (quadrature.size < 0 || (quadrature.size > 0 && !quadrature.integrand))
      throw std::invalid_argument("ERK::SetQuadrature: a positive size needs an integrand");
    quad_spec_ = std::move(quadrature);
    quad_.assign(quad_spec_.size, 0.0);
    quad_new_.assign(quad_spec_.size, 0.0);
    for (auto& g : quad_g_) g.assign(quad_spec_.size, 0.0);
  }
  const std::vector<double>& quadrature() const override { return quad_; }

  void Initialize(const State& x0) override {
    if (static_cast<int>(x0.q.size()) != nq_ || static_cast<int>(x0.v.size()) != nq_ ||
        static_cast<int>(x0.a.size()) != nq_ || static_cast<int>(x0.lambda.size()) != nc_)
      throw std::invalid_argument("ERK::Initialize: state sizes do not match the system (q " +
                                  std::to_string(x0.q.size()) + ", lambda " +
                                  std::to_string(x0.lambda.size()) + "; nq = " +
                                  std::to_string(nq_) + ", nc = " + std::to_string(nc_) + ")");
    state_ = x0;
    summary_ = Summary();
    summary_.status = Summary::Status::kRunning;
    summary_.t_reached = x0.t;
    err_old_ = 1e-4;
    rejected_last_ = false;
    stage_failure_.clear();
    std::fill(quad_.begin(), quad_.end(), 0.0);
    initialized_ = true;
    if (quad_spec_.size > 0 &&
        quad_spec_.integrand(state_.t, state_.q.data(), state_.v.data(), state_.a.data(),
                             state_.lambda.data(), quad_g_[0].data()) != 0) {
      initialized_ = false;
      summary_.status = Summary::Status::kFailed;
      summary_.message = "quadrature integrand failed at the initial state";
      return;
    }
    h_ = opt_.initial_step > 0 ? opt_.initial_step : InitialStep();
    if (opt_.max_step > 0) h_ = std::min(h_, opt_.max_step);
  }

  bool AdvanceTo(double t_target) override {
    if (!initialized_) return Fail("AdvanceTo called before a successful Initialize");
    if (!(t_target > state_.t)) return Fail("AdvanceTo: target time " + Num(t_target) +
                                            " is not after the current time " + Num(state_.t));
    summary_.status = Summary::Status::kRunning;
    while (state_.t < t_target) {
      if (summary_.steps_accepted + summary_.steps_rejected >= opt_.max_steps)
        return Fail("the step budget (max_steps = " + std::to_string(opt_.max_steps) +
                    " steps) is spent at t = " + Num(state_.t) + " (step size now " + Num(h_) +
                    "): a stiff force (an explicit method needs steps as small as its time "
                    "scale; use hht or ida) or a tolerance too small");
      const double remaining = t_target - state_.t;
      const double min_step = opt_.min_step > 0
                                  ? opt_.min_step
                                  : 1e-14 * std::max(1.0, std::abs(state_.t));
      if (h_ < min_step && remaining > min_step)
        return Fail("the step size " + Num(h_) + " at t = " + Num(state_.t) +
                    " is below the smallest step " + Num(min_step) +
                    (opt_.min_step > 0 ? " (min_step)" : "") +
                    ": the accelerations are not smooth here (a singular position, a "
                    "discontinuous force) or the problem is stiff; use hht or ida" +
                    (stage_failure_.empty() ? "" : " (last failed stage: " + stage_failure_ + ")"));
      bool last = false;
      double h = h_;
      if (remaining <= h * (1 + 1e-2)) {
        h = remaining;  // land on the target, stretching by at most 1 %
        last = true;
      }
      const int rc = TryStep(h);
      if (rc < 0) return Fail(message_);
      if (rc > 0) {  // a stage could not be evaluated or solved: shorter step
        stage_failure_ = message_;
        ++summary_.steps_rejected;
        h_ = 0.25 * h;
        rejected_last_ = true;
        continue;
      }
      const double err = ErrorNorm();
      if (!std::isfinite(err)) {
        ++summary_.steps_rejected;
        h_ = 0.25 * h;
        rejected_last_ = true;
        continue;
      }
      const double fac11 = std::pow(err, 0.2 - 0.75 * kBeta);
      if (err > 1.0) {
        ++summary_.steps_rejected;
        h_ = h / std::min(1 / kFacMin, fac11 / kSafety);
        rejected_last_ = true;
        continue;
      }
      double fac = fac11 / std::pow(err_old_, kBeta) / kSafety;
      fac = std::clamp(fac, 1 / kFacMax, 1 / kFacMin);
      double h_new = h / fac;
      if (rejected_last_) h_new = std::min(h_new, h);
      if (opt_.max_step > 0) h_new = std::min(h_new, opt_.max_step);
      err_old_ = std::max(err, 1e-4);
      const double t1 = last ? t_target : state_.t + h;
      if (!Accept(h, t1, last)) return Fail(message_);
      rejected_last_ = false;
      // A step cut short to land on the target keeps the controller's step.
      h_ = last && h < h_ ? std::max(h_, h_new) : h_new;
    }
    summary_.status = Summary::Status::kDone;
    summary_.message.clear();
    return true;
  }

  const State& state() const override { return state_; }
  const Summary& summary() const override { return summary_; }
  std::string name() const override {
    return "explicit Runge-Kutta Dormand-Prince 5(4) on the index-1 form" +
           std::string(opt_.project ? " with coordinate projection" : "") +
           ", rtol = " + Num(opt_.rtol) + ", atol = " + Num(opt_.atol);
  }

 private:
  bool Fail(const std::string& why) {
    summary_.status = Summary::Status::kFailed;
    summary_.message = why;
    return false;
  }

  // a, lambda at (t, q, v); counts the evaluation and the factorisation.
  int Accelerations(double t, const double* q, const double* v, double* a, double* lambda) {
    ++summary_.residual_evaluations;
    ++summary_.factorizations;
    const int rc = acc_.Solve(t, q, v, a, lambda);
    if (rc != 0) message_ = acc_.last_error();
    return rc;
  }

  // Weights of the error norm for y = (q, v): atol + rtol |y|.
  double Weight(double y) const { return opt_.atol + opt_.rtol * std::abs(y); }

  // Hairer et al. II.4: h0 from the sizes of y0, f(y0) and a second derivative estimate.
  double InitialStep() {
    double d0 = 0, d1 = 0;
    for (int i = 0; i < nq_; ++i) {
      const double wq = Weight(state_.q[i]), wv = Weight(state_.v[i]);
      d0 += (state_.q[i] / wq) * (state_.q[i] / wq) + (state_.v[i] / wv) * (state_.v[i] / wv);
      d1 += (state_.v[i] / wq) * (state_.v[i] / wq) + (state_.a[i] / wv) * (state_.a[i] / wv);
    }
    d0 = std::sqrt(d0 / (2 * nq_));
    d1 = std::sqrt(d1 / (2 * nq_));
    double h0 = d0 < 1e-5 || d1 < 1e-5 ? 1e-6 : 0.01 * d0 / d1;
    for (int i = 0; i < nq_; ++i) {
      yq_[i] = state_.q[i] + h0 * state_.v[i];
      yv_[i] = state_.v[i] + h0 * state_.a[i];
    }
    double d2 = 0;
    if (Accelerations(state_.t + h0, yq_.data(), yv_.data(), kv_[1].data(), lam_.data()) == 0) {
      for (int i = 0; i < nq_; ++i) {
        const double wq = Weight(state_.q[i]), wv = Weight(state_.v[i]);
        const double dq = (yv_[i] - state_.v[i]) / wq, dv = (kv_[1][i] - state_.a[i]) / wv;
        d2 += dq * dq + dv * dv;
      }
      d2 = std::sqrt(d2 / (2 * nq_)) / h0;
    }
    const double dm = std::max(d1, d2);
    const double h1 = dm <= 1e-15 ? std::max(1e-6, h0 * 1e-3) : std::pow(0.01 / dm, 1.0 / 5);
    return std::min(100 * h0, h1);
  }

  // The stages of a step of size h from state_; q1_, v1_ the 5th-order solution, eq_, ev_
  // the error estimate. 0: done; > 0: a stage failed (retry shorter); < 0: fatal.
  int TryStep(double h) {
    const State& x = state_;
    std::copy(x.v.begin(), x.v.end(), kq_[0].begin());
    std::copy(x.a.begin(), x.a.end(), kv_[0].begin());
    for (int s = 1; s < kStages; ++s) {
      for (int i = 0; i < nq_; ++i) {
        double dq = 0, dv = 0;
        for (int j = 0; j < s; ++j) {
          dq += kA[s][j] * kq_[j][i];
          dv += kA[s][j] * kv_[j][i];
        }
        yq_[i] = x.q[i] + h * dq;
        yv_[i] = x.v[i] + h * dv;
      }
      std::copy(yv_.begin(), yv_.end(), kq_[s].begin());
      const double ts = x.t + kC[s] * h;
      const int rc = Accelerations(ts, yq_.data(), yv_.data(), kv_[s].data(), lam_.data());
      if (rc != 0) return rc;
      if (quad_spec_.size > 0 && s < kStages - 1 &&
          quad_spec_.integrand(ts, yq_.data(), yv_.data(), kv_[s].data(), lam_.data(),
                               quad_g_[s].data()) != 0) {
        message_ = "quadrature integrand failed at t = " + Num(ts);
        return -1;
      }
    }
    // Stage 7 is at the 5th-order solution (row 7 of A is b).
    std::copy(yq_.begin(), yq_.end(), q1_.begin());
    std::copy(yv_.begin(), yv_.end(), v1_.begin());
    for (int i = 0; i < nq_; ++i) {
      double dq = 0, dv = 0;
      for (int s = 0; s < kStages; ++s) {
        dq += kE[s] * kq_[s][i];
        dv += kE[s] * kv_[s][i];
      }
      eq_[i] = h * dq;
      ev_[i] = h * dv;
    }
    return 0;
  }

  double ErrorNorm() const {
    double sum = 0;
    for (int i = 0; i < nq_; ++i) {
      const double wq = opt_.atol + opt_.rtol * std::max(std::abs(state_.q[i]), std::abs(q1_[i]));
      const double wv = opt_.atol + opt_.rtol * std::max(std::abs(state_.v[i]), std::abs(v1_[i]));
      sum += (eq_[i] / wq) * (eq_[i] / wq) + (ev_[i] / wv) * (ev_[i] / wv);
    }
    return std::sqrt(sum / (2 * nq_));
  }

  // Projects (q1_, v1_) onto the constraints at t1 and makes it the state. Its a and
  // lambda: at the end of AdvanceTo (`solve`) solved afresh at the projected state; between
  // steps those of the last stage (at t1 and the 5th-order solution before projection,
  // first same as last), which the next step takes as its first stage (docs/erk.md,
  // "First same as last"). False (message_) when that fails.
  bool Accept(double h, double t1, bool solve) {
    if (quad_spec_.size > 0)
      for (int k = 0; k < quad_spec_.size; ++k) {
        double sum = 0;
        for (int s = 0; s < kStages - 1; ++s) sum += kB[s] * quad_g_[s][k];
        quad_new_[k] = quad_[k] + h * sum;
      }
    if (opt_.project && nc_ > 0 && !Project(t1)) return false;
    // a and lambda at the accepted state: the first stage of the next step. Without a
    // projection the last stage's are at the state itself already.
    std::vector<double>& a1 = kv_[kStages - 1];  // the last stage's a (lam_: its lambda)
    if (solve && opt_.project && nc_ > 0) {
      if (const int rc = Accelerations(t1, q1_.data(), v1_.data(), a1.data(), lam_.data());
          rc != 0) {
        message_ = "the accelerations at the accepted state t = " + Num(t1) +
                   " cannot be solved: " + message_;
        return false;
      }
    }
    state_.t = t1;
    state_.q.swap(q1_);
    state_.v.swap(v1_);
    std::copy(a1.begin(), a1.end(), state_.a.begin());
    std::copy(lam_.begin(), lam_.end(), state_.lambda.begin());
    if (quad_spec_.size > 0) {
      if (quad_spec_.integrand(state_.t, state_.q.data(), state_.v.data(), state_.a.data(),
                               state_.lambda.data(), quad_g_[0].data()) != 0) {
        message_ = "quadrature integrand failed at t = " + Num(state_.t);
        return false;
      }
      quad_.swap(quad_new_);
    }
    ++summary_.steps_accepted;
    summary_.t_reached = t1;
    summary_.h_last = h;
    return true;
  }

  // The mass-metric projection with the factorisation of the last stage (at t1, q1_, v1_
  // before projection): simplified Newton on C(q) = 0, then one solve for the velocities.
  bool Project(double t1) {
    const CscPattern& pc = sys_.pattern(Matrix::kConstraintDq);
    for (int it = 0; it < opt_.max_projection_iterations; ++it) {
      EvalInput in;
      in.t = t1;
      in.q = q1_.data();
      in.v = v1_.data();
      EvalOutput out;
      out.constraint = con_.data();
      out.constraint_dt = con_dt_.data();
      out[Matrix::kConstraintDq] = cq_values_.data();
      ++summary_.residual_evaluations;
      if (const int rc = sys_.Evaluate(in, out); rc != 0) {
        message_ = "the constraints cannot be evaluated at t = " + Num(t1) + " (projection): " +
                   sys_.last_error();
        return false;
      }
      ++summary_.newton_iterations;
      std::fill(rhs_.begin(), rhs_.begin() + nq_, 0.0);
      for (int j = 0; j < nc_; ++j) rhs_[nq_ + j] = -con_[j];
      acc_.SolveAgain(rhs_.data());
      double norm = 0;
      for (int i = 0; i < nq_; ++i) {
        q1_[i] += rhs_[i];
        const double w = rhs_[i] / Weight(q1_[i]);
        norm = std::max(norm, std::abs(w));
      }
      if (!std::isfinite(norm)) {
        message_ = "the position projection at t = " + Num(t1) + " did not give finite values";
        return false;
      }
      if (norm <= 1e-3) break;
    }
    // Velocities: C_q v + C_t with the C_q of the last evaluation (before the last, small
    // position correction).
    std::fill(cqv_.begin(), cqv_.end(), 0.0);
    MultiplyAdd(pc, cq_values_.data(), 1.0, v1_.data(), cqv_.data());
    std::fill(rhs_.begin(), rhs_.begin() + nq_, 0.0);
    for (int j = 0; j < nc_; ++j) rhs_[nq_ + j] = -(cqv_[j] + con_dt_[j]);
    acc_.SolveAgain(rhs_.data());
    for (int i = 0; i < nq_; ++i) v1_[i] += rhs_[i];
    return true;
  }

  MechanicalSystem& sys_;
  ErkOptions opt_;
  AccelerationSolver acc_;
  int nq_ = 0, nc_ = 0;
  State state_;
  Summary summary_;
  bool initialized_ = false;
  std::string message_;
  std::string stage_failure_;  // why the last stage that failed did
  double h_ = 0;
  double err_old_ = 1e-4;
  bool rejected_last_ = false;
  std::vector<double> kq_[kStages], kv_[kStages];  // stage derivatives of q and v
  std::vector<double> yq_, yv_, q1_, v1_, eq_, ev_, lam_, con_, con_dt_, cqv_, rhs_,
      cq_values_;
  Quadrature quad_spec_;
  std::vector<double> quad_, quad_new_;
  std::vector<double> quad_g_[kStages];
};

}  // namespace

bool ErkOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& why) {
    if (error) *error = "ErkOptions: " + why;
    return false;
  };
  if (!(rtol > 0) || !std::isfinite(rtol)) return fail("rtol must be > 0, got " + Num(rtol));
  if (!(atol > 0) || !std::isfinite(atol)) return fail("atol must be > 0, got " + Num(atol));
  if (!(initial_step >= 0) || !std::isfinite(initial_step))
    return fail("initial_step must be >= 0 (0: automatic), got " + Num(initial_step));
  if (!(max_step >= 0) || !std::isfinite(max_step))
    return fail("max_step must be >= 0 (0: no limit), got " + Num(max_step));
  if (!(min_step >= 0) || !std::isfinite(min_step))
    return fail("min_step must be >= 0 (0: automatic), got " + Num(min_step));
  if (max_step > 0 && min_step > max_step)
    return fail("min_step " + Num(min_step) + " is larger than max_step " + Num(max_step));
  if (max_steps < 1) return fail("max_steps must be >= 1, got " + std::to_string(max_steps));
  if (max_projection_iterations < 1)
    return fail("max_projection_iterations must be >= 1, got " +
                std::to_string(max_projection_iterations));
  return true;
}

std::unique_ptr<Integrator> MakeErkIntegrator(MechanicalSystem& system, const ErkOptions& options) {
  return std::make_unique<ErkIntegrator>(system, options);
}

}  // namespace mbdae::dae
