// One-dimensional interpolating splines of the model file (linear, natural cubic,
// Akima), with exact first and second derivatives. A spline's points may be replaced
// between runs without reloading the model (SetPoints).
//
// The rules (docs/splines.md gives the same with examples):
//
// - Points: x strictly increasing, x and y of equal size, every value finite, at least
//   2 points for every kind. With exactly 2 points the cubic and the Akima spline are
//   the straight line through them (the natural cubic through 2 points is that line, and
//   Akima's end extension of a single secant slope makes every slope equal to it).
// - Linear: y is the chord on each interval; d2 = 0 everywhere. At an interior knot x_i
//   the value is y_i and d1 is the slope of the interval to the right, [x_i, x_i+1];
//   at the last knot d1 is the slope of the last interval.
// - Cubic: the natural cubic spline (second derivative zero at both ends), C2.
// - Akima (H. Akima, "A new method of interpolation and smooth curve fitting based on
//   local procedures", J. ACM 17 (1970) 589-602): C1; the slope at a knot is the weighted
//   average of the neighbouring secant slopes, see spline.cc.
// - Inside [x_0, x_n]: the cubic of the interval [x_i, x_i+1] with x_i <= x < x_i+1
//   (at x_n, the last interval), found by binary search; no allocation.
// - Outside [x_0, x_n]: linear extrapolation with the end value and the end slope (the
//   spline's own d1 at that end), so value and d1 are continuous at the ends and
//   d2 = 0 outside.
#pragma once

#include <string>
#include <vector>

namespace mbdae::mbs {

enum class Interpolation { kLinear, kCubic, kAkima };

// "linear", "cubic", "akima".
const char* InterpolationName(Interpolation kind);

class Spline {
 public:
  Spline() = default;
  // Throws std::invalid_argument when x is not strictly increasing, sizes differ, a value
  // is not finite, or there are fewer than 2 points; the message says which entry.
  Spline(std::vector<double> x, std::vector<double> y, Interpolation kind);

  // Replaces the points (same validation; on failure the spline is unchanged); the
  // coefficients are recomputed.
  void SetPoints(std::vector<double> x, std::vector<double> y);

  // Value and exact derivatives at x; d1, d2 may be null. Outside [x_0, x_n]: linear
  // extrapolation (see above). The spline must have points (not default-constructed).
  double Evaluate(double x, double* d1 = nullptr, double* d2 = nullptr) const;

  // The third derivative at x (6 d_i on interval i as Evaluate picks it; 0 outside
  // [x_0, x_n] and for the linear kind), for second-order Taylor arithmetic with a
  // parameter direction (Expression::EvaluateDirectional).
  double ThirdDerivative(double x) const;

  // Derivatives with respect to the ordinates y. Tangent(dy) is a spline-shaped object
  // whose Evaluate(x, d1, d2) and ThirdDerivative(x) give the directional derivatives
  // d/de of the value, d1, d2 and d3 at a fixed x when y changes to y + e dy (x fixed).
  // Linear and cubic splines are linear in y, so this is the spline of the same kind
  // through (x, dy), exactly. Akima's slopes are not linear in y: their derivative is
  // formed exactly from the weights |m_{i+1} - m_i| with d|u| = sign(u) du; where a weight
  // is exactly zero (two equal neighbouring secant slopes) the slope is not
  // differentiable in y and the convention sign(0) = 0 is used (docs/splines.md).
  Spline Tangent(const std::vector<double>& dy) const;
  // d(value at x)/d(y_point), and of d1 and d2 (either may be null), exactly
  // (Tangent with the unit vector of `point`). Throws std::out_of_range for a bad point.
  double OrdinateDerivative(double x, int point, double* d1 = nullptr, double* d2 = nullptr) const;

  Interpolation kind() const { return kind_; }
  const std::vector<double>& x() const { return x_; }
  const std::vector<double>& y() const { return y_; }
  bool empty() const { return x_.empty(); }

  // Coefficients of interval i (0 <= i < size - 1): y = y_i + b s + c s^2 + d s^3,
  // s = x - x_i.
  double b(int i) const { return b_[i]; }
  double c(int i) const { return c_[i]; }
  double d(int i) const { return d_[i]; }

  // Throws std::invalid_argument with the reason if (x, y) are not valid points.
  static void Validate(const std::vector<double>& x, const std::vector<double>& y);

 private:
  void Build();
  Interpolation kind_ = Interpolation::kLinear;
  std::vector<double> x_, y_;
  // Per interval i: y = y_i + b_i s + c_i s^2 + d_i s^3, s = x - x_i.
  std::vector<double> b_, c_, d_;
  // End slopes, for the extrapolation.
  double slope_first_ = 0, slope_last_ = 0;
};

// Reads columns of a CSV or whitespace-separated text file: skips header_lines lines,
// then reads column x_column and y_column (0-based) of every other line, except blank
// lines and lines whose first non-blank character is '#'. A line with a comma is split
// at commas (fields trimmed), any other at blanks and tabs. Throws std::runtime_error
// "PATH:LINE: what" on a malformed or non-finite number or a missing column, and
// "PATH: cannot open ..." when the file cannot be read; std::invalid_argument for
// negative header_lines or columns. If `lines` is not null it receives the 1-based line
// number of each point (for messages about the points themselves).
void ReadSplineFile(const std::string& path, int header_lines, int x_column, int y_column,
                    std::vector<double>* x, std::vector<double>* y,
                    std::vector<int>* lines = nullptr);

}  // namespace mbdae::mbs
