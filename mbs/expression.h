// Scalar expressions of the model file: numbers, `pi`, parameter names, the time `t`,
// measure names, `spline(NAME, x)`, + - * / ^, unary minus, parentheses and the functions
// of the model format. Parsed once into a compact postfix program (literal
// subexpressions folded); evaluation does no string work and no allocation.
//
// Three evaluations of the same program:
//   Evaluate                 the value;
//   EvaluateGradient         the value and its exact first derivatives with respect to t,
//                            every measure and every parameter the expression uses
//                            (forward-mode dual numbers, at most kMaxExpressionArguments
//                            distinct arguments, checked at parse time);
//   EvaluateTimeDerivatives  the value and its exact first and second derivatives with
//                            respect to t (second-order Taylor arithmetic), for
//                            expressions that do not depend on the state.
// All three are const and keep no scratch in the object: one Expression may be evaluated
// from several threads at once. The derivative conventions at non-smooth points (abs,
// sign, min, max, step, pow) are in docs/expressions.md.
#pragma once

#include <array>
#include <cstddef>
#include <exception>
#include <string>
#include <vector>

namespace mbdae::mbs {

class Spline;  // mbs/spline.h

// Largest number of distinct arguments (t, measures, parameters together) of one
// expression; Parse rejects more.
constexpr int kMaxExpressionArguments = 32;

// Names an expression may refer to, by index.
struct SymbolTable {
  std::vector<std::string> parameters;  // index i -> ExpressionInputs::parameters[i]
  // Names that exist in the model but may not be used here (typically measures in a
  // load-time value or a motion): using them gives "cannot be used here" instead of
  // "unknown name". (Second, so that SymbolTable{parameters, reserved} keeps its meaning.)
  std::vector<std::string> reserved;
  // State-dependent arguments: index k -> ExpressionInputs::measures[k].
  std::vector<std::string> measures;
  // Names usable as the first argument of spline(NAME, x): index k ->
  // ExpressionInputs::splines[k]. spline() itself is usable only where allow_time is true
  // (values evaluated during the run).
  std::vector<std::string> splines;
  // Whether `t` (and spline()) may be used. When false, `t` gives "'t' at column N cannot
  // be used here: this value is evaluated once at load time".
  bool allow_time = false;
};

// The values an expression is evaluated at. Arrays are indexed as in the SymbolTable the
// expression was parsed with; an array the expression does not use may be null.
struct ExpressionInputs {
  double t = 0;
  const double* parameters = nullptr;
  const double* measures = nullptr;
  const Spline* const* splines = nullptr;
};

// First derivatives of an expression's value. Entries beyond the counts of
// measures_used() / parameters_used() are left as they were.
struct ExpressionGradient {
  double d_t = 0;  // d/dt (0 when the expression does not use t)
  // d_measures[k] = d/d(measure measures_used()[k])
  std::array<double, kMaxExpressionArguments> d_measures;
  // d_parameters[k] = d/d(parameter parameters_used()[k])
  std::array<double, kMaxExpressionArguments> d_parameters;
};

// A direction in the parameters and spline ordinates, for EvaluateDirectional: the
// derivative of every parameter value (by SymbolTable parameter index; null: all zero)
// and, per spline (by SymbolTable spline index; null array or entry: zero), the tangent
// of its ordinates (Spline::Tangent).
struct ParameterDirection {
  const double* parameters = nullptr;
  const Spline* const* spline_tangents = nullptr;
};

// The value, its first and second partial derivatives in t (measures held fixed), and
// the derivatives of these three along a ParameterDirection.
struct DirectionalDerivatives {
  double value = 0, d_t = 0, d_tt = 0;
  double dir = 0, dir_t = 0, dir_tt = 0;
};

class ExpressionError : public std::exception {
 public:
  ExpressionError(std::string message, int column) : message_(std::move(message)), column_(column) {}
  const char* what() const noexcept override { return message_.c_str(); }
  int column() const { return column_; }  // 1-based column in the expression text
 private:
  std::string message_;
  int column_;
};

class Expression {
 public:
  Expression() = default;                       // the constant 0
  static Expression Constant(double value);
  // Throws ExpressionError on a syntax error, an unknown name, a name not usable here,
  // or more than kMaxExpressionArguments distinct arguments; the message names the column.
  static Expression Parse(const std::string& text, const SymbolTable& symbols);

  // The value over the parameters alone (t = 0); for expressions without measures and
  // splines, e.g. load-time values and force constants.
  double Evaluate(const double* parameters) const;
  double Evaluate(const ExpressionInputs& in) const;
  // Value, and *g (see ExpressionGradient).
  double EvaluateGradient(const ExpressionInputs& in, ExpressionGradient* g) const;
  // Value, *d1 = d/dt and *d2 = d2/dt2 (either may be null), with the parameters held
  // constant. Throws std::logic_error when the expression depends on the state
  // (depends_on_state()); in.measures is not read.
  double EvaluateTimeDerivatives(const ExpressionInputs& in, double* d1, double* d2) const;

  // Value, d/dt, d2/dt2 and their exact derivatives along `dir` (Taylor arithmetic in
  // two variables, second order in t and first order in the direction), at fixed
  // measures; for parameter derivatives of motions and force values. Same derivative
  // conventions as EvaluateTimeDerivatives at non-smooth points.
  DirectionalDerivatives EvaluateDirectional(const ExpressionInputs& in,
                                             const ParameterDirection& dir) const;
  // d(value)/d(ordinate `point` of spline `spline`) (SymbolTable spline index), exact, at
  // fixed t, measures and parameters; 0 when the expression does not call that spline.
  // Allocates (it builds the ordinate's tangent spline).
  double EvaluateSplineOrdinateGradient(const ExpressionInputs& in, int spline, int point) const;
  // The same along a prepared tangent (Spline::Tangent of the ordinate direction) of
  // spline `spline`: no allocation, for callers that evaluate it at many points.
  double EvaluateSplineTangent(const ExpressionInputs& in, int spline, const Spline& tangent) const;

  bool is_constant() const;       // refers to no parameter, no measure and not to t
  bool uses_time() const { return uses_time_; }
  bool depends_on_state() const { return !measures_used_.empty(); }
  // Indices (into the SymbolTable's lists) in the order of first use.
  const std::vector<int>& parameters_used() const { return parameters_used_; }
  const std::vector<int>& measures_used() const { return measures_used_; }
  const std::vector<int>& splines_used() const { return splines_used_; }
  // Distinct arguments: (uses_time() ? 1 : 0) + measures_used().size() + parameters_used().size().
  int num_arguments() const { return num_slots_; }
  const std::string& text() const { return text_; }

 private:
  friend class ExpressionParser;
  struct Op {
    int code;
    int index;     // parameter, measure or spline index (leaves, spline())
    int slot;      // derivative slot of a leaf: t first, then measures, then parameters
    double value;  // literal, or the exponent of a power with a literal exponent
  };
  // The value stack machine over ops[0, count).
  static double Run(const Op* ops, size_t count, const ExpressionInputs& in);
  std::vector<Op> program_;
  std::vector<int> parameters_used_;
  std::vector<int> measures_used_;
  std::vector<int> splines_used_;
  std::string text_;
  bool uses_time_ = false;
  int num_slots_ = 0;
  int max_stack_ = 1;
};

}  // namespace mbdae::mbs
