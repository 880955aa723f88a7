#include "mbs/expression.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <new>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "mbs/spline.h"

#include "tests/support/count_allocations.h"

namespace mbdae::mbs {
namespace {

double Eval(const std::string& text) { return Expression::Parse(text, {}).Evaluate(nullptr); }

// Column of the ExpressionError thrown by parsing `text`, and its message in *what.
int ErrorColumn(const std::string& text, std::string* what, const SymbolTable& symbols = {}) {
  try {
    Expression::Parse(text, symbols);
  } catch (const ExpressionError& e) {
    *what = e.what();
    return e.column();
  }
  *what = "(no error)";
  return 0;
}

TEST(Expression, NumbersAndPrecedence) {
  EXPECT_EQ(Eval("42"), 42.0);
  EXPECT_EQ(Eval("1.5e3"), 1500.0);
  EXPECT_EQ(Eval("2.5E-2"), 0.025);
  EXPECT_EQ(Eval(".5"), 0.5);
  EXPECT_EQ(Eval("1 + 2 * 3"), 7.0);
  EXPECT_EQ(Eval("(1 + 2) * 3"), 9.0);
  EXPECT_EQ(Eval("10 - 4 - 3"), 3.0);   // left-associative
  EXPECT_EQ(Eval("8 / 4 / 2"), 1.0);    // left-associative
  EXPECT_EQ(Eval("2 ^ 3 ^ 2"), 512.0);  // right-associative
  EXPECT_EQ(Eval("-2 ^ 2"), -4.0);      // ^ binds tighter than unary minus
  EXPECT_EQ(Eval("2 ^ -1"), 0.5);
  EXPECT_EQ(Eval("--3"), 3.0);
  EXPECT_EQ(Eval("-3 * -2"), 6.0);
  EXPECT_EQ(Eval("+4"), 4.0);
  EXPECT_EQ(Eval("2 * 3 ^ 2"), 18.0);
  EXPECT_DOUBLE_EQ(Eval("pi"), M_PI);
  EXPECT_DOUBLE_EQ(Eval("2*pi/4"), M_PI / 2);
}

TEST(Expression, Functions) {
  const double x = 0.3;
  EXPECT_DOUBLE_EQ(Eval("sin(0.3)"), std::sin(x));
  EXPECT_DOUBLE_EQ(Eval("cos(0.3)"), std::cos(x));
  EXPECT_DOUBLE_EQ(Eval("tan(0.3)"), std::tan(x));
  EXPECT_DOUBLE_EQ(Eval("asin(0.3)"), std::asin(x));
  EXPECT_DOUBLE_EQ(Eval("acos(0.3)"), std::acos(x));
  EXPECT_DOUBLE_EQ(Eval("atan(0.3)"), std::atan(x));
  EXPECT_DOUBLE_EQ(Eval("sinh(0.3)"), std::sinh(x));
  EXPECT_DOUBLE_EQ(Eval("cosh(0.3)"), std::cosh(x));
  EXPECT_DOUBLE_EQ(Eval("tanh(0.3)"), std::tanh(x));
  EXPECT_DOUBLE_EQ(Eval("exp(0.3)"), std::exp(x));
  EXPECT_DOUBLE_EQ(Eval("log(0.3)"), std::log(x));
  EXPECT_DOUBLE_EQ(Eval("sqrt(0.3)"), std::sqrt(x));
  EXPECT_EQ(Eval("abs(-0.3)"), 0.3);
  EXPECT_EQ(Eval("sign(-0.3)"), -1.0);
  EXPECT_EQ(Eval("sign(0)"), 0.0);
  EXPECT_EQ(Eval("sign(2)"), 1.0);
  EXPECT_DOUBLE_EQ(Eval("atan2(1, -1)"), 3 * M_PI / 4);
  EXPECT_EQ(Eval("min(2, -3)"), -3.0);
  EXPECT_EQ(Eval("max(2, -3)"), 2.0);
  EXPECT_EQ(Eval("pow(2, 10)"), 1024.0);
  EXPECT_DOUBLE_EQ(Eval("sqrt(sin(0.3)^2 + cos(0.3)^2)"), 1.0);
}

TEST(Expression, SmoothStep) {
  // h0 = 1 below x0 = 2, h1 = 5 above x1 = 4; between h0 + (h1 - h0) s^2 (3 - 2 s).
  EXPECT_EQ(Eval("step(0, 2, 1, 4, 5)"), 1.0);
  EXPECT_EQ(Eval("step(2, 2, 1, 4, 5)"), 1.0);
  EXPECT_EQ(Eval("step(4, 2, 1, 4, 5)"), 5.0);
  EXPECT_EQ(Eval("step(9, 2, 1, 4, 5)"), 5.0);
  EXPECT_DOUBLE_EQ(Eval("step(3, 2, 1, 4, 5)"), 3.0);  // midpoint: s = 1/2 -> half way
  const double s = 0.25;                                // x = 2.5
  EXPECT_DOUBLE_EQ(Eval("step(2.5, 2, 1, 4, 5)"), 1 + 4 * s * s * (3 - 2 * s));
  // Continuous first derivative at the ends: the slope just inside is ~0.
  const double h = 1e-6;
  EXPECT_NEAR((Eval("step(2.000001, 2, 1, 4, 5)") - 1.0) / h, 0.0, 1e-4);
  EXPECT_NEAR((5.0 - Eval("step(3.999999, 2, 1, 4, 5)")) / h, 0.0, 1e-4);
}

TEST(Expression, Parameters) {
  SymbolTable symbols;
  symbols.parameters = {"k", "l_0", "m2"};
  const Expression e = Expression::Parse("k * (l_0 - 0.5) ^ 2 + m2", symbols);
  const double p[] = {4.0, 1.5, 0.25};
  EXPECT_DOUBLE_EQ(e.Evaluate(p), 4.0 * 1.0 + 0.25);
  EXPECT_FALSE(e.is_constant());
  EXPECT_EQ(e.parameters_used(), (std::vector<int>{0, 1, 2}));
  const double q[] = {1.0, 3.5, -1.0};
  EXPECT_DOUBLE_EQ(e.Evaluate(q), 9.0 - 1.0);  // evaluated from the vector, every call
  EXPECT_EQ(e.text(), "k * (l_0 - 0.5) ^ 2 + m2");

  const Expression twice = Expression::Parse("k + k*k", symbols);
  EXPECT_EQ(twice.parameters_used(), std::vector<int>{0});

  EXPECT_TRUE(Expression::Parse("2*pi", symbols).is_constant());
  EXPECT_EQ(Expression().Evaluate(nullptr), 0.0);
  EXPECT_TRUE(Expression().is_constant());
  EXPECT_EQ(Expression::Constant(-2.5).Evaluate(nullptr), -2.5);
}

TEST(Expression, ErrorsCarryColumns) {
  SymbolTable symbols;
  symbols.parameters = {"k"};
  symbols.reserved = {"x1"};
  std::string what;
  EXPECT_EQ(ErrorColumn("k * foo", &what, symbols), 5);
  EXPECT_NE(what.find("unknown name 'foo'"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("1 + * 2", &what), 5);
  EXPECT_NE(what.find("expected a number"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("(1 + 2", &what), 7);
  EXPECT_NE(what.find("expected ')'"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("1 + 2)", &what), 6);
  EXPECT_NE(what.find("unexpected ')'"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("sin(1, 2)", &what), 1);
  EXPECT_NE(what.find("sin() takes 1 argument, got 2"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("2 + step(1, 2, 3)", &what), 5);
  EXPECT_NE(what.find("step() takes 5 arguments, got 3"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("foo(1)", &what), 1);
  EXPECT_NE(what.find("unknown function 'foo'"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("1e+", &what), 1);
  EXPECT_NE(what.find("malformed number"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("2k", &what, symbols), 1);
  EXPECT_EQ(ErrorColumn("", &what), 1);
  EXPECT_NE(what.find("empty"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("1 # 2", &what), 3);
  EXPECT_EQ(ErrorColumn("sin", &what), 1);
  EXPECT_NE(what.find("needs arguments"), std::string::npos) << what;
}

TEST(Expression, TimeMeasuresAndSplinesRefusedWhereNotAllowed) {
  SymbolTable symbols;
  symbols.parameters = {"k"};
  symbols.reserved = {"x1"};
  symbols.splines = {"drive"};
  std::string what;
  EXPECT_EQ(ErrorColumn("k*sin(2*pi*t)", &what, symbols), 12);
  EXPECT_NE(what.find("'t' at column 12 cannot be used here: this value is evaluated once at load time"),
            std::string::npos)
      << what;
  EXPECT_EQ(what.find("unknown"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("-k*x1", &what, symbols), 4);
  EXPECT_NE(what.find("measure 'x1' at column 4 cannot be used here: this value is evaluated once at load time"),
            std::string::npos)
      << what;
  EXPECT_EQ(ErrorColumn("1 + spline(drive, 1)", &what, symbols), 5);
  EXPECT_NE(what.find("spline() at column 5 cannot be used here"), std::string::npos) << what;
  // Where t is allowed but measures are not (a motion value).
  symbols.allow_time = true;
  EXPECT_EQ(ErrorColumn("t*x1", &what, symbols), 3);
  EXPECT_NE(what.find("measure 'x1' at column 3 cannot be used here: this value may depend on time only"),
            std::string::npos)
      << what;
}

TEST(Expression, DepthIsBoundedAtParseTime) {
  std::string deep;
  for (int k = 0; k < 100; ++k) deep += "(1+";
  deep += "1";
  for (int k = 0; k < 100; ++k) deep += ")";
  std::string what;
  EXPECT_GT(ErrorColumn(deep, &what), 0);
  EXPECT_NE(what.find("nested too deeply"), std::string::npos) << what;
  std::string minus(200, '-');
  EXPECT_GT(ErrorColumn(minus + "1", &what), 0);
  // Moderate nesting is fine and evaluates right: 30 nested (1+...) = 31.
  std::string ok;
  for (int k = 0; k < 30; ++k) ok += "(1+";
  ok += "1";
  for (int k = 0; k < 30; ++k) ok += ")";
  EXPECT_EQ(Eval(ok), 31.0);
}

TEST(Expression, EvaluateIsRepeatableAndConst) {
  SymbolTable symbols;
  symbols.parameters = {"a", "b"};
  const Expression e = Expression::Parse("step(a, 0, 0, 1, b) + max(a, b)^2", symbols);
  const double p[] = {0.5, 2.0};
  const double first = e.Evaluate(p);
  EXPECT_DOUBLE_EQ(first, 1.0 + 4.0);
  EXPECT_EQ(e.Evaluate(p), first);  // nothing left over from the first call
  const long before = g_allocations;
  double sum = 0;
  for (int k = 0; k < 100; ++k) sum += e.Evaluate(p);
  EXPECT_EQ(g_allocations, before);  // evaluation allocates nothing
  EXPECT_DOUBLE_EQ(sum, 100 * first);
  const Expression copy = e;
  EXPECT_EQ(copy.Evaluate(p), first);
}

// ---------------------------------------------------------------------------------------
// Derivatives against finite differences.

// Fourth-order central difference (Richardson extrapolation of two central differences):
// error O(h^4 f^(5)) + O(eps |f| / h).
template <class F>
double Fd(const F& f, double x, double h) {
  return (8 * (f(x + h) - f(x - h)) - (f(x + 2 * h) - f(x - 2 * h))) / (12 * h);
}

constexpr double kFdStep = 1e-3;
constexpr double kFdTol = 1e-7;     // relative to max(1, |derivative|)
constexpr double kKinkGap = 1e-2;   // points closer than this to a non-smooth place are skipped

bool Close(double exact, double fd) {
  return std::abs(exact - fd) <= kFdTol * std::max(1.0, std::abs(exact));
}

// The derivative tests' symbols: t, measures x and y, parameters p and q, spline s.
SymbolTable TestSymbols() {
  SymbolTable symbols;
  symbols.parameters = {"p", "q"};
  symbols.measures = {"x", "y"};
  symbols.splines = {"s"};
  symbols.allow_time = true;
  return symbols;
}

// The spline of the tests: natural cubic through sin-like data on knots -2, -1.5, ..., 3.
Spline TestSpline() {
  std::vector<double> x, y;
  for (int k = 0; k <= 10; ++k) {
    x.push_back(-2 + 0.5 * k);
    y.push_back(std::sin(1.1 * x.back()) + 0.1 * x.back() * x.back());
  }
  return Spline(x, y, Interpolation::kCubic);
}

double KnotGap(double a) { return std::abs(a - 0.5 * std::round(a / 0.5)); }

// One test expression per function and operator. 'X' and 'Y' stand for the measures x and
// y in the gradient test and for functions of t in the time-derivative test; both range
// over [-1, 1], t over [0, 1], p and q over [0.5, 1.5]. `gap` is the distance of the
// point to the nearest non-smooth place of the expression (null: smooth on the domain).
struct Case {
  const char* text;
  double (*gap)(double t, double X, double Y, double p, double q);
};

const Case kCases[] = {
    {"sin(X*p + t)", nullptr},
    {"cos(X - p*t) * q", nullptr},
    {"tan(0.5*X + 0.3*t*p)", nullptr},
    {"asin(0.4*X + 0.3*t*p)", nullptr},
    {"acos(0.4*X - 0.3*t*p)", nullptr},
    {"atan(3*X + t*p)", nullptr},
    {"sinh(X + t*p)", nullptr},
    {"cosh(X - t*p + q)", nullptr},
    {"tanh(2*X + t - p)", nullptr},
    {"exp(X*t + p)", nullptr},
    {"log(2 + X + t*p)", nullptr},
    {"sqrt(2 + X*p + t)", nullptr},
    {"abs(X - t*p) + Y", [](double t, double X, double, double p, double) { return std::abs(X - t * p); }},
    {"sign(X - t*p + 0.2) * (X + Y*q)",
     [](double t, double X, double, double p, double) { return std::abs(X - t * p + 0.2); }},
    {"min(X*q, t*p - 0.5)",
     [](double t, double X, double, double p, double q) { return std::abs(X * q - (t * p - 0.5)); }},
    {"max(X*p, t - Y)", [](double t, double X, double Y, double p, double) { return std::abs(X * p - t + Y); }},
    {"pow(1.5 + X, p*t + Y)", nullptr},
    {"(2 + X*q)^(p - t)", nullptr},
    {"2^(X*t) + pow(p, q)*X", nullptr},
    {"X^3*p - Y^2 + (t + p)^-2 + X^4", nullptr},
    {"(X + 1.5)^1.5 * q - pow(Y + 2, 0.5)", nullptr},
    {"atan2(X, t - p + Y)",
     [](double t, double X, double Y, double p, double) {
       const double u = t - p + Y;
       return u < 0 ? std::abs(X) : std::hypot(X, u);
     }},
    {"atan2(Y + 2, X*p)", nullptr},
    {"step(X, -0.5*p, t, 0.5*q, p*t - Y)",
     [](double, double X, double, double p, double q) {
       return std::min(std::abs(X + 0.5 * p), std::abs(X - 0.5 * q));
     }},
    {"-p*X - q*Y + 3*sin(2*pi*0.5*t)", nullptr},
    {"p*X*Y - Y/p + t*t/(X + 2) - -q", nullptr},
    {"X/(Y + 1.5) - 1/(t + p)", nullptr},
    {"spline(s, X*p + t) * q", [](double t, double X, double, double p, double) { return KnotGap(X * p + t); }},
};

std::string Substitute(std::string text, const std::string& x, const std::string& y) {
  std::string out;
  for (char c : text) {
    if (c == 'X') {
      out += x;
    } else if (c == 'Y') {
      out += y;
    } else {
      out += c;
    }
  }
  return out;
}

// Which gradient entry holds d/d(argument); nullptr when the expression does not use it.
const double* Entry(const Expression& e, const ExpressionGradient& g, char argument) {
  auto find = [](const std::vector<int>& used, int index) {
    return static_cast<int>(std::find(used.begin(), used.end(), index) - used.begin());
  };
  switch (argument) {
    case 't': return e.uses_time() ? &g.d_t : nullptr;
    case 'x':
    case 'y': {
      const int k = find(e.measures_used(), argument == 'x' ? 0 : 1);
      return k < static_cast<int>(e.measures_used().size()) ? &g.d_measures[k] : nullptr;
    }
    default: {
      const int k = find(e.parameters_used(), argument == 'p' ? 0 : 1);
      return k < static_cast<int>(e.parameters_used().size()) ? &g.d_parameters[k] : nullptr;
    }
  }
}

TEST(ExpressionDerivatives, GradientMatchesFiniteDifferencesForEveryFunction) {
  const Spline spline = TestSpline();
  const Spline* splines[] = {&spline};
  const SymbolTable symbols = TestSymbols();
  std::mt19937 rng(20240611);
  std::uniform_real_distribution<double> unit(0, 1), sym(-1, 1), par(0.5, 1.5);
  double worst = 0;
  std::string worst_case;
  for (const Case& c : kCases) {
    const Expression e = Expression::Parse(Substitute(c.text, "x", "y"), symbols);
    int checked = 0;
    for (int trial = 0; trial < 25; ++trial) {
      // args = t, x, y, p, q
      double args[5] = {unit(rng), sym(rng), sym(rng), par(rng), par(rng)};
      if (c.gap != nullptr && c.gap(args[0], args[1], args[2], args[3], args[4]) < kKinkGap) continue;
      ++checked;
      auto value = [&](const double* a) {
        const double measures[] = {a[1], a[2]};
        const double parameters[] = {a[3], a[4]};
        ExpressionInputs in{a[0], parameters, measures, splines};
        return e.Evaluate(in);
      };
      const double measures[] = {args[1], args[2]};
      const double parameters[] = {args[3], args[4]};
      ExpressionGradient g;
      const double v = e.EvaluateGradient(ExpressionInputs{args[0], parameters, measures, splines}, &g);
      ASSERT_EQ(v, value(args)) << c.text;  // the same arithmetic as Evaluate
      const char names[] = "txypq";
      for (int k = 0; k < 5; ++k) {
        const double* entry = Entry(e, g, names[k]);
        const double exact = entry == nullptr ? 0.0 : *entry;
        const double fd = Fd(
            [&](double a) {
              double b[5];
              std::copy(args, args + 5, b);
              b[k] = a;
              return value(b);
            },
            args[k], kFdStep);
        const double err = std::abs(exact - fd) / std::max(1.0, std::abs(exact));
        if (err > worst) worst = err, worst_case = c.text;
        EXPECT_TRUE(Close(exact, fd)) << c.text << ": d/d" << names[k] << " = " << exact << ", FD " << fd
                                      << " at t=" << args[0] << " x=" << args[1] << " y=" << args[2]
                                      << " p=" << args[3] << " q=" << args[4];
      }
    }
    EXPECT_GE(checked, 15) << c.text << ": too few points away from the non-smooth places";
  }
  std::cout << "largest relative FD difference: " << worst << " (" << worst_case << ")\n";
}

TEST(ExpressionDerivatives, TimeDerivativesMatchFiniteDifferencesForEveryFunction) {
  const Spline spline = TestSpline();
  const Spline* splines[] = {&spline};
  const SymbolTable symbols = TestSymbols();
  // X(t) and Y(t) in [-1, 1].
  auto X = [](double t) { return 0.9 * std::sin(1.3 * t + 0.2); };
  auto Y = [](double t) { return 0.7 * std::cos(0.9 * t); };
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0, 1), par(0.5, 1.5);
  double worst1 = 0, worst2 = 0;
  for (const Case& c : kCases) {
    const Expression e =
        Expression::Parse(Substitute(c.text, "(0.9*sin(1.3*t + 0.2))", "(0.7*cos(0.9*t))"), symbols);
    ASSERT_FALSE(e.depends_on_state()) << c.text;
    int checked = 0;
    for (int trial = 0; trial < 25; ++trial) {
      const double t = unit(rng);
      const double parameters[] = {par(rng), par(rng)};
      // Non-smooth places: the gap over the whole FD stencil in t (|dX/dt|, |dY/dt| < 1.2).
      if (c.gap != nullptr && c.gap(t, X(t), Y(t), parameters[0], parameters[1]) < 3 * kKinkGap) continue;
      ++checked;
      auto in = [&](double time) { return ExpressionInputs{time, parameters, nullptr, splines}; };
      double d1 = 0, d2 = 0;
      const double v = e.EvaluateTimeDerivatives(in(t), &d1, &d2);
      ASSERT_EQ(v, e.Evaluate(in(t))) << c.text;
      const double fd1 = Fd([&](double a) { return e.Evaluate(in(a)); }, t, kFdStep);
      const double fd2 = Fd(
          [&](double a) {
            double first = 0;
            e.EvaluateTimeDerivatives(in(a), &first, nullptr);
            return first;
          },
          t, kFdStep);
      worst1 = std::max(worst1, std::abs(d1 - fd1) / std::max(1.0, std::abs(d1)));
      worst2 = std::max(worst2, std::abs(d2 - fd2) / std::max(1.0, std::abs(d2)));
      EXPECT_TRUE(Close(d1, fd1)) << c.text << ": d/dt = " << d1 << ", FD " << fd1 << " at t=" << t;
      EXPECT_TRUE(Close(d2, fd2)) << c.text << ": d2/dt2 = " << d2 << ", FD of d/dt " << fd2 << " at t=" << t;
      // The gradient evaluator's d/dt is the same derivative by another route.
      ExpressionGradient g;
      e.EvaluateGradient(in(t), &g);
      EXPECT_NEAR(g.d_t, d1, 1e-12 * std::max(1.0, std::abs(d1))) << c.text;
    }
    EXPECT_GE(checked, 15) << c.text;
  }
  std::cout << "largest relative FD difference: d/dt " << worst1 << ", d2/dt2 " << worst2 << "\n";
}

// ---------------------------------------------------------------------------------------
// Exact values and the conventions at non-smooth points (docs/expressions.md).

struct Point {
  double t = 0, x = 0, y = 0, p = 0, q = 0;
};

double Grad(const std::string& text, const Point& at, ExpressionGradient* g, Expression* out = nullptr) {
  const Expression e = Expression::Parse(text, TestSymbols());
  const double measures[] = {at.x, at.y};
  const double parameters[] = {at.p, at.q};
  if (out != nullptr) *out = e;
  return e.EvaluateGradient(ExpressionInputs{at.t, parameters, measures, nullptr}, g);
}

TEST(ExpressionDerivatives, ConventionsAtNonSmoothPoints) {
  ExpressionGradient g;
  Point at;
  at.x = 0;
  EXPECT_EQ(Grad("abs(x)", at, &g), 0.0);
  EXPECT_EQ(g.d_measures[0], 0.0);  // abs' = sign = 0 at 0
  EXPECT_EQ(Grad("sign(x)", at, &g), 0.0);
  EXPECT_EQ(g.d_measures[0], 0.0);
  at.x = at.y = 1;
  EXPECT_EQ(Grad("min(x, y)", at, &g), 1.0);  // ties: the first argument
  EXPECT_EQ(g.d_measures[0], 1.0);
  EXPECT_EQ(g.d_measures[1], 0.0);
  EXPECT_EQ(Grad("max(y, 2*x - 1)", at, &g), 1.0);
  EXPECT_EQ(g.d_measures[0], 1.0);  // measures_used = {y, x}: y first
  EXPECT_EQ(g.d_measures[1], 0.0);
  // step at its lower end: the constant branch (d/dh0 = 1); its slope is 0 from both sides.
  at.x = 0.5;
  at.p = 0.5;
  at.q = 3;
  EXPECT_EQ(Grad("step(x, p, q, 2, 7)", at, &g), 3.0);
  EXPECT_EQ(g.d_measures[0], 0.0);
  EXPECT_EQ(g.d_parameters[0], 0.0);
  EXPECT_EQ(g.d_parameters[1], 1.0);
  at.x = 2;
  EXPECT_EQ(Grad("step(x, p, q, 2, 7)", at, &g), 7.0);
  EXPECT_EQ(g.d_parameters[1], 0.0);
  // atan2 at the origin: value 0, derivatives 0.
  at.x = at.y = 0;
  EXPECT_EQ(Grad("atan2(y, x)", at, &g), 0.0);
  EXPECT_EQ(g.d_measures[0], 0.0);
  EXPECT_EQ(g.d_measures[1], 0.0);
}

TEST(ExpressionDerivatives, PowersOfNegativeAndZeroBases) {
  ExpressionGradient g;
  Point at;
  at.x = -2;
  EXPECT_EQ(Grad("x^3", at, &g), -8.0);
  EXPECT_EQ(g.d_measures[0], 12.0);
  EXPECT_EQ(Grad("pow(x, -2)", at, &g), 0.25);
  EXPECT_EQ(g.d_measures[0], 0.25);  // -2 x^-3
  at.x = 0;
  EXPECT_EQ(Grad("x^2", at, &g), 0.0);
  EXPECT_EQ(g.d_measures[0], 0.0);
  EXPECT_EQ(Grad("x^0", at, &g), 1.0);
  EXPECT_EQ(g.d_measures[0], 0.0);
  EXPECT_EQ(Grad("x^1", at, &g), 0.0);
  EXPECT_EQ(g.d_measures[0], 1.0);
  EXPECT_TRUE(std::isinf(Grad("x^0.5", at, &g) + g.d_measures[0]));  // sqrt-like at 0: infinite slope
  // An exponent that is a parameter: d/dx by the power rule at a negative base; d/dq is
  // not defined there (NaN) and does not spill into the other derivatives.
  at.x = -2;
  at.q = 2;
  at.t = 0.5;
  EXPECT_EQ(Grad("x^q + t", at, &g), 4.5);
  EXPECT_EQ(g.d_t, 1.0);
  EXPECT_EQ(g.d_measures[0], -4.0);
  EXPECT_TRUE(std::isnan(g.d_parameters[0]));
  // Base exactly zero, exponent varying: the exponent's part is its limit 0.
  at.x = 0;
  at.q = 2.5;
  EXPECT_EQ(Grad("x^q", at, &g), 0.0);
  EXPECT_EQ(g.d_measures[0], 0.0);
  EXPECT_EQ(g.d_parameters[0], 0.0);
  // A value that does not depend on t gives exactly 0 for d/dt even where f' is infinite.
  at.p = 0;
  at.t = 0.25;
  EXPECT_EQ(Grad("sqrt(p) + t", at, &g), 0.25);
  EXPECT_EQ(g.d_t, 1.0);
  EXPECT_TRUE(std::isinf(g.d_parameters[0]));
}

TEST(ExpressionDerivatives, TimeDerivativesExactValues) {
  SymbolTable symbols = TestSymbols();
  const double parameters[] = {2.0, 3.0};
  ExpressionInputs in{1.0, parameters, nullptr, nullptr};
  double d1 = 0, d2 = 0;
  // (t - 3)^3 at t = 1: -8, 3 (t-3)^2 = 12, 6 (t-3) = -12 (negative base, literal exponent).
  EXPECT_EQ(Expression::Parse("(t - 3)^3", symbols).EvaluateTimeDerivatives(in, &d1, &d2), -8.0);
  EXPECT_EQ(d1, 12.0);
  EXPECT_EQ(d2, -12.0);
  // (t - 3)^q with the parameter q = 3: the same (the exponent is constant in t).
  EXPECT_EQ(Expression::Parse("(t - 3)^q", symbols).EvaluateTimeDerivatives(in, &d1, &d2), -8.0);
  EXPECT_EQ(d1, 12.0);
  EXPECT_EQ(d2, -12.0);
  // p*t^2 + q: 2*1 + 3 = 5, 2 p t = 4, 2 p = 4.
  EXPECT_EQ(Expression::Parse("p*t^2 + q", symbols).EvaluateTimeDerivatives(in, &d1, &d2), 5.0);
  EXPECT_EQ(d1, 4.0);
  EXPECT_EQ(d2, 4.0);
  // Parameters only: derivatives 0; null outputs are allowed.
  EXPECT_EQ(Expression::Parse("p*q", symbols).EvaluateTimeDerivatives(in, &d1, nullptr), 6.0);
  EXPECT_EQ(d1, 0.0);
  EXPECT_EQ(Expression().EvaluateTimeDerivatives(in, nullptr, &d2), 0.0);
  EXPECT_EQ(d2, 0.0);
  // A state-dependent expression has no time derivatives of its own.
  const Expression state = Expression::Parse("x + t", symbols);
  EXPECT_TRUE(state.depends_on_state());
  EXPECT_THROW(state.EvaluateTimeDerivatives(in, &d1, &d2), std::logic_error);
}

TEST(Expression, Queries) {
  SymbolTable symbols = TestSymbols();
  const Expression e = Expression::Parse("q*x + sin(t) + spline(s, y) + p*y + x", symbols);
  EXPECT_TRUE(e.uses_time());
  EXPECT_TRUE(e.depends_on_state());
  EXPECT_FALSE(e.is_constant());
  EXPECT_EQ(e.measures_used(), (std::vector<int>{0, 1}));
  EXPECT_EQ(e.parameters_used(), (std::vector<int>{1, 0}));
  EXPECT_EQ(e.splines_used(), std::vector<int>{0});
  EXPECT_EQ(e.num_arguments(), 5);
  const Spline spline = TestSpline();
  const Spline* splines[] = {&spline};
  const double measures[] = {0.5, -0.25};
  const double parameters[] = {2.0, 3.0};
  ExpressionGradient g;
  const double v = e.EvaluateGradient(ExpressionInputs{0.3, parameters, measures, splines}, &g);
  double s1 = 0;
  const double s = spline.Evaluate(-0.25, &s1);
  EXPECT_DOUBLE_EQ(v, 3 * 0.5 + std::sin(0.3) + s + 2 * -0.25 + 0.5);
  EXPECT_DOUBLE_EQ(g.d_t, std::cos(0.3));
  EXPECT_EQ(g.d_measures[0], 3.0 + 1.0);  // x
  EXPECT_DOUBLE_EQ(g.d_measures[1], s1 + 2.0);  // y
  EXPECT_EQ(g.d_parameters[0], 0.5);      // q
  EXPECT_EQ(g.d_parameters[1], -0.25);    // p

  const Expression motion = Expression::Parse("p*sin(t)", symbols);
  EXPECT_TRUE(motion.uses_time());
  EXPECT_FALSE(motion.depends_on_state());
  EXPECT_EQ(motion.num_arguments(), 2);
  const Expression folded = Expression::Parse("sin(2*pi*0.25) + 3^2", symbols);
  EXPECT_TRUE(folded.is_constant());
  EXPECT_EQ(folded.num_arguments(), 0);
  EXPECT_EQ(folded.Evaluate(nullptr), std::sin(2 * M_PI * 0.25) + 9.0);  // folding is the same arithmetic
}

TEST(Expression, SplineIsNeverFoldedAndFollowsItsPoints) {
  SymbolTable symbols = TestSymbols();
  const Expression e = Expression::Parse("2*spline(s, 1)", symbols);
  EXPECT_FALSE(e.is_constant());
  EXPECT_EQ(e.splines_used(), std::vector<int>{0});
  Spline spline({0, 1, 2}, {0, 5, 0}, Interpolation::kLinear);
  const Spline* splines[] = {&spline};
  ExpressionInputs in;
  in.splines = splines;
  EXPECT_EQ(e.Evaluate(in), 10.0);
  spline.SetPoints({0, 1, 2}, {0, -1, 0});
  EXPECT_EQ(e.Evaluate(in), -2.0);
  // Linear spline in t: first derivative the slope, second 0.
  const Expression m = Expression::Parse("spline(s, 0.5*t)", symbols);
  double d1 = 0, d2 = 1;
  in.t = 1.0;  // spline at 0.5: slope -1
  EXPECT_EQ(m.EvaluateTimeDerivatives(in, &d1, &d2), -0.5);
  EXPECT_EQ(d1, -0.5);
  EXPECT_EQ(d2, 0.0);
}

TEST(Expression, ArgumentErrorsCarryColumns) {
  SymbolTable symbols = TestSymbols();
  std::string what;
  EXPECT_EQ(ErrorColumn("t + spline(foo, t)", &what, symbols), 12);
  EXPECT_NE(what.find("unknown spline 'foo' at column 12"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("spline(1, t)", &what, symbols), 8);
  EXPECT_NE(what.find("needs a spline name"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("spline(s t)", &what, symbols), 10);
  EXPECT_NE(what.find("expected ','"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("spline(s, t, 2)", &what, symbols), 12);
  EXPECT_NE(what.find("expected ')'"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("2*spline", &what, symbols), 3);
  EXPECT_NE(what.find("needs arguments"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("x + z", &what, symbols), 5);
  EXPECT_NE(what.find("unknown name 'z'"), std::string::npos) << what;

  // At most kMaxExpressionArguments distinct arguments: the 33rd is refused where it appears.
  SymbolTable many;
  std::string text;
  for (int i = 0; i <= kMaxExpressionArguments; ++i) {
    many.parameters.push_back("p" + std::to_string(i));
    if (i < kMaxExpressionArguments) text += (i ? "+" : "") + many.parameters.back();
  }
  const Expression full = Expression::Parse(text + "+p0*p31", many);
  EXPECT_EQ(full.num_arguments(), kMaxExpressionArguments);
  std::vector<double> values(kMaxExpressionArguments + 1, 1.0);
  ExpressionGradient g;
  EXPECT_EQ(full.EvaluateGradient(ExpressionInputs{0, values.data(), nullptr, nullptr}, &g), 33.0);
  EXPECT_EQ(g.d_parameters[0], 2.0);
  EXPECT_EQ(g.d_parameters[15], 1.0);
  EXPECT_EQ(g.d_parameters[31], 2.0);
  const int column = static_cast<int>(text.size()) + 2;
  EXPECT_EQ(ErrorColumn(text + "+p32", &what, many), column);
  EXPECT_NE(what.find("too many distinct arguments"), std::string::npos) << what;
}

// ---------------------------------------------------------------------------------------
// No allocation per evaluation; several threads on one Expression.

TEST(Expression, EvaluationsDoNotAllocate) {
  const SymbolTable symbols = TestSymbols();
  const Expression force = Expression::Parse(
      "-p*x - q*y + 3*sin(2*pi*0.5*t) + step(x, -1, 0, 1, p)^2 + spline(s, y) + atan2(x, y + 2)", symbols);
  const Expression motion = Expression::Parse("p*sin(t)^3 + spline(s, 0.5*t) + pow(t + 1, q)", symbols);
  const Expression constant = Expression::Parse("p*q^2 + 1", symbols);  // the load-time call below
  const Spline spline = TestSpline();
  const Spline* splines[] = {&spline};
  const double measures[] = {0.3, -0.2};
  const double parameters[] = {1.5, 0.7};
  ExpressionInputs in{0.4, parameters, measures, splines};
  ExpressionGradient g;
  double sum = 0, d1 = 0, d2 = 0;
  const long before = g_allocations;
  for (int k = 0; k < 100; ++k) {
    in.t = 0.01 * k;
    sum += force.Evaluate(in) + force.EvaluateGradient(in, &g) + g.d_measures[1];
    sum += motion.EvaluateTimeDerivatives(in, &d1, &d2) + d1 + d2 + constant.Evaluate(parameters);
  }
  EXPECT_EQ(g_allocations - before, 0);
  EXPECT_TRUE(std::isfinite(sum));
  // The counter works: parsing allocates.
  Expression::Parse("p + q", symbols);
  EXPECT_GT(g_allocations - before, 0);
}

TEST(Expression, TwoThreadsEvaluateOneExpression) {
  const SymbolTable symbols = TestSymbols();
  const Expression e = Expression::Parse("-p*x - q*y^2 + exp(-t)*sin(x*y + t) + max(x, y)", symbols);
  const double parameters[] = {1.5, 0.7};
  auto work = [&](int start, std::vector<double>* out) {
    for (int k = 0; k < 2000; ++k) {
      const int i = (start + k) % 2000;
      const double measures[] = {std::sin(0.01 * i), std::cos(0.013 * i)};
      ExpressionGradient g;
      const double v = e.EvaluateGradient(ExpressionInputs{0.001 * i, parameters, measures, nullptr}, &g);
      (*out)[i] = v + 3 * g.d_t + 5 * g.d_measures[0] + 7 * g.d_measures[1] + 11 * g.d_parameters[1];
    }
  };
  std::vector<double> serial(2000), a(2000), b(2000);
  work(0, &serial);
  std::thread ta(work, 0, &a), tb(work, 1000, &b);
  ta.join();
  tb.join();
  EXPECT_EQ(a, serial);
  EXPECT_EQ(b, serial);
}

}  // namespace
}  // namespace mbdae::mbs
