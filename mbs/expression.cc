// Expression parser and evaluators: recursive descent into a postfix program, then three
// stack machines over it (values, values with first derivatives, second-order Taylor
// series in t).
//
// Grammar (lowest to highest precedence):
//   expr    := term (('+' | '-') term)*
//   term    := unary (('*' | '/') unary)*
//   unary   := ('-' | '+') unary | power
//   power   := primary ('^' unary)?        right-associative, binds tighter than unary
//                                           minus on its left: -2^2 = -4, 2^-1 = 0.5
//   primary := NUMBER | NAME | NAME '(' expr (',' expr)* ')' | 'spline' '(' NAME ',' expr ')'
//            | '(' expr ')'
//
// Derivatives: every operation is a function c = f(a, b, ...) of the values on the stack;
// the gradient evaluator carries with each value its derivatives with respect to the
// expression's arguments (forward mode: dc = f_a da + f_b db + ...), the Taylor evaluator
// carries (c, c', c'') in t with c'' = sum_i f_i a_i'' + sum_ij f_ij a_i' a_j' (the chain
// rule to second order; e.g. Griewank & Walther, "Evaluating Derivatives", 2nd ed., ch. 13).
// A derivative of an operand that is exactly zero contributes exactly zero, even where
// f' is infinite (sqrt at 0, pow at 0): a value that does not depend on an argument
// gives a result that does not depend on it.
#include "mbs/expression.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cctype>
#include <cstdint>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string_view>

#include "mbs/spline.h"

namespace mbdae::mbs {

namespace {

// Deepest evaluation stack an expression may need; the evaluators use fixed local arrays.
constexpr int kMaxStack = 64;
constexpr int kMaxArgs = kMaxExpressionArguments;

enum Code : int {
  // leaves
  kConst,
  kParam,
  kMeasure,
  kTime,
  // operators
  kAdd,
  kSub,
  kMul,
  kDiv,
  kPow,
  kNeg,
  // one argument
  kSin,
  kCos,
  kTan,
  kAsin,
  kAcos,
  kAtan,
  kSinh,
  kCosh,
  kTanh,
  kExp,
  kLog,
  kSqrt,
  kAbs,
  kSign,
  kPowConst,  // x ^ value, the exponent a literal (folded at parse time)
  kSpline,    // spline `index` at x
  // two arguments
  kAtan2,
  kMin,
  kMax,
  kPowFn,
  // five arguments
  kStep,
};

int Arity(int code) {
  switch (code) {
    case kConst: case kParam: case kMeasure: case kTime: return 0;
    case kAdd: case kSub: case kMul: case kDiv: case kPow: case kAtan2: case kMin: case kMax: case kPowFn:
      return 2;
    case kStep: return 5;
    default: return 1;
  }
}

struct Function {
  const char* name;
  int code;
  int arity;
};

constexpr Function kFunctions[] = {
    {"sin", kSin, 1},     {"cos", kCos, 1},     {"tan", kTan, 1},   {"asin", kAsin, 1},
    {"acos", kAcos, 1},   {"atan", kAtan, 1},   {"sinh", kSinh, 1}, {"cosh", kCosh, 1},
    {"tanh", kTanh, 1},   {"exp", kExp, 1},     {"log", kLog, 1},   {"sqrt", kSqrt, 1},
    {"abs", kAbs, 1},     {"sign", kSign, 1},   {"atan2", kAtan2, 2}, {"min", kMin, 2},
    {"max", kMax, 2},     {"pow", kPowFn, 2},   {"step", kStep, 5},
};

const Function* FindFunction(std::string_view name) {
  for (const Function& f : kFunctions)
    if (name == f.name) return &f;
  return nullptr;
}

double Sign(double x) { return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0); }

// ---------------------------------------------------------------------------------------
// Local derivatives of each operation.

// Value of a one-argument function at x, its first derivative *f1 and, when kSecond, its
// second derivative *f2. Conventions at non-smooth points: abs' = sign (0 at 0), sign' = 0.
template <bool kSecond>
double Unary(int code, double x, double exponent, double* f1, double* f2) {
  double f = 0, d1 = 0, d2 = 0;
  switch (code) {
    case kNeg: f = -x; d1 = -1; break;
    case kSin: f = std::sin(x); d1 = std::cos(x); d2 = -f; break;
    case kCos: f = std::cos(x); d1 = -std::sin(x); d2 = -f; break;
    case kTan: f = std::tan(x); d1 = 1 + f * f; d2 = 2 * f * d1; break;
    case kAsin: f = std::asin(x); d1 = 1 / std::sqrt(1 - x * x); d2 = x * d1 * d1 * d1; break;
    case kAcos: f = std::acos(x); d1 = -1 / std::sqrt(1 - x * x); d2 = x * d1 * d1 * d1; break;
    case kAtan: f = std::atan(x); d1 = 1 / (1 + x * x); d2 = -2 * x * d1 * d1; break;
    case kSinh: f = std::sinh(x); d1 = std::cosh(x); d2 = f; break;
    case kCosh: f = std::cosh(x); d1 = std::sinh(x); d2 = f; break;
    case kTanh: f = std::tanh(x); d1 = 1 - f * f; d2 = -2 * f * d1; break;
    case kExp: f = std::exp(x); d1 = f; d2 = f; break;
    case kLog: f = std::log(x); d1 = 1 / x; d2 = -d1 * d1; break;
    case kSqrt: f = std::sqrt(x); d1 = 0.5 / f; d2 = -0.5 * d1 / x; break;
    case kAbs: f = std::abs(x); d1 = Sign(x); break;
    case kSign: f = Sign(x); break;
    case kPowConst: {
      const double c = exponent;
      f = std::pow(x, c);
      if (c != 0) d1 = c * std::pow(x, c - 1);
      if (kSecond && c != 0 && c != 1) d2 = c * (c - 1) * std::pow(x, c - 2);
      break;
    }
    default: assert(false && "not a one-argument operation");
  }
  *f1 = d1;
  if constexpr (kSecond) *f2 = d2;
  return f;
}

// Partial derivatives of a ^ b: *fa = b a^(b-1) (0 when b = 0), *fb = a^b log a (0 when
// a = 0: the limit from a > 0 for b > 0; NaN for a < 0, where a^b is not differentiable
// in b).
double PowPartials(double a, double b, double* fa, double* fb) {
  const double c = std::pow(a, b);
  *fa = b == 0 ? 0.0 : b * std::pow(a, b - 1);
  *fb = a > 0 ? c * std::log(a) : (a == 0 ? 0.0 : std::numeric_limits<double>::quiet_NaN());
  return c;
}

// Cubic smooth step: h0 for x <= x0, h1 for x >= x1, h0 + (h1 - h0) s^2 (3 - 2 s) between,
// s = (x - x0) / (x1 - x0). With p non-null, also the partials with respect to
// (x, x0, h0, x1, h1); at x = x0 and x = x1 (and for x1 <= x0) the constant branch's.
double SmoothStep(double x, double x0, double h0, double x1, double h1, double* p = nullptr) {
  if (x <= x0 || x >= x1) {
    const bool low = x <= x0;
    if (p != nullptr) {
      p[0] = p[1] = p[3] = 0;
      p[2] = low ? 1 : 0;
      p[4] = low ? 0 : 1;
    }
    return low ? h0 : h1;
  }
  const double L = x1 - x0;
  const double s = (x - x0) / L;
  if (p != nullptr) {
    const double S = s * s * (3.0 - 2.0 * s);
    const double dS = 6.0 * s * (1.0 - s) * (h1 - h0) / L;  // d/dx
    p[0] = dS;
    p[1] = dS * (s - 1.0);  // ds/dx0 = (s - 1) / L
    p[2] = 1.0 - S;
    p[3] = -dS * s;         // ds/dx1 = -s / L
    p[4] = S;
  }
  return h0 + (h1 - h0) * s * s * (3.0 - 2.0 * s);
}

// ---------------------------------------------------------------------------------------
// Value evaluation of a program (also used to fold literal subexpressions at parse time).

// Second-order Taylor numbers in t: value, first and second derivative.
struct T2 {
  double v, d1, d2;
};

T2 operator+(const T2& a, const T2& b) { return {a.v + b.v, a.d1 + b.d1, a.d2 + b.d2}; }
T2 operator-(const T2& a, const T2& b) { return {a.v - b.v, a.d1 - b.d1, a.d2 - b.d2}; }
T2 operator*(const T2& a, const T2& b) {
  return {a.v * b.v, a.d1 * b.v + a.v * b.d1, a.d2 * b.v + 2 * a.d1 * b.d1 + a.v * b.d2};
}
T2 operator/(const T2& a, const T2& b) {
  const double c = a.v / b.v;
  const double c1 = (a.d1 - c * b.d1) / b.v;
  return {c, c1, (a.d2 - 2 * c1 * b.d1 - c * b.d2) / b.v};
}
T2 Lit(double x) { return {x, 0, 0}; }
bool IsConstantInT(const T2& a) { return a.d1 == 0 && a.d2 == 0; }

// c = f(a) with f' = f1, f'' = f2: c' = f1 a', c'' = f2 a'^2 + f1 a''.
T2 Chain(double f, double f1, double f2, const T2& a) {
  if (IsConstantInT(a)) return {f, 0, 0};
  return {f, f1 * a.d1, f2 * a.d1 * a.d1 + f1 * a.d2};
}

}  // namespace

// The parser proper; builds the program of an Expression.
class ExpressionParser {
 public:
  using Op = Expression::Op;

  ExpressionParser(const std::string& text, const SymbolTable& symbols)
      : text_(text), symbols_(symbols) {}

  void Run(Expression* e) {
    e_ = e;
    SkipSpace();
    if (pos_ >= text_.size()) throw ExpressionError("empty expression", 1);
    ParseExpr();
    SkipSpace();
    if (pos_ < text_.size()) {
      throw ExpressionError(std::string("unexpected '") + text_[pos_] + "' at column " +
                                std::to_string(Column()),
                            Column());
    }
    assert(depth_ == 1);
    e->max_stack_ = max_depth_;
    // Derivative slots: t first, then the measures, then the parameters, in order of use.
    const int nt = e->uses_time_ ? 1 : 0;
    const int nm = static_cast<int>(e->measures_used_.size());
    e->num_slots_ = nt + nm + static_cast<int>(e->parameters_used_.size());
    assert(e->num_slots_ <= kMaxArgs);
    for (Op& op : e->program_) {
      if (op.code == kTime) op.slot = 0;
      if (op.code == kMeasure) op.slot = nt + Position(e->measures_used_, op.index);
      if (op.code == kParam) op.slot = nt + nm + Position(e->parameters_used_, op.index);
    }
  }

 private:
  static int Position(const std::vector<int>& list, int index) {
    return static_cast<int>(std::find(list.begin(), list.end(), index) - list.begin());
  }

  int Column() const { return static_cast<int>(pos_) + 1; }

  void SkipSpace() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
  }

  bool Accept(char c) {
    SkipSpace();
    if (pos_ < text_.size() && text_[pos_] == c) {
      ++pos_;
      return true;
    }
    return false;
  }

  [[noreturn]] void Fail(const std::string& what, int column) {
    throw ExpressionError(what + " at column " + std::to_string(column), column);
  }

  std::string Here() const {
    if (pos_ >= text_.size()) return "end of expression";
    return std::string("'") + text_[pos_] + "'";
  }

  // Appends an operation; `pops` operands consumed, one result pushed. An operation whose
  // operands are all literals is folded into a literal (splines are never folded: their
  // points may change between runs); a power with a literal exponent becomes kPowConst.
  void Emit(int code, double value, int pops, int column, int index = -1) {
    std::vector<Op>& program = e_->program_;
    const int n = static_cast<int>(program.size());
    bool literal_operands = pops > 0 && code != kSpline && n >= pops;
    for (int k = n - pops; literal_operands && k < n; ++k) literal_operands = program[k].code == kConst;
    if (literal_operands) {
      Op ops[6];
      for (int k = 0; k < pops; ++k) ops[k] = program[n - pops + k];
      ops[pops] = Op{code, index, -1, value};
      const double folded = Expression::Run(ops, pops + 1, ExpressionInputs{});
      program.resize(n - pops);
      program.push_back(Op{kConst, -1, -1, folded});
    } else if ((code == kPow || code == kPowFn) && program.back().code == kConst) {
      const double exponent = program.back().value;
      program.pop_back();
      program.push_back(Op{kPowConst, -1, -1, exponent});
    } else {
      program.push_back(Op{code, index, -1, value});
    }
    depth_ += 1 - pops;
    if (depth_ > max_depth_) max_depth_ = depth_;
    if (max_depth_ > kMaxStack) Fail("expression is nested too deeply", column);
  }

  void ParseExpr() {
    ParseTerm();
    for (;;) {
      SkipSpace();
      const int column = Column();
      if (Accept('+')) {
        ParseTerm();
        Emit(kAdd, 0, 2, column);
      } else if (Accept('-')) {
        ParseTerm();
        Emit(kSub, 0, 2, column);
      } else {
        return;
      }
    }
  }

  void ParseTerm() {
    ParseUnary();
    for (;;) {
      SkipSpace();
      const int column = Column();
      if (Accept('*')) {
        ParseUnary();
        Emit(kMul, 0, 2, column);
      } else if (Accept('/')) {
        ParseUnary();
        Emit(kDiv, 0, 2, column);
      } else {
        return;
      }
    }
  }

  void ParseUnary() {
    SkipSpace();
    const int column = Column();
    if (++nesting_ > kMaxStack) Fail("expression is nested too deeply", column);
    if (Accept('-')) {
      ParseUnary();
      Emit(kNeg, 0, 1, column);
    } else if (Accept('+')) {
      ParseUnary();
    } else {
      ParsePower();
    }
    --nesting_;
  }

  void ParsePower() {
    ParsePrimary();
    SkipSpace();
    const int column = Column();
    if (Accept('^')) {
      ParseUnary();  // right-associative: 2^3^2 = 2^(3^2)
      Emit(kPow, 0, 2, column);
    }
  }

  void ParsePrimary() {
    SkipSpace();
    const int column = Column();
    if (pos_ >= text_.size()) Fail("expected a number, a name or '(' but found end of expression", column);
    const char c = text_[pos_];
    if (c == '(') {
      ++pos_;
      ParseExpr();
      if (!Accept(')')) Fail("expected ')' but found " + Here(), Column());
      return;
    }
    if (std::isdigit(static_cast<unsigned char>(c)) || c == '.') {
      ParseNumber();
      return;
    }
    if (IsNameStart(c)) {
      ParseName();
      return;
    }
    Fail("expected a number, a name or '(' but found " + Here(), column);
  }

  static bool IsNameStart(char c) { return std::isalpha(static_cast<unsigned char>(c)) || c == '_'; }
  static bool IsNameChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

  void ParseNumber() {
    const size_t start = pos_;
    const int column = Column();
    auto digits = [&] {
      size_t n = 0;
      while (pos_ < text_.size() && std::isdigit(static_cast<unsigned char>(text_[pos_]))) ++pos_, ++n;
      return n;
    };
    size_t n = digits();
    if (pos_ < text_.size() && text_[pos_] == '.') {
      ++pos_;
      n += digits();
    }
    if (n == 0) Fail("malformed number", column);
    if (pos_ < text_.size() && (text_[pos_] == 'e' || text_[pos_] == 'E')) {
      ++pos_;
      if (pos_ < text_.size() && (text_[pos_] == '+' || text_[pos_] == '-')) ++pos_;
      if (digits() == 0) Fail("malformed number (exponent has no digits)", column);
    }
    if (pos_ < text_.size() && IsNameStart(text_[pos_])) {
      Fail("malformed number (a name cannot start with a digit)", column);
    }
    const std::string literal = text_.substr(start, pos_ - start);
    const double value = std::strtod(literal.c_str(), nullptr);
    if (!std::isfinite(value)) Fail("number out of range", column);
    Emit(kConst, value, 0, column);
  }

  // A name that exists but may not be used in this value.
  [[noreturn]] void Refuse(const std::string& what, int column) {
    throw ExpressionError(what + " at column " + std::to_string(column) + " cannot be used here: " +
                              (symbols_.allow_time ? "this value may depend on time only"
                                                   : "this value is evaluated once at load time"),
                          column);
  }

  // Records a use of an argument (t, measure `index` or parameter `index`) and checks the
  // number of distinct arguments.
  void UseArgument(std::vector<int>* used, int index, int column) {
    if (used != nullptr && std::find(used->begin(), used->end(), index) != used->end()) return;
    if (used == nullptr && e_->uses_time_) return;
    const int count = (e_->uses_time_ ? 1 : 0) + static_cast<int>(e_->measures_used_.size() +
                                                                  e_->parameters_used_.size());
    if (count + 1 > kMaxArgs) {
      Fail("too many distinct arguments (t, measures and parameters): at most " +
               std::to_string(kMaxArgs) + " per expression",
           column);
    }
    if (used == nullptr) {
      e_->uses_time_ = true;
    } else {
      used->push_back(index);
    }
  }

  static int Find(const std::vector<std::string>& names, const std::string& name) {
    for (size_t i = 0; i < names.size(); ++i)
      if (names[i] == name) return static_cast<int>(i);
    return -1;
  }

  // spline(NAME, x), after the name 'spline' and with pos_ at '('.
  void ParseSplineCall(int column) {
    if (!symbols_.allow_time) {
      Refuse("spline()", column);
    }
    ++pos_;  // '('
    SkipSpace();
    const int name_column = Column();
    const size_t start = pos_;
    if (pos_ < text_.size() && IsNameStart(text_[pos_])) {
      while (pos_ < text_.size() && IsNameChar(text_[pos_])) ++pos_;
    }
    if (pos_ == start) Fail("spline() needs a spline name first: spline(NAME, x), found " + Here(), name_column);
    const std::string name = text_.substr(start, pos_ - start);
    const int index = Find(symbols_.splines, name);
    if (index < 0) Fail("unknown spline '" + name + "'", name_column);
    if (!Accept(',')) Fail("expected ',' after the spline name but found " + Here(), Column());
    ParseExpr();
    if (!Accept(')')) {
      Fail("spline() takes a spline name and one argument: expected ')' but found " + Here(), Column());
    }
    if (std::find(e_->splines_used_.begin(), e_->splines_used_.end(), index) == e_->splines_used_.end()) {
      e_->splines_used_.push_back(index);
    }
    Emit(kSpline, 0, 1, column, index);
  }

  void ParseName() {
    const size_t start = pos_;
    const int column = Column();
    while (pos_ < text_.size() && IsNameChar(text_[pos_])) ++pos_;
    const std::string name = text_.substr(start, pos_ - start);
    SkipSpace();
    const bool call = pos_ < text_.size() && text_[pos_] == '(';

    if (name == "t" && !call) {
      if (!symbols_.allow_time) Refuse("'t'", column);
      UseArgument(nullptr, 0, column);
      Emit(kTime, 0, 0, column);
      return;
    }
    if (call) {
      if (name == "spline") {
        ParseSplineCall(column);
        return;
      }
      const Function* f = FindFunction(name);
      if (f == nullptr) Fail("unknown function '" + name + "'", column);
      ++pos_;  // '('
      int args = 0;
      if (!Accept(')')) {
        for (;;) {
          ParseExpr();
          ++args;
          if (Accept(',')) continue;
          if (Accept(')')) break;
          Fail("expected ',' or ')' in the arguments of " + name + "() but found " + Here(), Column());
        }
      }
      if (args != f->arity) {
        Fail(name + "() takes " + std::to_string(f->arity) + " argument" + (f->arity == 1 ? "" : "s") +
                 ", got " + std::to_string(args),
             column);
      }
      Emit(f->code, 0, f->arity, column);
      return;
    }
    if (name == "pi") {
      Emit(kConst, M_PI, 0, column);
      return;
    }
    if (const int i = Find(symbols_.measures, name); i >= 0) {
      UseArgument(&e_->measures_used_, i, column);
      Emit(kMeasure, 0, 0, column, i);
      return;
    }
    if (const int i = Find(symbols_.parameters, name); i >= 0) {
      UseArgument(&e_->parameters_used_, i, column);
      Emit(kParam, 0, 0, column, i);
      return;
    }
    if (Find(symbols_.reserved, name) >= 0) {
      Refuse("measure '" + name + "'", column);
    }
    if (FindFunction(name) != nullptr || name == "spline") {
      Fail("function '" + name + "' needs arguments in parentheses", column);
    }
    Fail("unknown name '" + name + "'", column);
  }

  const std::string& text_;
  const SymbolTable& symbols_;
  Expression* e_ = nullptr;
  size_t pos_ = 0;
  int depth_ = 0;
  int max_depth_ = 0;
  int nesting_ = 0;
};

// The value stack machine (also folds literal subexpressions at parse time).
double Expression::Run(const Op* ops, size_t count, const ExpressionInputs& in) {
  std::array<double, kMaxStack> stack;
  int top = -1;  // index of the top element
  for (size_t k = 0; k < count; ++k) {
    const Op& op = ops[k];
    switch (op.code) {
      case kConst: stack[++top] = op.value; break;
      case kParam:
        assert(in.parameters != nullptr);
        stack[++top] = in.parameters[op.index];
        break;
      case kMeasure:
        assert(in.measures != nullptr);
        stack[++top] = in.measures[op.index];
        break;
      case kTime: stack[++top] = in.t; break;
      case kAdd: --top; stack[top] += stack[top + 1]; break;
      case kSub: --top; stack[top] -= stack[top + 1]; break;
      case kMul: --top; stack[top] *= stack[top + 1]; break;
      case kDiv: --top; stack[top] /= stack[top + 1]; break;
      case kPow:
      case kPowFn: --top; stack[top] = std::pow(stack[top], stack[top + 1]); break;
      case kPowConst: stack[top] = std::pow(stack[top], op.value); break;
      case kNeg: stack[top] = -stack[top]; break;
      case kSin: stack[top] = std::sin(stack[top]); break;
      case kCos: stack[top] = std::cos(stack[top]); break;
      case kTan: stack[top] = std::tan(stack[top]); break;
      case kAsin: stack[top] = std::asin(stack[top]); break;
      case kAcos: stack[top] = std::acos(stack[top]); break;
      case kAtan: stack[top] = std::atan(stack[top]); break;
      case kSinh: stack[top] = std::sinh(stack[top]); break;
      case kCosh: stack[top] = std::cosh(stack[top]); break;
      case kTanh: stack[top] = std::tanh(stack[top]); break;
      case kExp: stack[top] = std::exp(stack[top]); break;
      case kLog: stack[top] = std::log(stack[top]); break;
      case kSqrt: stack[top] = std::sqrt(stack[top]); break;
      case kAbs: stack[top] = std::abs(stack[top]); break;
      case kSign: stack[top] = Sign(stack[top]); break;
      case kSpline:
        assert(in.splines != nullptr && in.splines[op.index] != nullptr);
        stack[top] = in.splines[op.index]->Evaluate(stack[top]);
        break;
      case kAtan2: --top; stack[top] = std::atan2(stack[top], stack[top + 1]); break;
      case kMin: --top; stack[top] = std::min(stack[top], stack[top + 1]); break;
      case kMax: --top; stack[top] = std::max(stack[top], stack[top + 1]); break;
      case kStep:
        top -= 4;
        stack[top] = SmoothStep(stack[top], stack[top + 1], stack[top + 2], stack[top + 3], stack[top + 4]);
        break;
      default: assert(false && "bad expression op code");
    }
  }
  assert(top == 0);
  return stack[0];
}

Expression Expression::Constant(double value) {
  Expression e;
  e.program_.push_back({kConst, -1, -1, value});
  std::ostringstream text;
  text << std::setprecision(17) << value;
  e.text_ = text.str();
  e.max_stack_ = 1;
  return e;
}

Expression Expression::Parse(const std::string& text, const SymbolTable& symbols) {
  Expression e;
  ExpressionParser(text, symbols).Run(&e);
  e.program_.shrink_to_fit();
  e.text_ = text;
  return e;
}

bool Expression::is_constant() const {
  return parameters_used_.empty() && measures_used_.empty() && splines_used_.empty() && !uses_time_;
}

double Expression::Evaluate(const double* parameters) const {
  ExpressionInputs in;
  in.parameters = parameters;
  return Evaluate(in);
}

double Expression::Evaluate(const ExpressionInputs& in) const {
  if (program_.empty()) return 0.0;
  assert(max_stack_ <= kMaxStack);
  return Run(program_.data(), program_.size(), in);
}

double Expression::EvaluateGradient(const ExpressionInputs& in, ExpressionGradient* g) const {
  assert(g != nullptr);
  g->d_t = 0;
  if (program_.empty()) return 0.0;
  assert(max_stack_ <= kMaxStack);
  // Stack entry k: value v[k], the set of argument slots it depends on (bit j of m[k]),
  // and its derivatives d[k][j], valid for the slots in m[k] only (the others are never
  // read, so leaves and literals need no zero-filling and each operation touches only
  // the slots its result depends on).
  std::array<double, kMaxStack> v;
  std::array<uint32_t, kMaxStack> m;
  std::array<std::array<double, kMaxArgs>, kMaxStack> d;
  int top = -1;
  // Slot j of operand row `row` with slot set `mask`, as a term: 0 when the operand does
  // not depend on j or its derivative is exactly 0 (even if the factor f is infinite).
  auto term = [](uint32_t mask, const double* row, int j, double f) {
    return ((mask >> j) & 1u) != 0 && row[j] != 0 ? f * row[j] : 0.0;
  };
  // top-1 <- fa * (top-1) + fb * (top), over the union of their slots.
  auto combine = [&](double fa, double fb) {
    --top;
    const uint32_t ma = m[top], mb = m[top + 1];
    double* da = d[top].data();
    const double* db = d[top + 1].data();
    for (uint32_t bits = ma | mb; bits != 0; bits &= bits - 1) {
      const int j = __builtin_ctz(bits);
      da[j] = term(ma, da, j, fa) + term(mb, db, j, fb);
    }
    m[top] = ma | mb;
  };
  auto scale = [&](double fa) {
    double* da = d[top].data();
    for (uint32_t bits = m[top]; bits != 0; bits &= bits - 1) {
      const int j = __builtin_ctz(bits);
      da[j] = da[j] != 0 ? fa * da[j] : 0.0;
    }
  };
  for (const Op& op : program_) {
    switch (op.code) {
      case kConst: v[++top] = op.value; m[top] = 0; break;
      case kParam:
        assert(in.parameters != nullptr);
        v[++top] = in.parameters[op.index];
        m[top] = 1u << op.slot;
        d[top][op.slot] = 1.0;
        break;
      case kMeasure:
        assert(in.measures != nullptr);
        v[++top] = in.measures[op.index];
        m[top] = 1u << op.slot;
        d[top][op.slot] = 1.0;
        break;
      case kTime: v[++top] = in.t; m[top] = 1u << op.slot; d[top][op.slot] = 1.0; break;
      case kAdd: {
        const double b = v[top];
        combine(1.0, 1.0);
        v[top] += b;
        break;
      }
      case kSub: {
        const double b = v[top];
        combine(1.0, -1.0);
        v[top] -= b;
        break;
      }
      case kMul: {
        const double a = v[top - 1], b = v[top];
        combine(b, a);
        v[top] = a * b;
        break;
      }
      case kDiv: {
        const double b = v[top];
        const double c = v[top - 1] / b;
        combine(1.0 / b, -c / b);
        v[top] = c;
        break;
      }
      case kNeg: v[top] = -v[top]; scale(-1.0); break;
      case kSpline: {
        assert(in.splines != nullptr && in.splines[op.index] != nullptr);
        double f1 = 0;
        v[top] = in.splines[op.index]->Evaluate(v[top], &f1, nullptr);
        scale(f1);
        break;
      }
      case kPow:
      case kPowFn: {
        double fa, fb;
        const double c = PowPartials(v[top - 1], v[top], &fa, &fb);
        combine(fa, fb);
        v[top] = c;
        break;
      }
      case kAtan2: {
        const double y = v[top - 1], x = v[top];
        const double r2 = x * x + y * y;
        // d atan2(y, x) = (x dy - y dx) / (x^2 + y^2); 0 at the origin by convention.
        combine(r2 > 0 ? x / r2 : 0.0, r2 > 0 ? -y / r2 : 0.0);
        v[top] = std::atan2(y, x);
        break;
      }
      case kMin:
      case kMax: {
        --top;
        const double a = v[top], b = v[top + 1];
        // Ties take the first argument, as std::min / std::max do.
        const bool first = op.code == kMin ? !(b < a) : !(a < b);
        if (!first) {
          v[top] = b;
          m[top] = m[top + 1];
          for (uint32_t bits = m[top]; bits != 0; bits &= bits - 1) {
            const int j = __builtin_ctz(bits);
            d[top][j] = d[top + 1][j];
          }
        }
        break;
      }
      case kStep: {
        top -= 4;
        double p[5];
        v[top] = SmoothStep(v[top], v[top + 1], v[top + 2], v[top + 3], v[top + 4], p);
        uint32_t all = 0;
        for (int i = 0; i < 5; ++i) all |= m[top + i];
        for (uint32_t bits = all; bits != 0; bits &= bits - 1) {
          const int j = __builtin_ctz(bits);
          double s = 0;
          for (int i = 0; i < 5; ++i) s += term(m[top + i], d[top + i].data(), j, p[i]);
          d[top][j] = s;
        }
        m[top] = all;
        break;
      }
      default: {
        double f1;
        v[top] = Unary<false>(op.code, v[top], op.value, &f1, nullptr);
        scale(f1);
        break;
      }
    }
  }
  assert(top == 0);
  const int nt = uses_time_ ? 1 : 0;
  const int nm = static_cast<int>(measures_used_.size());
  const int np = static_cast<int>(parameters_used_.size());
  auto slot = [&](int j) { return ((m[0] >> j) & 1u) != 0 ? d[0][j] : 0.0; };
  if (uses_time_) g->d_t = slot(0);
  for (int k = 0; k < nm; ++k) g->d_measures[k] = slot(nt + k);
  for (int k = 0; k < np; ++k) g->d_parameters[k] = slot(nt + nm + k);
  return v[0];
}

double Expression::EvaluateTimeDerivatives(const ExpressionInputs& in, double* d1, double* d2) const {
  if (depends_on_state()) {
    throw std::logic_error("expression '" + text_ +
                           "' depends on measures: its time derivatives need the state's");
  }
  T2 r{0, 0, 0};
  if (!program_.empty()) {
    assert(max_stack_ <= kMaxStack);
    std::array<T2, kMaxStack> s;
    int top = -1;
    for (const Op& op : program_) {
      switch (op.code) {
        case kConst: s[++top] = Lit(op.value); break;
        case kParam: assert(in.parameters != nullptr); s[++top] = Lit(in.parameters[op.index]); break;
        case kTime: s[++top] = T2{in.t, 1, 0}; break;
        case kAdd: --top; s[top] = s[top] + s[top + 1]; break;
        case kSub: --top; s[top] = s[top] - s[top + 1]; break;
        case kMul: --top; s[top] = s[top] * s[top + 1]; break;
        case kDiv: --top; s[top] = s[top] / s[top + 1]; break;
        case kSpline: {
          assert(in.splines != nullptr && in.splines[op.index] != nullptr);
          double f1 = 0, f2 = 0;
          const double f = in.splines[op.index]->Evaluate(s[top].v, &f1, &f2);
          s[top] = Chain(f, f1, f2, s[top]);
          break;
        }
        case kPow:
        case kPowFn: {
          --top;
          const T2 a = s[top], b = s[top + 1];
          if (IsConstantInT(b) || a.v == 0) {
            // Power rule in a alone (b constant in t; or a = 0, where the b-part vanishes).
            double f1, f2;
            const double f = Unary<true>(kPowConst, a.v, b.v, &f1, &f2);
            s[top] = Chain(f, f1, f2, a);
          } else {
            // a^b = exp(b log a): with m = b log a, c' = c m', c'' = c (m'' + m'^2). NaN
            // derivatives for a < 0 (a^b is not differentiable in b there).
            const T2 log_a = Chain(std::log(a.v), 1 / a.v, -1 / (a.v * a.v), a);
            const T2 m = b * log_a;
            const double c = std::pow(a.v, b.v);
            s[top] = T2{c, c * m.d1, c * (m.d2 + m.d1 * m.d1)};
          }
          break;
        }
        case kAtan2: {
          --top;
          const T2 y = s[top], x = s[top + 1];
          const double r2 = x.v * x.v + y.v * y.v;
          T2 c{std::atan2(y.v, x.v), 0, 0};
          if (r2 > 0 && !(IsConstantInT(x) && IsConstantInT(y))) {
            // First partials fy = x/r2, fx = -y/r2; second fyy = -2xy/r2^2, fxx = 2xy/r2^2,
            // fxy = (y^2 - x^2)/r2^2.
            const double fy = x.v / r2, fx = -y.v / r2;
            const double r4 = r2 * r2;
            const double fyy = -2 * x.v * y.v / r4, fxx = -fyy, fxy = (y.v * y.v - x.v * x.v) / r4;
            c.d1 = fy * y.d1 + fx * x.d1;
            c.d2 = fy * y.d2 + fx * x.d2 + fyy * y.d1 * y.d1 + 2 * fxy * x.d1 * y.d1 + fxx * x.d1 * x.d1;
          }
          s[top] = c;
          break;
        }
        case kMin: --top; if (s[top + 1].v < s[top].v) s[top] = s[top + 1]; break;
        case kMax: --top; if (s[top].v < s[top + 1].v) s[top] = s[top + 1]; break;
        case kStep: {
          top -= 4;
          const T2 x = s[top], x0 = s[top + 1], h0 = s[top + 2], x1 = s[top + 3], h1 = s[top + 4];
          const double value = SmoothStep(x.v, x0.v, h0.v, x1.v, h1.v);
          if (x.v <= x0.v) {
            s[top] = h0;
          } else if (x.v >= x1.v) {
            s[top] = h1;
          } else {
            const T2 u = (x - x0) / (x1 - x0);
            const T2 S = u * u * (Lit(3) - Lit(2) * u);
            s[top] = h0 + (h1 - h0) * S;
          }
          s[top].v = value;  // bit-identical to Evaluate
          break;
        }
        case kMeasure: assert(false && "checked above"); break;
        default: {
          double f1, f2;
          const double f = Unary<true>(op.code, s[top].v, op.value, &f1, &f2);
          s[top] = Chain(f, f1, f2, s[top]);
          break;
        }
      }
    }
    assert(top == 0);
    r = s[0];
  }
  if (d1 != nullptr) *d1 = r.d1;
  if (d2 != nullptr) *d2 = r.d2;
  return r.v;
}

}  // namespace mbdae::mbs

// ---------------------------------------------------------------------------------------
// Directional evaluation: truncated Taylor polynomials in two variables, t (to second
// order) and a parameter direction e (to first order): x = sum c[i][j] t^i e^j, i < 3,
// j < 2. Products are truncated polynomial products; a function of one argument is
// f(x) = f(v) + f' N + f''/2 N^2 + f'''/6 N^3 with N = x - v (N^4 = 0).

namespace mbdae::mbs {
namespace {

struct Jet {
  double c[3][2] = {{0, 0}, {0, 0}, {0, 0}};
  double v() const { return c[0][0]; }
  bool constant() const {
    return c[1][0] == 0 && c[2][0] == 0 && c[0][1] == 0 && c[1][1] == 0 && c[2][1] == 0;
  }
};

Jet JLit(double x) { Jet r; r.c[0][0] = x; return r; }
Jet operator+(const Jet& a, const Jet& b) {
  Jet r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 2; ++j) r.c[i][j] = a.c[i][j] + b.c[i][j];
  return r;
}
Jet operator-(const Jet& a, const Jet& b) {
  Jet r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 2; ++j) r.c[i][j] = a.c[i][j] - b.c[i][j];
  return r;
}
Jet operator*(double s, const Jet& a) {
  Jet r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 2; ++j) r.c[i][j] = a.c[i][j] != 0 ? s * a.c[i][j] : 0.0;
  return r;
}
Jet operator*(const Jet& a, const Jet& b) {
  Jet r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 2; ++j) {
      double s = 0;
      for (int ia = 0; ia <= i; ++ia)
        for (int ja = 0; ja <= j; ++ja) {
          const double x = a.c[ia][ja], y = b.c[i - ia][j - ja];
          if (x != 0 && y != 0) s += x * y;
        }
      r.c[i][j] = s;
    }
  return r;
}
// f(a) from f and its first three derivatives at a.v(); a term whose power of N is
// exactly zero contributes zero even if the derivative is infinite.
Jet JChain(const Jet& a, double f0, double f1, double f2, double f3) {
  Jet n = a;
  n.c[0][0] = 0;
  const Jet n2 = n * n, n3 = n2 * n;
  Jet r = JLit(f0);
  r = r + f1 * n;
  r = r + (0.5 * f2) * n2;
  r = r + (f3 / 6) * n3;
  return r;
}
// The first three derivatives of a one-argument operation at x.
double Unary3(int code, double x, double exponent, double* d1, double* d2, double* d3) {
  double f = 0, a = 0, b = 0, c = 0;
  switch (code) {
    case kNeg: f = -x; a = -1; break;
    case kSin: f = std::sin(x); a = std::cos(x); b = -f; c = -a; break;
    case kCos: f = std::cos(x); a = -std::sin(x); b = -f; c = -a; break;
    case kTan: f = std::tan(x); a = 1 + f * f; b = 2 * f * a; c = 2 * a * a + 2 * f * b; break;
    case kAsin: case kAcos: {
      const double s = (code == kAsin ? 1.0 : -1.0);
      f = code == kAsin ? std::asin(x) : std::acos(x);
      const double g = 1 / std::sqrt(1 - x * x);  // (1 - x^2)^(-1/2)
      a = s * g;
      b = s * x * g * g * g;
      c = s * (g * g * g + 3 * x * x * g * g * g * g * g);
      break;
    }
    case kAtan: f = std::atan(x); a = 1 / (1 + x * x); b = -2 * x * a * a; c = -2 * a * a + 8 * x * x * a * a * a; break;
    case kSinh: f = std::sinh(x); a = std::cosh(x); b = f; c = a; break;
    case kCosh: f = std::cosh(x); a = std::sinh(x); b = f; c = a; break;
    case kTanh: f = std::tanh(x); a = 1 - f * f; b = -2 * f * a; c = -2 * a * a - 2 * f * b; break;
    case kExp: f = std::exp(x); a = b = c = f; break;
    case kLog: f = std::log(x); a = 1 / x; b = -a * a; c = 2 * a * a * a; break;
    case kSqrt: f = std::sqrt(x); a = 0.5 / f; b = -0.5 * a / x; c = -1.5 * b / x; break;
    case kAbs: f = std::abs(x); a = Sign(x); break;
    case kSign: f = Sign(x); break;
    case kPowConst: {
      const double e = exponent;
      f = std::pow(x, e);
      if (e != 0) a = e * std::pow(x, e - 1);
      if (e != 0 && e != 1) b = e * (e - 1) * std::pow(x, e - 2);
      if (e != 0 && e != 1 && e != 2) c = e * (e - 1) * (e - 2) * std::pow(x, e - 3);
      break;
    }
    default: assert(false && "not a one-argument operation");
  }
  *d1 = a;
  *d2 = b;
  *d3 = c;
  return f;
}
Jet JUnary(int code, const Jet& x, double exponent) {
  double a, b, c;
  const double f = Unary3(code, x.v(), exponent, &a, &b, &c);
  return JChain(x, f, a, b, c);
}
Jet JDiv(const Jet& a, const Jet& b) {
  const double v = b.v();
  return a * JChain(b, 1 / v, -1 / (v * v), 2 / (v * v * v), -6 / (v * v * v * v));
}

}  // namespace

DirectionalDerivatives Expression::EvaluateDirectional(const ExpressionInputs& in,
                                                       const ParameterDirection& dir) const {
  DirectionalDerivatives out;
  if (program_.empty()) return out;
  assert(max_stack_ <= kMaxStack);
  std::array<Jet, kMaxStack> s;
  int top = -1;
  for (const Op& op : program_) {
    switch (op.code) {
      case kConst: s[++top] = JLit(op.value); break;
      case kParam:
        assert(in.parameters != nullptr);
        s[++top] = JLit(in.parameters[op.index]);
        if (dir.parameters) s[top].c[0][1] = dir.parameters[op.index];
        break;
      case kMeasure: assert(in.measures != nullptr); s[++top] = JLit(in.measures[op.index]); break;
      case kTime: s[++top] = JLit(in.t); s[top].c[1][0] = 1; break;
      case kAdd: --top; s[top] = s[top] + s[top + 1]; break;
      case kSub: --top; s[top] = s[top] - s[top + 1]; break;
      case kMul: --top; s[top] = s[top] * s[top + 1]; break;
      case kDiv: --top; s[top] = JDiv(s[top], s[top + 1]); break;
      case kSpline: {
        assert(in.splines != nullptr && in.splines[op.index] != nullptr);
        const Spline& sp = *in.splines[op.index];
        const double x = s[top].v();
        double f1 = 0, f2 = 0;
        const double f = sp.Evaluate(x, &f1, &f2);
        const Jet arg = s[top];
        s[top] = JChain(arg, f, f1, f2, sp.ThirdDerivative(x));
        const Spline* tangent = dir.spline_tangents ? dir.spline_tangents[op.index] : nullptr;
        if (tangent) {
          // + e (Y(x) + Y' N + Y''/2 N^2), Y the ordinates' tangent at the argument.
          double y1 = 0, y2 = 0;
          const double y0 = tangent->Evaluate(x, &y1, &y2);
          Jet e;
          e.c[0][1] = 1;
          s[top] = s[top] + e * JChain(arg, y0, y1, y2, 0.0);
        }
        break;
      }
      case kPow:
      case kPowFn: {
        --top;
        const Jet a = s[top], b = s[top + 1];
        if (b.constant() || a.v() == 0) {
          s[top] = JUnary(kPowConst, a, b.v());
        } else {
          // a^b = exp(b log a)
          const Jet m = b * JUnary(kLog, a, 0);
          s[top] = JUnary(kExp, m, 0);
        }
        break;
      }
      case kAtan2: {
        --top;
        const Jet y = s[top], x = s[top + 1];
        const double x0 = x.v(), y0 = y.v(), r2 = x0 * x0 + y0 * y0;
        Jet c = JLit(std::atan2(y0, x0));
        if (r2 > 0 && !(x.constant() && y.constant())) {
          // atan2(y, x) = atan2(y0, x0) + atan(Y / X) near (x0, y0), with
          // Y = x0 y - y0 x (value 0) and X = x0 x + y0 y (value r2 > 0).
          const Jet Y = x0 * y - y0 * x, X = x0 * x + y0 * y;
          Jet r = JUnary(kAtan, JDiv(Y, X), 0);
          r.c[0][0] = 0;
          c = c + r;
        }
        s[top] = c;
        break;
      }
      case kMin: --top; if (s[top + 1].v() < s[top].v()) s[top] = s[top + 1]; break;
      case kMax: --top; if (s[top].v() < s[top + 1].v()) s[top] = s[top + 1]; break;
      case kStep: {
        top -= 4;
        const Jet x = s[top], x0 = s[top + 1], h0 = s[top + 2], x1 = s[top + 3], h1 = s[top + 4];
        if (x.v() <= x0.v()) {
          s[top] = h0;
        } else if (x.v() >= x1.v()) {
          s[top] = h1;
        } else {
          const Jet u = JDiv(x - x0, x1 - x0);
          const Jet S = u * u * (JLit(3) - 2.0 * u);
          s[top] = h0 + (h1 - h0) * S;
        }
        break;
      }
      default: s[top] = JUnary(op.code, s[top], op.value); break;
    }
  }
  assert(top == 0);
  const Jet& r = s[0];
  out.value = Evaluate(in);
  out.d_t = r.c[1][0];
  out.d_tt = 2 * r.c[2][0];
  out.dir = r.c[0][1];
  out.dir_t = r.c[1][1];
  out.dir_tt = 2 * r.c[2][1];
  return out;
}

double Expression::EvaluateSplineOrdinateGradient(const ExpressionInputs& in, int spline,
                                                  int point) const {
  if (std::find(splines_used_.begin(), splines_used_.end(), spline) == splines_used_.end()) return 0;
  assert(in.splines != nullptr && in.splines[spline] != nullptr);
  const Spline& sp = *in.splines[spline];
  std::vector<double> dy(sp.x().size(), 0.0);
  if (point < 0 || point >= static_cast<int>(dy.size())) {
    throw std::out_of_range("EvaluateSplineOrdinateGradient: point " + std::to_string(point) + " of " +
                            std::to_string(dy.size()));
  }
  dy[point] = 1;
  return EvaluateSplineTangent(in, spline, sp.Tangent(dy));
}

double Expression::EvaluateSplineTangent(const ExpressionInputs& in, int spline, const Spline& tangent) const {
  if (std::find(splines_used_.begin(), splines_used_.end(), spline) == splines_used_.end()) return 0;
  // Indexed by spline: large enough for every spline the expression uses (a null
  // tangent is a zero direction). Expressions call few splines: on the stack.
  constexpr int kStack = 16;
  int size = spline + 1;
  for (int s : splines_used_) size = std::max(size, s + 1);
  const Spline* stack[kStack] = {};
  std::vector<const Spline*> heap;
  const Spline** tangents = stack;
  if (size > kStack) {
    heap.assign(size, nullptr);
    tangents = heap.data();
  }
  tangents[spline] = &tangent;
  ParameterDirection dir;
  dir.spline_tangents = tangents;
  return EvaluateDirectional(in, dir).dir;
}

}  // namespace mbdae::mbs
