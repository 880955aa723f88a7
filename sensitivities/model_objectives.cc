#include "sensitivities/model_objectives.h"

#include <cmath>
#include <exception>
#include <limits>
#include <string>
#include <stdexcept>

#include "mbs/measure_kinematics.h"
#include "mbs/reaction.h"

namespace mbdae::sens {

namespace {

using mbs::Vec14;
using mbs::Mat14;

// Adds c * local (14) into the global vector x (nq) by the measure's slot offsets.
void Scatter(const int offset[2], const Vec14& local, double c, double* x) {
  for (int s = 0; s < 2; ++s) {
    if (offset[s] < 0) continue;
    for (int k = 0; k < 7; ++k) x[offset[s] + k] += c * local[7 * s + k];
  }
}

}  // namespace

struct ModelObjectives::Impl {
  const mbs::Model& model;
  const mbs::MultibodySystem& system;
  std::vector<int> kept;
  std::vector<mbs::SensitivityParameter> params;
  // chain[k][j] = d(model parameter j)/d(params[k]) (mbs::ParameterChain);
  // spline_dirs[k][s]: d(ordinates of spline s)/d(params[k]) when params[k] is a model
  // parameter that inline points of spline s use (empty otherwise).
  std::vector<std::vector<double>> chain;
  std::vector<std::vector<std::vector<double>>> spline_dirs;
  // tangents[k][s]: Spline::Tangent of spline s along params[k] (its ordinate, or
  // spline_dirs[k][s]), built on first use; the ordinates' abscissae do not change
  // during the object's life, so one build serves every step of a sweep.
  std::vector<std::vector<std::unique_ptr<mbs::Spline>>> tangents;
  int nq = 0, nc_full = 0;
  std::vector<std::string> names;
  std::vector<int> used;                 // model measure indices used by some objective
  std::vector<mbs::MeasureDef> defs;     // by model measure index (kinematic ones)
  std::vector<double> offsets;           // by model measure index
  std::vector<double> values;            // by model measure index (used ones set)
  std::vector<double> coef;              // by model measure index: d(sum w f)/dm
  std::vector<double> lambda_full, dlambda_full;
  std::vector<const mbs::Spline*> splines;
  std::unique_ptr<mbs::ReactionMeasures> reactions;
  std::vector<int> angles;               // used angle measures (model order)
  std::vector<mbs::MeasureDef> rate_defs;  // their rates
  AngleTrack track;
  bool acceleration = false, multipliers = false;
  std::string error;

  Impl(const mbs::Model& m, const mbs::MultibodySystem& sys, std::vector<int> k,
       std::vector<mbs::SensitivityParameter> p)
      : model(m), system(sys), kept(std::move(k)), params(std::move(p)) {
    nq = system.num_coordinates();
    nc_full = system.num_constraints();
    for (int r : kept)
      if (r < 0 || r >= nc_full) throw std::invalid_argument("ModelObjectives: kept equation out of range");
    for (const auto& sp : params) {
      if (sp.parameter >= static_cast<int>(model.parameters.size()) ||
          (sp.parameter < 0 && (sp.spline < 0 || sp.spline >= static_cast<int>(model.splines.size()))))
        throw std::invalid_argument("ModelObjectives: sensitivity parameter '" + sp.name + "' out of range");
    }
    chain = mbs::ParameterChain(model, params);
    spline_dirs.assign(params.size(), std::vector<std::vector<double>>(model.splines.size()));
    for (size_t k = 0; k < params.size(); ++k) {
      if (params[k].parameter < 0) continue;
      for (size_t sp = 0; sp < model.splines.size(); ++sp) {
        if (!model.splines[sp].depends_on_parameters()) continue;
        std::vector<double> dir =
            mbs::SplineOrdinateDirection(model, params[k], chain[k], static_cast<int>(sp));
        bool nonzero = false;
        for (double d : dir) nonzero = nonzero || d != 0;
        if (nonzero) spline_dirs[k][sp] = std::move(dir);
      }
    }
    const int nm = static_cast<int>(model.measures.size());
    std::vector<bool> is_used(nm, false);
    for (const mbs::Objective& o : model.objectives) {
      names.push_back(o.name);
      for (const mbs::Expression* e : {&o.integral, &o.terminal})
        for (int u : e->measures_used()) is_used[u] = true;
    }
    defs.resize(nm);
    offsets.assign(nm, 0.0);
    values.assign(nm, 0.0);
    coef.assign(nm, 0.0);
    std::vector<double> q0, v0;
    system.InitialState(q0, v0);
    bool any_reaction = false;
    for (int u = 0; u < nm; ++u) {
      if (!is_used[u]) continue;
      used.push_back(u);
      const mbs::Measure& me = model.measures[u];
      if (me.type == mbs::MeasureType::kReaction) {
        any_reaction = multipliers = true;
        continue;
      }
      defs[u] = mbs::ResolveMeasure(model, u);
      if (me.quantity == mbs::Quantity::kAcceleration) acceleration = true;
      if (me.offset_initial) offsets[u] = mbs::EvaluateMeasureValue(defs[u], q0.data(), v0.data(), nullptr);
      if (mbs::IsAngleMeasure(me)) {
        angles.push_back(u);
        rate_defs.push_back(mbs::AngleRate(defs[u]));
        const double angle0 = mbs::EvaluateMeasureValue(defs[u], q0.data(), v0.data(), nullptr);
        track.angles.push_back(std::isfinite(me.turn_reference) ? mbs::UnwrapAngle(angle0, me.turn_reference) : angle0);
        track.rates.push_back(0.0);
      }
    }
    track.t = std::numeric_limits<double>::quiet_NaN();
    if (any_reaction) reactions = std::make_unique<mbs::ReactionMeasures>(model, system.parameters());
    lambda_full.assign(nc_full, 0.0);
    dlambda_full.assign(nc_full, 0.0);
    for (const mbs::SplineDef& sd : model.splines) splines.push_back(&sd.spline);
  }

  // The tangent of spline s along params[k] (null: zero direction).
  const mbs::Spline* Tangent(size_t k, int s) {
    if (tangents.size() != params.size()) tangents.resize(params.size());
    std::vector<std::unique_ptr<mbs::Spline>>& row = tangents[k];
    if (row.empty()) row.resize(model.splines.size());
    if (!row[s]) {
      const mbs::Spline& spline = model.splines[s].spline;
      if (params[k].parameter >= 0) {
        if (spline_dirs[k][s].empty()) return nullptr;
        row[s] = std::make_unique<mbs::Spline>(spline.Tangent(spline_dirs[k][s]));
      } else {
        if (params[k].spline != s) return nullptr;
        std::vector<double> dy(spline.x().size(), 0.0);
        dy.at(params[k].point) = 1;
        row[s] = std::make_unique<mbs::Spline>(spline.Tangent(dy));
      }
    }
    return row[s].get();
  }

  mbs::ExpressionInputs Inputs(double t) const {
    mbs::ExpressionInputs in;
    in.t = t;
    in.parameters = system.parameters().data();
    in.measures = values.data();
    in.splines = splines.empty() ? nullptr : splines.data();
    return in;
  }

  void FullLambda(const double* lambda) {
    std::fill(lambda_full.begin(), lambda_full.end(), 0.0);
    if (!lambda) return;
    for (size_t k = 0; k < kept.size(); ++k) lambda_full[kept[k]] = lambda[k];
  }

  // The values of the used measures at x (into `values`).
  int Measures(const ObjectivePoint& x) {
    FullLambda(x.lambda);
    if (reactions) reactions->parameters() = system.parameters();
    for (int u : used) {
      const mbs::Measure& me = model.measures[u];
      if (me.type == mbs::MeasureType::kReaction) {
        if (const int rc = reactions->Derivatives(u, x.t, x.q, lambda_full.data(), 0.0, &values[u],
                                                  nullptr, nullptr);
            rc != 0) {
          error = std::string("reaction measure '") + me.name + "': " + reactions->last_error();
          return rc;
        }
        continue;
      }
      values[u] = mbs::EvaluateMeasureValue(defs[u], x.q, x.v, x.a) - offsets[u];
    }
    // Angles: the turn nearest to the prediction from the last evaluation.
    for (size_t k = 0; k < angles.size(); ++k) {
      const int u = angles[k];
      const double rate = mbs::EvaluateMeasureValue(rate_defs[k], x.q, x.v, nullptr);
      const double raw = values[u] + offsets[u];
      const double angle = std::isfinite(track.t)
                               ? mbs::UnwrapAngle(raw, track.angles[k], track.rates[k], rate, x.t - track.t)
                               : mbs::UnwrapAngle(raw, track.angles[k]);
      values[u] = angle - offsets[u];
      track.angles[k] = angle;
      track.rates[k] = rate;
    }
    if (!angles.empty()) track.t = x.t;
    return 0;
  }

  int Values(bool terminal, const ObjectivePoint& x, double* out) {
    try {
      if (const int rc = Measures(x); rc != 0) return rc;
      const mbs::ExpressionInputs in = Inputs(x.t);
      for (size_t i = 0; i < model.objectives.size(); ++i) {
        const mbs::Objective& o = model.objectives[i];
        const bool has = terminal ? o.has_terminal : o.has_integral;
        out[i] = has ? (terminal ? o.terminal : o.integral).Evaluate(in) : 0.0;
      }
    } catch (const std::exception& e) {
      error = e.what();
      return -1;
    }
    return 0;
  }

  // d(v^T H(q) v)/dq by central differences of the exact Hessian, added with factor c.
  void AccelerationQuadraticDq(const mbs::MeasureDef& def, const double* q, const Vec14& vl,
                               double c, double* dq) const {
    std::vector<double> qp(q, q + nq);
    mbs::MeasureJacobian jp, jm;
    for (int s = 0; s < 2; ++s) {
      if (def.offset[s] < 0) continue;
      for (int k = 0; k < 7; ++k) {
        const int i = def.offset[s] + k;
        const double h = 1e-5 * (1 + std::abs(q[i]));
        qp[i] = q[i] + h;
        mbs::EvaluateMeasurePosition(def, qp.data(), true, &jp);
        qp[i] = q[i] - h;
        mbs::EvaluateMeasurePosition(def, qp.data(), true, &jm);
        qp[i] = q[i];
        dq[i] += c * (vl.dot(jp.hessian * vl) - vl.dot(jm.hessian * vl)) / (2 * h);
      }
    }
  }

  int Gradient(bool terminal, const ObjectivePoint& x, const double* weights, ObjectiveGradient* out) {
    try {
      if (const int rc = Measures(x); rc != 0) return rc;
      const mbs::ExpressionInputs in = Inputs(x.t);
      std::fill(coef.begin(), coef.end(), 0.0);
      mbs::ExpressionGradient g;
      for (size_t i = 0; i < model.objectives.size(); ++i) {
        const mbs::Objective& o = model.objectives[i];
        if (!(terminal ? o.has_terminal : o.has_integral) || weights[i] == 0) continue;
        const mbs::Expression& e = terminal ? o.terminal : o.integral;
        e.EvaluateGradient(in, &g);
        const double w = weights[i];
        for (size_t k = 0; k < e.measures_used().size(); ++k) coef[e.measures_used()[k]] += w * g.d_measures[k];
        if (!out->dp) continue;
        for (size_t k = 0; k < params.size(); ++k) {
          const mbs::SensitivityParameter& sp = params[k];
          if (sp.parameter >= 0) {
            // Total derivative through the parameters computed from this one.
            for (size_t u = 0; u < e.parameters_used().size(); ++u)
              out->dp[k] += w * g.d_parameters[u] * chain[k][e.parameters_used()[u]];
            for (int s : e.splines_used())
              if (const mbs::Spline* tangent = Tangent(k, s))
                out->dp[k] += w * e.EvaluateSplineTangent(in, s, *tangent);
          } else {
            for (int s : e.splines_used())
              if (s == sp.spline) {
                out->dp[k] += w * e.EvaluateSplineTangent(in, sp.spline, *Tangent(k, s));
                break;
              }
          }
        }
      }
      std::fill(dlambda_full.begin(), dlambda_full.end(), 0.0);
      bool any_lambda = false;
      for (int u : used) {
        const double c = coef[u];
        if (c == 0) continue;
        const mbs::Measure& me = model.measures[u];
        if (me.type == mbs::MeasureType::kReaction) {
          any_lambda = true;
          const int rc = reactions->Derivatives(u, x.t, x.q, lambda_full.data(), c, nullptr, out->dq,
                                                out->dlambda ? dlambda_full.data() : nullptr);
          if (rc != 0) {
            error = std::string("reaction measure '") + me.name + "': " + reactions->last_error();
            return rc;
          }
          continue;
        }
        const mbs::MeasureDef& def = defs[u];
        const bool need_h = me.quantity != mbs::Quantity::kPosition;
        mbs::MeasureJacobian j;
        mbs::EvaluateMeasurePosition(def, x.q, need_h, &j);
        if (me.quantity == mbs::Quantity::kPosition) {
          if (out->dq) Scatter(j.offset, j.gradient, c, out->dq);
        } else if (me.quantity == mbs::Quantity::kVelocity) {
          const Vec14 vl = mbs::GatherLocal(j.offset, x.v);
          if (out->dq) Scatter(j.offset, j.hessian * vl, c, out->dq);
          if (out->dv) Scatter(j.offset, j.gradient, c, out->dv);
        } else {
          const Vec14 vl = mbs::GatherLocal(j.offset, x.v);
          const Vec14 al = x.a ? mbs::GatherLocal(j.offset, x.a) : Vec14::Zero();
          if (out->da) Scatter(j.offset, j.gradient, c, out->da);
          if (out->dv) Scatter(j.offset, 2 * (j.hessian * vl), c, out->dv);
          if (out->dq) {
            Scatter(j.offset, j.hessian * al, c, out->dq);
            AccelerationQuadraticDq(def, x.q, vl, c, out->dq);
          }
        }
      }
      if (any_lambda && out->dlambda)
        for (size_t k = 0; k < kept.size(); ++k) out->dlambda[k] += dlambda_full[kept[k]];
    } catch (const std::exception& e) {
      error = e.what();
      return -1;
    }
    return 0;
  }
};

ModelObjectives::ModelObjectives(const mbs::Model& model, const mbs::MultibodySystem& system,
                                 std::vector<int> kept, std::vector<mbs::SensitivityParameter> parameters)
    : impl_(std::make_unique<Impl>(model, system, std::move(kept), std::move(parameters))) {}
ModelObjectives::~ModelObjectives() = default;

int ModelObjectives::num_objectives() const { return static_cast<int>(impl_->names.size()); }
const std::vector<std::string>& ModelObjectives::names() const { return impl_->names; }
bool ModelObjectives::has_integral(int i) const { return impl_->model.objectives.at(i).has_integral; }
bool ModelObjectives::has_terminal(int i) const { return impl_->model.objectives.at(i).has_terminal; }
bool ModelObjectives::depends_on_acceleration() const { return impl_->acceleration; }
bool ModelObjectives::depends_on_multipliers() const { return impl_->multipliers; }
const char* ModelObjectives::last_error() const { return impl_->error.c_str(); }
const ModelObjectives::AngleTrack& ModelObjectives::angle_track() const { return impl_->track; }
void ModelObjectives::set_angle_track(const AngleTrack& track) {
  if (track.angles.size() != impl_->angles.size() || track.rates.size() != impl_->angles.size())
    throw std::invalid_argument("ModelObjectives: angle track of another model (" +
                                std::to_string(track.angles.size()) + " angles, expected " +
                                std::to_string(impl_->angles.size()) + ")");
  impl_->track = track;
}

int ModelObjectives::Integrand(const ObjectivePoint& x, double* g) { return impl_->Values(false, x, g); }
int ModelObjectives::Terminal(const ObjectivePoint& x, double* phi) { return impl_->Values(true, x, phi); }
int ModelObjectives::IntegrandGradient(const ObjectivePoint& x, const double* weights,
                                       ObjectiveGradient* out) {
  return impl_->Gradient(false, x, weights, out);
}
int ModelObjectives::TerminalGradient(const ObjectivePoint& x, const double* weights,
                                      ObjectiveGradient* out) {
  return impl_->Gradient(true, x, weights, out);
}

}  // namespace mbdae::sens
