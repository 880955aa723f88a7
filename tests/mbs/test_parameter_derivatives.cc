// Exact parameter derivatives against central differences: splines' ordinate tangents,
// directional expression evaluation, the parameter chain, every parameter matrix of the
// multibody system (the model reloaded with --set overrides, or spline points changed)
// and the raw initial state; patterns fixed; refusals with their messages.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "mbs/expression.h"
#include "mbs/loader.h"
#include "mbs/sensitivity_parameters.h"
#include "mbs/spline.h"
#include "mbs/system.h"

namespace mbdae::mbs {
namespace {

// |a - b| <= tol * max(1, scale)
void ExpectClose(double exact, double fd, double scale, double tol, const std::string& what) {
  EXPECT_LE(std::abs(exact - fd), tol * std::max(1.0, scale)) << what << ": exact " << exact << " fd " << fd;
}

TEST(SplineTangent, MatchesCentralDifferencesForEveryKind) {
  const std::vector<double> x = {0, 0.4, 1.1, 1.5, 2.3, 3.0};
  const std::vector<double> y = {0.2, 1.0, -0.3, 0.7, 0.1, 0.9};
  for (Interpolation kind : {Interpolation::kLinear, Interpolation::kCubic, Interpolation::kAkima}) {
    const Spline s(x, y, kind);
    for (int i = 0; i < static_cast<int>(x.size()); ++i) {
      for (double at : {-0.5, 0.1, 0.4, 0.77, 1.3, 2.0, 2.9, 3.4}) {
        double e1, e2;
        const double e0 = s.OrdinateDerivative(at, i, &e1, &e2);
        const double h = 1e-6;
        std::vector<double> yp = y, ym = y;
        yp[i] += h;
        ym[i] -= h;
        const Spline sp(x, yp, kind), sm(x, ym, kind);
        double p1, p2, m1, m2;
        const double p0 = sp.Evaluate(at, &p1, &p2), m0 = sm.Evaluate(at, &m1, &m2);
        const std::string what = std::string(InterpolationName(kind)) + " point " + std::to_string(i) + " at " +
                                 std::to_string(at);
        ExpectClose(e0, (p0 - m0) / (2 * h), 1, 1e-8, what + " value");
        ExpectClose(e1, (p1 - m1) / (2 * h), 1, 1e-8, what + " d1");
        ExpectClose(e2, (p2 - m2) / (2 * h), 1, 1e-7, what + " d2");
      }
    }
  }
}

TEST(ExpressionDirectional, MatchesCentralDifferences) {
  Spline u({0, 0.5, 1.0, 2.0}, {0.0, 0.8, 0.3, 1.1}, Interpolation::kAkima);
  const Spline* splines[1] = {&u};
  SymbolTable sym;
  sym.parameters = {"a", "b"};
  sym.splines = {"u"};
  sym.allow_time = true;
  const std::vector<std::string> texts = {
      "a*sin(b*t) + t^2/a", "exp(-a*t)*cos(t) + sqrt(b + t)", "spline(u, a*t) * b",
      "atan2(a*t, 1 + b*t^2) + log(a + t)", "pow(a + t, b) + tanh(t*b)", "step(t, 0.1, a, 1.0, b)",
      "asin(0.3*a*t) + acos(0.1*b) + atan(t) + abs(t - a) + cosh(b*t)/sinh(1+t) + tan(0.2*t)",
      "min(a*t, b) + max(t, 0.2*a) + (a*t)^3 + spline(u, t)^2"};
  const double p[2] = {0.7, 1.3};
  const double dir[2] = {0.6, -0.4};  // direction in (a, b)
  for (const std::string& text : texts) {
    const Expression e = Expression::Parse(text, sym);
    std::vector<double> dy = {0.3, -1.0, 0.5, 2.0};
    const Spline tangent = u.Tangent(dy);
    const Spline* tangents[1] = {&tangent};
    for (double t : {0.35, 0.6, 1.2}) {
      ExpressionInputs in;
      in.t = t;
      in.parameters = p;
      in.splines = splines;
      ParameterDirection d;
      d.parameters = dir;
      d.spline_tangents = tangents;
      const DirectionalDerivatives r = e.EvaluateDirectional(in, d);
      double t1, t2;
      const double v = e.EvaluateTimeDerivatives(in, &t1, &t2);
      EXPECT_EQ(r.value, e.Evaluate(in)) << text;
      ExpectClose(r.d_t, t1, std::abs(t1), 1e-12, text + " d_t");
      ExpectClose(r.d_tt, t2, std::abs(t2), 1e-12, text + " d_tt");
      (void)v;
      // Along the direction: parameters and ordinates together.
      const double h = 1e-6;
      auto at = [&](double eps, double* f1, double* f2) {
        const double pp[2] = {p[0] + eps * dir[0], p[1] + eps * dir[1]};
        std::vector<double> yy = u.y();
        for (size_t i = 0; i < yy.size(); ++i) yy[i] += eps * dy[i];
        const Spline us(u.x(), yy, u.kind());
        const Spline* sp[1] = {&us};
        ExpressionInputs j = in;
        j.parameters = pp;
        j.splines = sp;
        return e.EvaluateTimeDerivatives(j, f1, f2);
      };
      double p1, p2, m1, m2;
      const double fp = at(h, &p1, &p2), fm = at(-h, &m1, &m2);
      ExpectClose(r.dir, (fp - fm) / (2 * h), std::abs(r.dir), 1e-7, text + " dir");
      ExpectClose(r.dir_t, (p1 - m1) / (2 * h), std::abs(r.dir_t), 1e-7, text + " dir_t");
      ExpectClose(r.dir_tt, (p2 - m2) / (2 * h), std::abs(r.dir_tt), 1e-6, text + " dir_tt");
    }
  }
  // EvaluateSplineOrdinateGradient, point by point.
  const Expression e = Expression::Parse("a*spline(u, b*t) + spline(u, t)^2", sym);
  ExpressionInputs in;
  in.t = 0.8;
  in.parameters = p;
  in.splines = splines;
  for (int i = 0; i < 4; ++i) {
    const double h = 1e-6;
    auto at = [&](double eps) {
      std::vector<double> yy = u.y();
      yy[i] += eps;
      const Spline us(u.x(), yy, u.kind());
      const Spline* sp[1] = {&us};
      ExpressionInputs j = in;
      j.splines = sp;
      return e.Evaluate(j);
    };
    ExpectClose(e.EvaluateSplineOrdinateGradient(in, 0, i), (at(h) - at(-h)) / (2 * h), 1, 1e-8,
                "ordinate " + std::to_string(i));
  }
  // Several splines in one expression: the ordinate gradient of the first one (a
  // regression: the tangent array was sized by the differentiated spline's index and
  // read past its end for the later ones, a crash in the robot example's objectives).
  {
    SymbolTable sym2;
    sym2.parameters = {"a", "b"};
    sym2.splines = {"u", "w", "z"};
    sym2.allow_time = true;
    const Spline w({0.0, 1.0, 2.0}, {1.0, -1.0, 0.5}, u.kind());
    const Spline z({0.0, 2.0}, {0.2, 0.4}, u.kind());
    const Spline* three[3] = {&u, &w, &z};
    const Expression e2 = Expression::Parse("spline(u, t)^2 + a*spline(w, t)^2 + spline(z, t)*spline(u, t)", sym2);
    ExpressionInputs in2 = in;
    in2.splines = three;
    for (int i = 0; i < 4; ++i) {
      const double h = 1e-6;
      auto at = [&](double eps) {
        std::vector<double> yy = u.y();
        yy[i] += eps;
        const Spline us(u.x(), yy, u.kind());
        const Spline* sp[3] = {&us, &w, &z};
        ExpressionInputs j = in2;
        j.splines = sp;
        return e2.Evaluate(j);
      };
      ExpectClose(e2.EvaluateSplineOrdinateGradient(in2, 0, i), (at(h) - at(-h)) / (2 * h), 1, 1e-8,
                  "three splines, ordinate " + std::to_string(i));
    }
  }
}

const char* kModel = R"Y(format: 1
parameters:
  k: 120
  c: 2.5
  L: 0.8
  m: 1.5
  m2: "2*m + 0.1"
  g: 9.81
  w: 1.3
  amp: 0.2
  pre: "k/100 + m2"
  fixed: "3*k"
splines:
  u1: {x: [0, 0.5, 1, 1.5, 2], y: [0, 1, "amp*3", 0.5, -0.2], interpolation: akima}
  u2: {x: [0, 1, 2, 3], y: [1, 2, 0, 1], interpolation: cubic}
  u3: {x: [0, 1, 2], y: [1, "fixed/100", 0], interpolation: linear}
gravity: [0, "-g", "0.01*m"]
bodies:
  - name: a
    mass: m
    inertia: ["0.4 + 0.1*m", "0.2*m2", 0.5, "0.01*k/100", 0, "0.001*w"]
    position: ["L", 0, "amp"]
    orientation: {axis: [0, "1 + amp", 1], angle: "0.3*w"}
    velocity: [0, "w*L", 0]
    angular_velocity: [0, "amp", w]
    markers: {p: {position: [0.1, 0.2, 0]}}
  - name: b
    mass: m2
    inertia: [0.2, 0.2, 0.3]
    position: [1.5, -0.5, 0.2]
    orientation: ["cos(amp)", "sin(amp)", 0, 0]
    angular_velocity: [0.1, "amp", 0.3]
measures:
  - {name: d, type: translational, i: a.p, j: b.cm, component: distance}
  - {name: vx, type: translational, i: a.cm, component: x, quantity: velocity}
  - {name: ang, type: rotational, i: b.cm, axis: z}
joints:
  - {name: drive, type: motion, measure: ang, value: "amp*sin(w*t) + 0.1*spline(u2, t*L)"}
  - {name: sph, type: spherical, i: a.p, j: b.cm}
forces:
  - {name: s, type: spring_damper, i: a.p, j: b.cm, stiffness: "k*(1 + 0.1*d)", damping: c, free_length: L, preload: pre}
  - {name: f, type: force, i: a.cm, frame: i, value: ["spline(u1, t)*k/100", "c*vx", "amp*t^2 + spline(u3, t)"]}
  - {name: tq, type: torque, i: b.cm, value: [0, "m2", "spline(u1, d)"]}
  - {name: bu, type: bushing, i: a.cm, j: ground.O, stiffness: [k, k, "2*k", 1, 1, "w"], damping: [c, c, c, 0.1, 0.1, 0.1]}
)Y";

// Dense copy of a sparse output.
std::vector<double> Dense(const dae::CscPattern& p, const std::vector<double>& val) {
  std::vector<double> d(static_cast<size_t>(p.rows) * p.cols, 0.0);
  for (int c = 0; c < p.cols; ++c)
    for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) d[static_cast<size_t>(c) * p.rows + p.row_index[k]] = val[k];
  return d;
}

struct Outputs {
  std::vector<double> Ma, Q, C, Cv, gamma;  // M a, Q, C, C_q v + C_t, gamma
  std::vector<double> q0, v0;
};

Outputs Evaluate(MultibodySystem& sys, double t, const std::vector<double>& q, const std::vector<double>& v,
                 const std::vector<double>& a) {
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  Outputs o;
  o.Q.assign(nq, 0);
  o.C.assign(nc, 0);
  o.gamma.assign(nc, 0);
  std::vector<double> ct(nc), M(sys.pattern(dae::Matrix::kMass).nnz()), Cq(sys.pattern(dae::Matrix::kConstraintDq).nnz());
  dae::EvalInput in;
  in.t = t;
  in.q = q.data();
  in.v = v.data();
  in.a = a.data();
  dae::EvalOutput out;
  out.force = o.Q.data();
  out.constraint = o.C.data();
  out.constraint_dt = ct.data();
  out.acc_rhs = o.gamma.data();
  out[dae::Matrix::kMass] = M.data();
  out[dae::Matrix::kConstraintDq] = Cq.data();
  EXPECT_EQ(sys.Evaluate(in, out), 0);
  o.Ma.assign(nq, 0);
  dae::MultiplyAdd(sys.pattern(dae::Matrix::kMass), M.data(), 1.0, a.data(), o.Ma.data());
  o.Cv = ct;
  dae::MultiplyAdd(sys.pattern(dae::Matrix::kConstraintDq), Cq.data(), 1.0, v.data(), o.Cv.data());
  sys.InitialState(o.q0, o.v0);
  return o;
}

// Checks every parameter matrix and the initial state derivatives of `names` against
// central differences of the reloaded model; returns the largest relative error seen.
double CheckModel(const std::string& text, const std::vector<std::string>& names, double tol) {
  const Model model = LoadModelFromString(text, "model.yaml");
  const std::vector<SensitivityParameter> sp = ResolveSensitivityParameters(model, names);
  MultibodySystem sys(model, sp, {});
  const int nq = sys.num_coordinates(), nc = sys.num_constraints(), np = sys.num_parameters();
  EXPECT_EQ(np, static_cast<int>(names.size()));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> q(nq), v(nq), a(nq);
  for (int b = 0; b < nq / 7; ++b) {
    for (int k = 0; k < 3; ++k) q[7 * b + k] = u(rng);
    double n = 0;
    for (int k = 0; k < 4; ++k) n += (q[7 * b + 3 + k] = u(rng)) * q[7 * b + 3 + k];
    for (int k = 0; k < 4; ++k) q[7 * b + 3 + k] /= std::sqrt(n);
  }
  for (double& x : v) x = u(rng);
  for (double& x : a) x = u(rng);
  const double t = 0.37;
  // Exact, twice (the second call must give the same pattern and values).
  std::vector<std::vector<double>> dense(dae::kNumParameterMatrices);
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<std::vector<double>> vals(dae::kNumParameterMatrices);
    dae::EvalInput in;
    in.t = t;
    in.q = q.data();
    in.v = v.data();
    in.a = a.data();
    dae::EvalOutput out;
    for (int m = 0; m < dae::kNumParameterMatrices; ++m) {
      const dae::CscPattern& p = sys.parameter_pattern(static_cast<dae::ParameterMatrix>(m));
      std::string err;
      EXPECT_TRUE(p.IsValid(&err)) << err;
      EXPECT_EQ(p.cols, np);
      vals[m].assign(p.nnz(), 0.0);
      out.parameter_matrix[m] = vals[m].data();
    }
    EXPECT_EQ(sys.Evaluate(in, out), 0);
    for (int m = 0; m < dae::kNumParameterMatrices; ++m) {
      const auto d = Dense(sys.parameter_pattern(static_cast<dae::ParameterMatrix>(m)), vals[m]);
      if (pass == 1) EXPECT_EQ(d, dense[m]) << "matrix " << m << " changed between calls";
      dense[m] = d;
    }
  }
  std::vector<double> dq0, dv0;
  sys.InitialStateParameterDerivatives(dq0, dv0);
  double worst = 0;
  for (int k = 0; k < np; ++k) {
    Model mp, mm;
    double h;
    if (sp[k].parameter >= 0) {
      const double p0 = model.parameters[sp[k].parameter].value;
      h = 1e-5 * (1 + std::abs(p0));
      LoadOptions op, om;
      op.parameter_overrides[names[k]] = p0 + h;
      om.parameter_overrides[names[k]] = p0 - h;
      mp = LoadModelFromString(text, "model.yaml", op);
      mm = LoadModelFromString(text, "model.yaml", om);
    } else {
      mp = LoadModelFromString(text, "model.yaml");
      mm = LoadModelFromString(text, "model.yaml");
      Spline& s1 = mp.splines[sp[k].spline].spline;
      Spline& s2 = mm.splines[sp[k].spline].spline;
      const double y0 = s1.y()[sp[k].point];
      h = 1e-5 * (1 + std::abs(y0));
      std::vector<double> y1 = s1.y(), y2 = s2.y();
      y1[sp[k].point] += h;
      y2[sp[k].point] -= h;
      s1.SetPoints(s1.x(), y1);
      s2.SetPoints(s2.x(), y2);
    }
    MultibodySystem sp_sys(mp), sm_sys(mm);
    const Outputs op = Evaluate(sp_sys, t, q, v, a), om = Evaluate(sm_sys, t, q, v, a);
    auto check = [&](const std::vector<double>& plus, const std::vector<double>& minus, const std::vector<double>& exact,
                     int rows, const std::string& what) {
      double scale = 0;
      for (int r = 0; r < rows; ++r) scale = std::max({scale, std::abs(plus[r]), std::abs(exact[static_cast<size_t>(k) * rows + r])});
      for (int r = 0; r < rows; ++r) {
        const double fd = (plus[r] - minus[r]) / (2 * h);
        const double ex = exact[static_cast<size_t>(k) * rows + r];
        worst = std::max(worst, std::abs(ex - fd) / std::max(1.0, scale));
        ExpectClose(ex, fd, scale, tol, what + " row " + std::to_string(r) + " wrt " + names[k]);
      }
    };
    using PM = dae::ParameterMatrix;
    check(op.Ma, om.Ma, dense[static_cast<int>(PM::kMassTimesAccDp)], nq, "d(M a)/dp");
    check(op.Q, om.Q, dense[static_cast<int>(PM::kForceDp)], nq, "dQ/dp");
    check(op.C, om.C, dense[static_cast<int>(PM::kConstraintDp)], nc, "dC/dp");
    check(op.Cv, om.Cv, dense[static_cast<int>(PM::kConstraintVelDp)], nc, "d(C_q v + C_t)/dp");
    check(op.gamma, om.gamma, dense[static_cast<int>(PM::kAccRhsDp)], nc, "dgamma/dp");
    std::vector<double> zero(static_cast<size_t>(nq) * np, 0.0);
    for (int r = 0; r < nq; ++r) EXPECT_EQ(dense[static_cast<int>(PM::kConstraintTDp)].size(), zero.size());
    check(op.q0, om.q0, dq0, nq, "dq0/dp");
    check(op.v0, om.v0, dv0, nq, "dv0/dp");
  }
  return worst;
}

TEST(SystemParameterDerivatives, HandWrittenModelEveryDependency) {
  const Model model = LoadModelFromString(kModel, "model.yaml");
  std::vector<std::string> names;
  for (const SensitivityParameter& p : AllSensitivityParameters(model, true)) names.push_back(p.name);
  EXPECT_EQ(names.size(), 10u + 5u + 4u + 3u);
  const double worst = CheckModel(kModel, names, 1e-7);
  std::printf("largest relative difference to central differences: %.3g\n", worst);
}

TEST(SystemParameterDerivatives, RandomModels) {
  std::mt19937 rng(2024);
  std::uniform_real_distribution<double> u(0.2, 2.0);
  const char* laws[] = {"k*(1 + d)", "c + k*t", "k*sin(c*t) + d", "exp(-c*t)*k"};
  for (int trial = 0; trial < 6; ++trial) {
    char text[4096];
    std::snprintf(text, sizeof(text), R"Y(format: 1
parameters: {k: %.6g, c: %.6g, m: %.6g, r: "%.3g*k + c"}
gravity: [0, 0, "-9.81*m"]
bodies:
  - {name: a, mass: "m*%.3g", inertia: ["m + c", "r + c", "r + m"], position: [%.3g, "c", 0], velocity: ["r", 0, 1], angular_velocity: ["k", "m", 0]}
  - {name: b, mass: "r", inertia: ["1 + r", "1 + r", 2], position: [0, 1, "%.3g*k"], orientation: {axis: ["c", 1, "m"], angle: "r"}}
measures:
  - {name: d, type: translational, i: a.cm, j: b.cm, component: %s}
joints:
  - {name: j1, type: motion, measure: d, value: "c*t + r*sin(t*k)"}
forces:
  - {name: s, type: spring_damper, i: a.cm, j: b.cm, stiffness: "%s", damping: "c*m", free_length: "r", preload: "k*c"}
  - {name: f, type: %s, i: b.cm, frame: %s, value: ["k*d", "r", "m*t"]}
)Y",
                  u(rng), u(rng), u(rng), u(rng), u(rng), u(rng), u(rng), u(rng),
                  trial % 2 ? "distance" : "x", laws[trial % 4], trial % 3 ? "force" : "torque",
                  trial % 2 ? "world" : "i");
    CheckModel(text, {"k", "c", "m", "r"}, 1e-7);
  }
}

// A chain of n bodies, each with its own parameters (mass, inertia, spring stiffness and
// damping, a load, a torque gain) and a torque over a shared spline: many parameters,
// each reaching one or two elements.
std::string ManyLocalParametersModel(int n) {
  std::string t = "format: 1\nparameters:\n";
  for (int i = 0; i < n; ++i) {
    const std::string s = std::to_string(i), x = std::to_string(1 + 0.1 * i);
    t += "  m_" + s + ": " + x + "\n  J_" + s + ": " + std::to_string(0.1 + 0.01 * i) + "\n  k_" + s + ": " +
         std::to_string(50 + 3 * i) + "\n  c_" + s + ": " + std::to_string(0.5 + 0.05 * i) + "\n  f_" + s + ": " +
         std::to_string(0.2 * (i + 1)) + "\n  g_" + s + ": " + std::to_string(1 + 0.3 * i) + "\n";
  }
  t += "splines:\n  u: {x: [0, 0.3, 0.6, 1.0, 1.5], y: [0, 0.5, -0.2, 0.4, 0.1], interpolation: akima}\n";
  t += "bodies:\n";
  for (int i = 0; i < n; ++i) {
    const std::string s = std::to_string(i);
    t += "  - {name: b" + s + ", mass: m_" + s + ", inertia: [J_" + s + ", \"2*J_" + s + "\", 0.3], position: [" +
         std::to_string(0.5 * i) + ", 0, 0]}\n";
  }
  t += "measures:\n  - {name: ang, type: rotational, i: b0.cm, axis: z}\n";
  t += "joints:\n  - {name: drive, type: motion, measure: ang, value: \"0.1*sin(t) + 0.05*spline(u, t)\"}\n";
  t += "forces:\n";
  for (int i = 0; i < n; ++i) {
    const std::string s = std::to_string(i), prev = i == 0 ? "ground.O" : "b" + std::to_string(i - 1) + ".cm";
    t += "  - {name: s" + s + ", type: spring_damper, i: b" + s + ".cm, j: " + prev + ", stiffness: k_" + s +
         ", damping: c_" + s + ", free_length: 0.4}\n";
    t += "  - {name: f" + s + ", type: force, i: b" + s + ".cm, frame: world, value: [f_" + s + ", 0, 0]}\n";
    t += "  - {name: t" + s + ", type: torque, i: b" + s + ".cm, value: [0, 0, \"g_" + s + "*spline(u, t)\"]}\n";
  }
  return t;
}

// One parameter p reaching almost everything through a chain of dependent parameters
// (a, b, c computed from p): masses, inertias, gravity, spring laws, force values, a
// spline ordinate, bushing stiffness and damping, a motion.
const char* kChainModel = R"Y(format: 1
parameters:
  p: 1.2
  a: "2*p + 1"
  b: "a*a/10"
  c: "sin(p) + b"
  other: 0.7
splines:
  u: {x: [0, 0.5, 1, 1.5], y: [0.1, c, -0.3, "other"], interpolation: cubic}
gravity: [0, "-9 - 0.1*a", "0.01*c"]
bodies:
  - {name: b0, mass: "1 + 0.1*b", inertia: ["a/10", "c/10", 0.3, 0.01, "0.001*p", 0], position: [0, 0, 0]}
  - {name: b1, mass: "2 + 0.1*c", inertia: ["a/10", 0.3, "b/10"], position: [0.6, 0, 0]}
  - {name: b2, mass: "1 + p*p", inertia: [0.2, 0.2, 0.3], position: [1.2, 0.1, 0]}
  - {name: b3, mass: other, inertia: [0.5, "other", 0.3], position: [1.8, 0, 0.2]}
measures:
  - {name: ang, type: rotational, i: b0.cm, axis: z}
  - {name: d, type: translational, i: b1.cm, j: b2.cm, component: distance}
joints:
  - {name: drive, type: motion, measure: ang, value: "0.1*c*sin(a*t) + 0.01*spline(u, t)"}
forces:
  - {name: s01, type: spring_damper, i: b0.cm, j: b1.cm, stiffness: "10*a", damping: b, free_length: "0.5 + 0.01*c", preload: p}
  - {name: s12, type: spring_damper, i: b1.cm, j: b2.cm, stiffness: "20 + b*d", damping: 0.3, free_length: 0.6}
  - {name: s23, type: spring_damper, i: b2.cm, j: b3.cm, stiffness: 30, damping: other, free_length: 0.6}
  - {name: f, type: force, i: b2.cm, frame: i, value: ["spline(u, t)*b", "c*t", 0]}
  - {name: tq, type: torque, i: b3.cm, value: [0, "other*d", "p*spline(u, d)"]}
  - {name: bu, type: bushing, i: b1.cm, j: ground.O, stiffness: [a, a, b, 1, 1, c], damping: ["p*p", 0.1, 0.1, 0.1, 0.1, b]}
)Y";

TEST(SystemParameterDerivatives, ManyParametersEachReachingFewElements) {
  const std::string text = ManyLocalParametersModel(6);
  const Model model = LoadModelFromString(text, "model.yaml");
  std::vector<std::string> names;
  for (const SensitivityParameter& p : AllSensitivityParameters(model, true)) names.push_back(p.name);
  EXPECT_EQ(names.size(), 6u * 6u + 5u);
  const double worst = CheckModel(text, names, 1e-7);
  std::printf("largest relative difference to central differences: %.3g\n", worst);
}

TEST(SystemParameterDerivatives, OneParameterReachingManyElementsThroughDependentParameters) {
  // p alone (a, b, c follow it), p with a (a then independent: p reaches less), and all
  // with the ordinates.
  CheckModel(kChainModel, {"p"}, 1e-7);
  CheckModel(kChainModel, {"a", "p"}, 1e-7);
  const Model model = LoadModelFromString(kChainModel, "model.yaml");
  std::vector<std::string> names;
  for (const SensitivityParameter& p : AllSensitivityParameters(model, true)) names.push_back(p.name);
  const double worst = CheckModel(kChainModel, names, 1e-7);
  std::printf("largest relative difference to central differences: %.3g\n", worst);
}

// Every parameter matrix with all of them requested, and with the regular outputs.
struct ParameterValues {
  std::vector<std::vector<double>> pm;
  std::vector<double> force, mass;
};
ParameterValues EvaluateParameterMatrices(MultibodySystem& sys, const std::vector<bool>& which, bool regular,
                                          double t, const std::vector<double>& q, const std::vector<double>& v,
                                          const std::vector<double>& a, const std::vector<double>& w) {
  ParameterValues r;
  r.pm.resize(dae::kNumParameterMatrices);
  dae::EvalInput in;
  in.t = t;
  in.q = q.data();
  in.v = v.data();
  in.a = a.data();
  in.w = w.data();
  dae::EvalOutput out;
  for (int m = 0; m < dae::kNumParameterMatrices; ++m) {
    if (!which[m]) continue;
    // Filled with garbage: every entry must be written.
    r.pm[m].assign(sys.parameter_pattern(static_cast<dae::ParameterMatrix>(m)).nnz(), 123.0);
    out.parameter_matrix[m] = r.pm[m].data();
  }
  if (regular) {
    r.force.assign(sys.num_coordinates(), 0.0);
    r.mass.assign(sys.pattern(dae::Matrix::kMass).nnz(), 0.0);
    out.force = r.force.data();
    out[dae::Matrix::kMass] = r.mass.data();
  }
  EXPECT_EQ(sys.Evaluate(in, out), 0) << sys.last_error();
  return r;
}

// A random state (positions, unit Euler parameters, rates, accelerations, weights).
void RandomState(const MultibodySystem& sys, unsigned seed, std::vector<double>* q, std::vector<double>* v,
                 std::vector<double>* a, std::vector<double>* w) {
  const int nq = sys.num_coordinates();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  q->assign(nq, 0.0);
  v->assign(nq, 0.0);
  a->assign(nq, 0.0);
  w->assign(sys.num_constraints(), 0.0);
  for (int b = 0; b < nq / 7; ++b) {
    for (int k = 0; k < 3; ++k) (*q)[7 * b + k] = u(rng);
    double n = 0;
    for (int k = 0; k < 4; ++k) n += ((*q)[7 * b + 3 + k] = u(rng)) * (*q)[7 * b + 3 + k];
    for (int k = 0; k < 4; ++k) (*q)[7 * b + 3 + k] /= std::sqrt(n);
  }
  for (double& x : *v) x = u(rng);
  for (double& x : *a) x = u(rng);
  for (double& x : *w) x = u(rng);
}

// Reported: an Evaluate requesting one parameter matrix crashed (the adds of the matrices
// not requested were written through a null pointer). Any subset must give the values of
// the call with all of them, bit for bit, with or without the regular outputs, and in any
// order of calls.
TEST(SystemParameterDerivatives, AnySubsetOfParameterMatricesEqualsAllOfThem) {
  const std::vector<std::string> texts = {kModel, kChainModel, ManyLocalParametersModel(4)};
  for (const std::string& text : texts) {
    const Model model = LoadModelFromString(text, "model.yaml");
    MultibodySystem sys(model, AllSensitivityParameters(model, true), {});
    std::vector<double> q, v, a, w;
    RandomState(sys, 11, &q, &v, &a, &w);
    const double t = 0.41;
    const std::vector<bool> all(dae::kNumParameterMatrices, true), none(dae::kNumParameterMatrices, false);
    const ParameterValues ref = EvaluateParameterMatrices(sys, all, true, t, q, v, a, w);
    int nonzero = 0;
    for (const auto& m : ref.pm)
      for (double x : m) nonzero += x != 0;
    EXPECT_GT(nonzero, 10);
    // Every subset (2^6), with and without the regular outputs.
    for (int subset = 0; subset < (1 << dae::kNumParameterMatrices); ++subset) {
      std::vector<bool> which(dae::kNumParameterMatrices);
      for (int m = 0; m < dae::kNumParameterMatrices; ++m) which[m] = (subset >> m) & 1;
      for (bool regular : {false, true}) {
        const ParameterValues r = EvaluateParameterMatrices(sys, which, regular, t, q, v, a, w);
        for (int m = 0; m < dae::kNumParameterMatrices; ++m)
          if (which[m]) EXPECT_EQ(r.pm[m], ref.pm[m]) << "matrix " << m << " in subset " << subset;
        if (regular) {
          EXPECT_EQ(r.force, ref.force) << "subset " << subset;
          EXPECT_EQ(r.mass, ref.mass) << "subset " << subset;
        }
      }
    }
    // Each matrix alone at another state, then all: the same values (nothing left over).
    std::vector<double> q2, v2, a2, w2;
    RandomState(sys, 12, &q2, &v2, &a2, &w2);
    std::vector<std::vector<double>> alone(dae::kNumParameterMatrices);
    for (int m = 0; m < dae::kNumParameterMatrices; ++m) {
      std::vector<bool> which(dae::kNumParameterMatrices, false);
      which[m] = true;
      alone[m] = EvaluateParameterMatrices(sys, which, false, 0.9, q2, v2, a2, w2).pm[m];
    }
    const ParameterValues ref2 = EvaluateParameterMatrices(sys, all, false, 0.9, q2, v2, a2, w2);
    for (int m = 0; m < dae::kNumParameterMatrices; ++m) EXPECT_EQ(alone[m], ref2.pm[m]) << "matrix " << m;
    EvaluateParameterMatrices(sys, none, true, t, q, v, a, w);
  }
}

// The parameter-only derivatives are cached and the spline tangents kept between calls:
// after the parameter values or a spline's points change, the values are those of a
// system built with the new ones.
TEST(SystemParameterDerivatives, NewParameterValuesAndSplinePointsAreUsed) {
  Model model = LoadModelFromString(kChainModel, "model.yaml");
  const std::vector<SensitivityParameter> sp = AllSensitivityParameters(model, true);
  MultibodySystem sys(model, sp, {});
  std::vector<double> q, v, a, w;
  RandomState(sys, 5, &q, &v, &a, &w);
  const std::vector<bool> all(dae::kNumParameterMatrices, true);
  const ParameterValues before = EvaluateParameterMatrices(sys, all, true, 0.3, q, v, a, w);
  // New values of p and of the parameters computed from it (the mass of b2 and a bushing
  // damping are nonlinear in p: their derivatives change), and new ordinates of u.
  auto index = [&](const std::string& name) {
    for (size_t j = 0; j < model.parameters.size(); ++j)
      if (model.parameters[j].name == name) return j;
    ADD_FAILURE() << name;
    return size_t{0};
  };
  std::vector<double> values = sys.parameters();
  const double p = 1.5, a_ = 2 * p + 1, b = a_ * a_ / 10;
  values[index("p")] = p;
  values[index("a")] = a_;
  values[index("b")] = b;
  values[index("c")] = std::sin(p) + b;
  sys.parameters() = values;
  Spline& u = model.splines[0].spline;
  std::vector<double> y = u.y();
  y[0] = 0.4;
  y[2] = -0.1;
  u.SetPoints(u.x(), y);
  const ParameterValues after = EvaluateParameterMatrices(sys, all, true, 0.3, q, v, a, w);
  MultibodySystem fresh(model, sp, values);
  const ParameterValues expected = EvaluateParameterMatrices(fresh, all, true, 0.3, q, v, a, w);
  for (int m = 0; m < dae::kNumParameterMatrices; ++m) EXPECT_EQ(after.pm[m], expected.pm[m]) << "matrix " << m;
  EXPECT_NE(after.pm, before.pm);
}

TEST(SensitivityParameters, ChainThroughDependentParametersAndOverrides) {
  const char* text = "format: 1\nparameters: {a: 2, b: \"a^2\", c: \"3*b + a\", d: \"b\"}\n";
  const Model m = LoadModelFromString(text, "m.yaml");
  auto chain = ParameterChain(m, ResolveSensitivityParameters(m, {"a", "b"}));
  EXPECT_DOUBLE_EQ(chain[0][0], 1);
  EXPECT_DOUBLE_EQ(chain[0][1], 4);       // db/da = 2a
  EXPECT_DOUBLE_EQ(chain[0][2], 13);      // 3*4 + 1
  EXPECT_DOUBLE_EQ(chain[0][3], 4);
  EXPECT_DOUBLE_EQ(chain[1][0], 0);       // b independent: a does not depend on it
  EXPECT_DOUBLE_EQ(chain[1][2], 3);
  LoadOptions o;
  o.parameter_overrides["b"] = 5;         // fixed number
  const Model mo = LoadModelFromString(text, "m.yaml", o);
  chain = ParameterChain(mo, ResolveSensitivityParameters(mo, {"a"}));
  EXPECT_DOUBLE_EQ(chain[0][1], 0);
  EXPECT_DOUBLE_EQ(chain[0][2], 1);
}

TEST(SensitivityParameters, ResolveErrors) {
  const Model m = LoadModelFromString(
      "format: 1\nparameters: {stiff: 1, damp: 2}\nsplines: {u1: {x: [0, 1, 2], y: [0, 1, 0]}}\n", "m.yaml");
  auto message = [&](const std::vector<std::string>& names) {
    try {
      ResolveSensitivityParameters(m, names);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message({"stif"}).find("unknown sensitivity parameter 'stif' (did you mean 'stiff'?)"), std::string::npos)
      << message({"stif"});
  EXPECT_NE(message({"u1[x]"}).find("malformed spline ordinate 'u1[x]'"), std::string::npos);
  EXPECT_NE(message({"u1[-1]"}).find("malformed"), std::string::npos);
  EXPECT_NE(message({"u1[3]"}).find("point index 3 out of range: spline 'u1' has 3 points"), std::string::npos)
      << message({"u1[3]"});
  EXPECT_NE(message({"u2[0]"}).find("unknown spline 'u2' (did you mean 'u1'?)"), std::string::npos) << message({"u2[0]"});
  EXPECT_NE(message({"u1"}).find("'u1' is a spline"), std::string::npos);
  const auto ok = ResolveSensitivityParameters(m, {"damp", "u1[2]"});
  EXPECT_EQ(ok[0].parameter, 1);
  EXPECT_EQ(ok[1].spline, 0);
  EXPECT_EQ(ok[1].point, 2);
  EXPECT_EQ(AllSensitivityParameters(m, false).size(), 2u);
  EXPECT_EQ(AllSensitivityParameters(m, true).size(), 5u);
}

std::string Refusal(const std::string& text, const std::string& name) {
  const Model m = LoadModelFromString(text, "refuse.yaml");
  try {
    MultibodySystem sys(m, ResolveSensitivityParameters(m, {name}), {});
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no error";
}

TEST(SystemParameterDerivatives, RefusesUnsupportedLoadTimeUses) {
  const std::string head = "format: 1\nparameters: {p: 0.5, q: \"2*p\", k: 3}\n";
  const std::string body = "bodies:\n  - name: a\n    mass: 1\n    inertia: [1, 1, 1]\n";
  struct Case { std::string text, expect; };
  const std::vector<Case> cases = {
      {head + body + "    markers: {m: {position: [q, 0, 0]}}\n",
       "sensitivity parameter 'p': body 'a', marker 'm' 'position' (refuse.yaml:7) is computed from it at load time"},
      {head + body + "    orientation: {matrix: [[1, 0, 0], [0, \"cos(p-p)\", 0], [0, 0, 1]]}\n",
       "body 'a' 'orientation matrix row' (refuse.yaml:"},
      {head + "bodies:\n  - name: a\n    geometry: {shape: sphere, radius: q, density: 1}\n",
       "body 'a' 'geometry radius' (refuse.yaml:5)"},
      {head + "splines: {u: {x: [0, q, 2], y: [0, 1, 0]}}\n", "spline 'u' 'x[1]' (refuse.yaml:3)"},
      {head + "simulation: {t_end: q}\n", "'t_end' (refuse.yaml:3)"},
      {head + body + "  - {name: b, mass: 1, inertia: [1, 1, 1]}\nmeasures:\n"
                     "  - {name: t1, type: rotational, i: a.cm, axis: z}\n  - {name: t2, type: rotational, i: b.cm, axis: z}\n"
                     "joints:\n  - {name: g, type: gear, measures: [t1, t2], ratio: q}\n",
       "joint 'g' 'ratio' (refuse.yaml:"},
      {head + body + "    position: [p, 0, 0]\n  - {name: b, mass: 1, inertia: [1, 1, 1]}\nmeasures:\n"
                     "  - {name: t1, type: rotational, i: a.cm, axis: z}\n  - {name: t2, type: rotational, i: b.cm, axis: z}\n"
                     "joints:\n  - {name: g, type: gear, measures: [t1, t2], ratio: 2}\n",
       "gear joint 'g' (refuse.yaml:"},
      {head + body + "    position: [p, 0, 0]\nmeasures:\n  - {name: x, type: translational, i: a.cm, component: x, offset_initial: true}\n"
                     "forces:\n  - {name: f, type: force, i: a.cm, value: [x, 0, 0]}\n",
       "force 'f' (refuse.yaml:11) uses measure 'x' with offset_initial"},
  };
  for (const Case& c : cases) {
    const std::string msg = Refusal(c.text, "p");
    EXPECT_NE(msg.find(c.expect), std::string::npos) << "got: " << msg << "\nexpected: " << c.expect;
    EXPECT_NE(msg.find("sensitivity parameter 'p'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("not supported"), std::string::npos) << msg;
    // A parameter the refused value does not use is accepted.
    EXPECT_EQ(Refusal(c.text, "k"), "no error") << c.text;
  }
}

}  // namespace
}  // namespace mbdae::mbs
