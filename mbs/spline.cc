// Interpolating splines: coefficients per interval, evaluation by binary search, and the
// reader of spline data files. The rules are stated in spline.h and docs/splines.md.
#include "mbs/spline.h"

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "dae/format.h"

namespace mbdae::mbs {

namespace {

std::string Num(double v) { return std::isnan(v) ? "nan" : FormatG(v, 17); }

}  // namespace

const char* InterpolationName(Interpolation kind) {
  switch (kind) {
    case Interpolation::kLinear: return "linear";
    case Interpolation::kCubic: return "cubic";
    case Interpolation::kAkima: return "akima";
  }
  return "?";
}

Spline::Spline(std::vector<double> x, std::vector<double> y, Interpolation kind) : kind_(kind) {
  SetPoints(std::move(x), std::move(y));
}

void Spline::Validate(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.size() != y.size()) {
    throw std::invalid_argument("x has " + std::to_string(x.size()) + " entries but y has " +
                                std::to_string(y.size()) + "; they must have the same number");
  }
  if (x.size() < 2) {
    throw std::invalid_argument("a spline needs at least 2 points, got " + std::to_string(x.size()));
  }
  for (size_t k = 0; k < x.size(); ++k) {
    if (!std::isfinite(x[k])) throw std::invalid_argument("x[" + std::to_string(k) + "] is " + Num(x[k]) + ", not finite");
    if (!std::isfinite(y[k])) throw std::invalid_argument("y[" + std::to_string(k) + "] is " + Num(y[k]) + ", not finite");
  }
  for (size_t k = 1; k < x.size(); ++k) {
    if (!(x[k] > x[k - 1])) {
      throw std::invalid_argument("x must be strictly increasing: x[" + std::to_string(k) + "] = " + Num(x[k]) +
                                  " is not greater than x[" + std::to_string(k - 1) + "] = " + Num(x[k - 1]));
    }
  }
}

void Spline::SetPoints(std::vector<double> x, std::vector<double> y) {
  Validate(x, y);  // before anything changes: a failed call leaves the spline as it was
  x_ = std::move(x);
  y_ = std::move(y);
  Build();
}

void Spline::Build() {
  const int n = static_cast<int>(x_.size());
  const int intervals = n - 1;
  b_.assign(intervals, 0.0);
  c_.assign(intervals, 0.0);
  d_.assign(intervals, 0.0);
  std::vector<double> h(intervals), m(intervals);  // widths and secant slopes
  for (int i = 0; i < intervals; ++i) {
    h[i] = x_[i + 1] - x_[i];
    m[i] = (y_[i + 1] - y_[i]) / h[i];
  }

  // With 2 points every kind is the chord (see spline.h).
  if (kind_ == Interpolation::kLinear || n == 2) {
    for (int i = 0; i < intervals; ++i) b_[i] = m[i];
  } else if (kind_ == Interpolation::kCubic) {
    // Natural cubic spline: second derivatives M_i with M_0 = M_{n-1} = 0 and, for
    // i = 1 .. n-2 (continuity of the first derivative),
    //   h_{i-1} M_{i-1} + 2 (h_{i-1} + h_i) M_i + h_i M_{i+1} = 6 (m_i - m_{i-1}).
    // The system is symmetric, tridiagonal and strictly diagonally dominant: the Thomas
    // algorithm (Gaussian elimination without pivoting) is stable for it.
    std::vector<double> M(n, 0.0), diag(n, 0.0), rhs(n, 0.0);
    for (int i = 1; i < n - 1; ++i) {
      diag[i] = 2 * (h[i - 1] + h[i]);
      rhs[i] = 6 * (m[i] - m[i - 1]);
    }
    for (int i = 2; i < n - 1; ++i) {  // forward elimination of the sub-diagonal h_{i-1}
      const double f = h[i - 1] / diag[i - 1];
      diag[i] -= f * h[i - 1];
      rhs[i] -= f * rhs[i - 1];
    }
    for (int i = n - 2; i >= 1; --i) M[i] = (rhs[i] - (i + 1 < n - 1 ? h[i] * M[i + 1] : 0.0)) / diag[i];
    for (int i = 0; i < intervals; ++i) {
      b_[i] = m[i] - h[i] * (2 * M[i] + M[i + 1]) / 6;
      c_[i] = M[i] / 2;
      d_[i] = (M[i + 1] - M[i]) / (6 * h[i]);
    }
  } else {
    // Akima (1970). Secant slopes extended by two on each side (Akima's end rule, the
    // secants continued linearly): m_{-1} = 2 m_0 - m_1, m_{-2} = 2 m_{-1} - m_0, and
    // likewise past the last one. The slope at knot i is
    //   t_i = (|m_{i+1} - m_i| m_{i-1} + |m_{i-1} - m_{i-2}| m_i) / (|m_{i+1} - m_i| + |m_{i-1} - m_{i-2}|),
    // and when both weights are exactly zero (m_{i-2} = m_{i-1} and m_i = m_{i+1}),
    // t_i = (m_{i-1} + m_i) / 2, Akima's rule for that case. Weights that are only
    // nearly zero need no special case: t_i is then a convex combination of m_{i-1}
    // and m_i, computed without cancellation.
    std::vector<double> e(intervals + 4);  // e[k + 2] = m_k, k = -2 .. n
    for (int i = 0; i < intervals; ++i) e[i + 2] = m[i];
    e[1] = 2 * e[2] - e[3];
    e[0] = 2 * e[1] - e[2];
    e[intervals + 2] = 2 * e[intervals + 1] - e[intervals];
    e[intervals + 3] = 2 * e[intervals + 2] - e[intervals + 1];
    std::vector<double> t(n);
    for (int i = 0; i < n; ++i) {
      const double m_im2 = e[i], m_im1 = e[i + 1], m_i = e[i + 2], m_ip1 = e[i + 3];
      const double w_left = std::abs(m_ip1 - m_i), w_right = std::abs(m_im1 - m_im2);
      const double den = w_left + w_right;
      t[i] = den == 0 ? 0.5 * (m_im1 + m_i) : (w_left * m_im1 + w_right * m_i) / den;
    }
    // Cubic Hermite on each interval with end slopes t_i, t_{i+1}.
    for (int i = 0; i < intervals; ++i) {
      b_[i] = t[i];
      c_[i] = (3 * m[i] - 2 * t[i] - t[i + 1]) / h[i];
      d_[i] = (t[i] + t[i + 1] - 2 * m[i]) / (h[i] * h[i]);
    }
  }
  slope_first_ = b_[0];
  const int l = intervals - 1;
  slope_last_ = b_[l] + h[l] * (2 * c_[l] + 3 * d_[l] * h[l]);
}

double Spline::Evaluate(double x, double* d1, double* d2) const {
  assert(!x_.empty() && "Spline::Evaluate on a spline without points");
  const int n = static_cast<int>(x_.size());
  if (x < x_[0] || x > x_[n - 1]) {
    const bool before = x < x_[0];
    const double slope = before ? slope_first_ : slope_last_;
    const double end = before ? y_[0] : y_[n - 1];
    if (d1) *d1 = slope;
    if (d2) *d2 = 0;
    return end + slope * (x - (before ? x_[0] : x_[n - 1]));
  }
  // Interval i with x_i <= x < x_{i+1}; the last knot belongs to the last interval.
  int i = static_cast<int>(std::upper_bound(x_.begin(), x_.end(), x) - x_.begin()) - 1;
  i = std::clamp(i, 0, n - 2);
  const double s = x - x_[i];
  const double b = b_[i], c = c_[i], d = d_[i];
  if (d1) *d1 = b + s * (2 * c + 3 * d * s);
  if (d2) *d2 = 2 * c + 6 * d * s;
  return y_[i] + s * (b + s * (c + d * s));
}

double Spline::ThirdDerivative(double x) const {
  assert(!x_.empty());
  const int n = static_cast<int>(x_.size());
  if (x < x_[0] || x > x_[n - 1]) return 0;
  int i = static_cast<int>(std::upper_bound(x_.begin(), x_.end(), x) - x_.begin()) - 1;
  i = std::clamp(i, 0, n - 2);
  return 6 * d_[i];
}

Spline Spline::Tangent(const std::vector<double>& dy) const {
  assert(!x_.empty());
  if (dy.size() != x_.size()) {
    throw std::invalid_argument("Spline::Tangent: " + std::to_string(dy.size()) + " ordinate directions for " +
                                std::to_string(x_.size()) + " points");
  }
  Spline t;
  t.kind_ = kind_;
  t.x_ = x_;
  t.y_ = dy;
  const int n = static_cast<int>(x_.size());
  if (kind_ != Interpolation::kAkima || n == 2) {
    t.Build();  // linear in y: the tangent is the spline through (x, dy)
    return t;
  }
  // Akima: the derivative of Build's formulas along dy (same order of operations).
  const int intervals = n - 1;
  std::vector<double> h(intervals), m(intervals), dm(intervals);
  for (int i = 0; i < intervals; ++i) {
    h[i] = x_[i + 1] - x_[i];
    m[i] = (y_[i + 1] - y_[i]) / h[i];
    dm[i] = (dy[i + 1] - dy[i]) / h[i];
  }
  std::vector<double> e(intervals + 4), de(intervals + 4);
  for (int i = 0; i < intervals; ++i) {
    e[i + 2] = m[i];
    de[i + 2] = dm[i];
  }
  auto extend = [intervals](std::vector<double>& v) {
    v[1] = 2 * v[2] - v[3];
    v[0] = 2 * v[1] - v[2];
    v[intervals + 2] = 2 * v[intervals + 1] - v[intervals];
    v[intervals + 3] = 2 * v[intervals + 2] - v[intervals + 1];
  };
  extend(e);
  extend(de);
  auto sign = [](double u) { return u > 0 ? 1.0 : (u < 0 ? -1.0 : 0.0); };
  std::vector<double> dt(n);
  for (int i = 0; i < n; ++i) {
    const double m_im2 = e[i], m_im1 = e[i + 1], m_i = e[i + 2], m_ip1 = e[i + 3];
    const double d_im2 = de[i], d_im1 = de[i + 1], d_i = de[i + 2], d_ip1 = de[i + 3];
    const double w_left = std::abs(m_ip1 - m_i), w_right = std::abs(m_im1 - m_im2);
    const double dw_left = sign(m_ip1 - m_i) * (d_ip1 - d_i);
    const double dw_right = sign(m_im1 - m_im2) * (d_im1 - d_im2);
    const double den = w_left + w_right;
    if (den == 0) {
      dt[i] = 0.5 * (d_im1 + d_i);
    } else {
      const double num = w_left * m_im1 + w_right * m_i;
      const double dnum = dw_left * m_im1 + w_left * d_im1 + dw_right * m_i + w_right * d_i;
      dt[i] = (dnum - num / den * (dw_left + dw_right)) / den;
    }
  }
  t.b_.assign(intervals, 0.0);
  t.c_.assign(intervals, 0.0);
  t.d_.assign(intervals, 0.0);
  for (int i = 0; i < intervals; ++i) {
    t.b_[i] = dt[i];
    t.c_[i] = (3 * dm[i] - 2 * dt[i] - dt[i + 1]) / h[i];
    t.d_[i] = (dt[i] + dt[i + 1] - 2 * dm[i]) / (h[i] * h[i]);
  }
  t.slope_first_ = t.b_[0];
  const int l = intervals - 1;
  t.slope_last_ = t.b_[l] + h[l] * (2 * t.c_[l] + 3 * t.d_[l] * h[l]);
  return t;
}

double Spline::OrdinateDerivative(double x, int point, double* d1, double* d2) const {
  if (point < 0 || point >= static_cast<int>(x_.size())) {
    throw std::out_of_range("Spline::OrdinateDerivative: point " + std::to_string(point) + " of " +
                            std::to_string(x_.size()));
  }
  std::vector<double> dy(x_.size(), 0.0);
  dy[point] = 1;
  return Tangent(dy).Evaluate(x, d1, d2);
}

// ---- data files ---------------------------------------------------------------------------

namespace {

std::string Trim(const std::string& s) {
  const char* blank = " \t\r\n\f\v";
  const size_t first = s.find_first_not_of(blank);
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(blank) - first + 1);
}

std::vector<std::string> Fields(const std::string& line) {
  std::vector<std::string> out;
  if (line.find(',') != std::string::npos) {
    std::string field;
    std::istringstream in(line);
    while (std::getline(in, field, ',')) out.push_back(Trim(field));
    if (!line.empty() && line.back() == ',') out.emplace_back();  // a trailing empty field
  } else {
    std::istringstream in(line);
    std::string field;
    while (in >> field) out.push_back(field);
  }
  return out;
}

}  // namespace

void ReadSplineFile(const std::string& path, int header_lines, int x_column, int y_column,
                    std::vector<double>* x, std::vector<double>* y, std::vector<int>* lines) {
  assert(x && y);
  if (header_lines < 0) throw std::invalid_argument("header_lines must be >= 0, got " + std::to_string(header_lines));
  if (x_column < 0) throw std::invalid_argument("x_column must be >= 0, got " + std::to_string(x_column));
  if (y_column < 0) throw std::invalid_argument("y_column must be >= 0, got " + std::to_string(y_column));
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open the spline data file: " + std::strerror(errno));
  x->clear();
  y->clear();
  if (lines) lines->clear();
  std::string line;
  int number = 0;
  const int needed = std::max(x_column, y_column) + 1;
  while (std::getline(in, line)) {
    ++number;
    if (number <= header_lines) continue;
    const std::string text = Trim(line);
    if (text.empty() || text[0] == '#') continue;
    const std::vector<std::string> fields = Fields(text);
    const std::string where = path + ":" + std::to_string(number) + ": ";
    if (static_cast<int>(fields.size()) < needed) {
      throw std::runtime_error(where + "column " + std::to_string(needed - 1) + " (0-based) is missing: the line has " +
                               std::to_string(fields.size()) + " column" + (fields.size() == 1 ? "" : "s"));
    }
    double values[2];
    const int columns[2] = {x_column, y_column};
    for (int k = 0; k < 2; ++k) {
      const std::string& f = fields[columns[k]];
      char* end = nullptr;
      errno = 0;
      const double v = f.empty() ? 0.0 : std::strtod(f.c_str(), &end);
      if (f.empty() || *end != '\0') {
        throw std::runtime_error(where + "column " + std::to_string(columns[k]) + " is '" + f + "', not a number");
      }
      if (!std::isfinite(v)) {
        throw std::runtime_error(where + "column " + std::to_string(columns[k]) + " is '" + f + "', not a finite number");
      }
      values[k] = v;
    }
    x->push_back(values[0]);
    y->push_back(values[1]);
    if (lines) lines->push_back(number);
  }
  if (in.bad()) throw std::runtime_error(path + ": cannot read the spline data file: " + std::strerror(errno));
}

}  // namespace mbdae::mbs
