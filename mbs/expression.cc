// Expression parser and evaluator: recursive descent into a postfix program.
//
// Grammar (lowest to highest precedence):
//   expr    := term (('+' | '-') term)*
//   term    := unary (('*' | '/') unary)*
//   unary   := ('-' | '+') unary | power
//   power   := primary ('^' unary)?        right-associative, binds tighter than unary
//                                           minus on its left: -2^2 = -4, 2^-1 = 0.5
//   primary := NUMBER | NAME | NAME '(' expr (',' expr)* ')' | '(' expr ')'
#include "mbs/expression.h"

#include <array>
#include <cassert>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <sstream>
#include <string_view>

namespace mbdae::mbs {

namespace {

// Deepest evaluation stack an expression may need; Evaluate uses a fixed local array.
constexpr int kMaxStack = 64;

enum Code : int {
  kConst,
  kParam,
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
  // two arguments
  kAtan2,
  kMin,
  kMax,
  kPowFn,
  // five arguments
  kStep,
};

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

constexpr const char* kNotYet =
    " is not supported yet (time- and state-dependent expressions come with a later release)";

// Cubic smooth step: h0 for x <= x0, h1 for x >= x1, h0 + (h1 - h0) s^2 (3 - 2 s) between,
// s = (x - x0) / (x1 - x0).
double SmoothStep(double x, double x0, double h0, double x1, double h1) {
  if (x <= x0) return h0;
  if (x >= x1) return h1;
  const double s = (x - x0) / (x1 - x0);
  return h0 + (h1 - h0) * s * s * (3.0 - 2.0 * s);
}

double Sign(double x) { return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0); }

}  // namespace

// The parser proper; builds the program of an Expression.
class ExpressionParser {
 public:
  ExpressionParser(const std::string& text, const SymbolTable& symbols)
      : text_(text), symbols_(symbols) {}

  void Run(std::vector<std::pair<int, double>>* program, std::vector<int>* used, int* max_stack) {
    program_ = program;
    used_ = used;
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
    *max_stack = max_depth_;
  }

 private:
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

  // Stack effect bookkeeping: `pops` operands consumed, one result pushed.
  void Emit(int code, double value, int pops, int column) {
    program_->emplace_back(code, value);
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
    if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
      ParseName();
      return;
    }
    Fail("expected a number, a name or '(' but found " + Here(), column);
  }

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
    if (pos_ < text_.size() &&
        (std::isalpha(static_cast<unsigned char>(text_[pos_])) || text_[pos_] == '_')) {
      Fail("malformed number (a name cannot start with a digit)", column);
    }
    const std::string literal = text_.substr(start, pos_ - start);
    const double value = std::strtod(literal.c_str(), nullptr);
    if (!std::isfinite(value)) Fail("number out of range", column);
    Emit(kConst, value, 0, column);
  }

  void ParseName() {
    const size_t start = pos_;
    const int column = Column();
    while (pos_ < text_.size() &&
           (std::isalnum(static_cast<unsigned char>(text_[pos_])) || text_[pos_] == '_')) {
      ++pos_;
    }
    const std::string name = text_.substr(start, pos_ - start);
    SkipSpace();
    const bool call = pos_ < text_.size() && text_[pos_] == '(';

    if (name == "t" || name == "spline") {
      throw ExpressionError("'" + name + "' at column " + std::to_string(column) + kNotYet, column);
    }
    for (const std::string& r : symbols_.reserved) {
      if (r == name) {
        throw ExpressionError("measure '" + name + "' at column " + std::to_string(column) + kNotYet,
                              column);
      }
    }
    if (call) {
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
    for (size_t i = 0; i < symbols_.parameters.size(); ++i) {
      if (symbols_.parameters[i] == name) {
        Emit(kParam, static_cast<double>(i), 0, column);
        bool seen = false;
        for (int u : *used_) seen = seen || u == static_cast<int>(i);
        if (!seen) used_->push_back(static_cast<int>(i));
        return;
      }
    }
    if (FindFunction(name) != nullptr) Fail("function '" + name + "' needs arguments in parentheses", column);
    Fail("unknown name '" + name + "'", column);
  }

  const std::string& text_;
  const SymbolTable& symbols_;
  size_t pos_ = 0;
  int depth_ = 0;
  int max_depth_ = 0;
  int nesting_ = 0;
  std::vector<std::pair<int, double>>* program_ = nullptr;
  std::vector<int>* used_ = nullptr;
};

Expression Expression::Constant(double value) {
  Expression e;
  e.program_.push_back({kConst, value});
  std::ostringstream text;
  text << std::setprecision(17) << value;
  e.text_ = text.str();
  e.max_stack_ = 1;
  return e;
}

Expression Expression::Parse(const std::string& text, const SymbolTable& symbols) {
  std::vector<std::pair<int, double>> program;
  Expression e;
  int max_stack = 1;
  ExpressionParser(text, symbols).Run(&program, &e.parameters_used_, &max_stack);
  e.program_.reserve(program.size());
  for (const auto& [code, value] : program) e.program_.push_back({code, value});
  e.text_ = text;
  e.max_stack_ = max_stack;
  return e;
}

bool Expression::is_constant() const { return parameters_used_.empty(); }

double Expression::Evaluate(const double* parameters) const {
  if (program_.empty()) return 0.0;
  assert(max_stack_ <= kMaxStack);
  std::array<double, kMaxStack> stack;
  int top = -1;  // index of the top element
  for (const Op& op : program_) {
    switch (op.code) {
      case kConst: stack[++top] = op.value; break;
      case kParam:
        assert(parameters != nullptr);
        stack[++top] = parameters[static_cast<int>(op.value)];
        break;
      case kAdd: --top; stack[top] += stack[top + 1]; break;
      case kSub: --top; stack[top] -= stack[top + 1]; break;
      case kMul: --top; stack[top] *= stack[top + 1]; break;
      case kDiv: --top; stack[top] /= stack[top + 1]; break;
      case kPow:
      case kPowFn: --top; stack[top] = std::pow(stack[top], stack[top + 1]); break;
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

}  // namespace mbdae::mbs
