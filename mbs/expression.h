// Scalar expressions of the model file: numbers, `pi`, parameter names, + - * / ^,
// unary minus, parentheses and the functions of the model format. Parsed once into a
// compact postfix program; evaluation does no string work and no allocation.
//
// This scope: expressions over parameters only (load-time and run-time values
// of forces). Time `t`, measures and `spline()` are rejected by the parser with a
// "not supported yet" error; they come with the elements issue.
#pragma once

#include <exception>
#include <string>
#include <vector>

namespace mbdae::mbs {

// Names an expression may refer to, by index.
struct SymbolTable {
  std::vector<std::string> parameters;  // index i -> parameter i
  // Names that exist in the model but may not be used here (measures, `t`): using them
  // gives "not supported yet" instead of "unknown name".
  std::vector<std::string> reserved;
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
  // Throws ExpressionError on a syntax error or unknown name.
  static Expression Parse(const std::string& text, const SymbolTable& symbols);

  double Evaluate(const double* parameters) const;
  bool is_constant() const;                     // refers to no parameter
  const std::vector<int>& parameters_used() const { return parameters_used_; }
  const std::string& text() const { return text_; }

 private:
  struct Op {
    int code;
    double value;  // constant, or index of the parameter
  };
  std::vector<Op> program_;
  std::vector<int> parameters_used_;
  std::string text_;
  int max_stack_ = 1;
};

}  // namespace mbdae::mbs
