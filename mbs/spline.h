// One-dimensional interpolating splines of the model file (linear, natural cubic,
// Akima), with exact first and second derivatives. A spline's points may be replaced
// between runs without reloading the model (SetPoints).
#pragma once

#include <string>
#include <vector>

namespace mbdae::mbs {

enum class Interpolation { kLinear, kCubic, kAkima };

class Spline {
 public:
  Spline() = default;
  // Throws std::invalid_argument when x is not strictly increasing, sizes differ, or
  // there are fewer points than the interpolation needs (linear 2, cubic 3, akima 3 —
  // see the implementation for the exact rule).
  Spline(std::vector<double> x, std::vector<double> y, Interpolation kind);

  // Replaces the points (same validation); the coefficients are recomputed.
  void SetPoints(std::vector<double> x, std::vector<double> y);

  // Value and exact derivatives at x; d1, d2 may be null. Outside [x_0, x_n]: see the
  // implementation's documented rule (the contract asks that it is documented).
  double Evaluate(double x, double* d1 = nullptr, double* d2 = nullptr) const;

  Interpolation kind() const { return kind_; }
  const std::vector<double>& x() const { return x_; }
  const std::vector<double>& y() const { return y_; }

 private:
  void Build();
  Interpolation kind_ = Interpolation::kLinear;
  std::vector<double> x_, y_;
  // Per interval i: y = y_i + b_i s + c_i s^2 + d_i s^3, s = x - x_i.
  std::vector<double> b_, c_, d_;
};

// Reads columns of a CSV or whitespace-separated text file: skips header_lines lines,
// then reads column x_column and y_column (0-based) of every non-empty line. Throws
// std::runtime_error naming the file and line on a malformed number or a missing column.
void ReadSplineFile(const std::string& path, int header_lines, int x_column, int y_column,
                    std::vector<double>* x, std::vector<double>* y);

}  // namespace mbdae::mbs
