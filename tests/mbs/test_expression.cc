#include "mbs/expression.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <new>
#include <string>

// Counts heap allocations, to show that Evaluate makes none.
static int g_allocations = 0;
void* operator new(std::size_t size) {
  ++g_allocations;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

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

TEST(Expression, TimeMeasuresAndSplinesAreNotSupportedYet) {
  SymbolTable symbols;
  symbols.parameters = {"k"};
  symbols.reserved = {"x1"};
  std::string what;
  EXPECT_EQ(ErrorColumn("k*sin(2*pi*t)", &what, symbols), 12);
  EXPECT_NE(what.find("'t' at column 12 is not supported yet"), std::string::npos) << what;
  EXPECT_EQ(what.find("unknown"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("-k*x1", &what, symbols), 4);
  EXPECT_NE(what.find("measure 'x1' at column 4 is not supported yet"), std::string::npos) << what;
  EXPECT_EQ(ErrorColumn("spline(drive, 1)", &what, symbols), 1);
  EXPECT_NE(what.find("'spline' at column 1 is not supported yet"), std::string::npos) << what;
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
  const int before = g_allocations;
  double sum = 0;
  for (int k = 0; k < 100; ++k) sum += e.Evaluate(p);
  EXPECT_EQ(g_allocations, before);  // evaluation allocates nothing
  EXPECT_DOUBLE_EQ(sum, 100 * first);
  const Expression copy = e;
  EXPECT_EQ(copy.Evaluate(p), first);
}

}  // namespace
}  // namespace mbdae::mbs
