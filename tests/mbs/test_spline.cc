// Splines: interpolation of the data, exactness on straight lines, derivatives against
// finite differences inside and outside the range, continuity at the knots, values
// computed by hand, SetPoints, validation and the data-file reader.
#include "mbs/spline.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <new>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "tests/support/count_allocations.h"

namespace mbdae::mbs {
namespace {

const Interpolation kAll[] = {Interpolation::kLinear, Interpolation::kCubic, Interpolation::kAkima};

std::string Name(Interpolation k) { return InterpolationName(k); }

// Irregular, non-monotone data: x_k = k + 0.6 u_k, y_k random in [-1, 1].
void RandomData(std::mt19937& rng, int n, std::vector<double>* x, std::vector<double>* y) {
  std::uniform_real_distribution<double> u(0, 0.6), v(-1, 1);
  x->clear();
  y->clear();
  for (int k = 0; k < n; ++k) {
    x->push_back(k + u(rng));
    y->push_back(v(rng));
  }
}

std::string ErrorOf(std::vector<double> x, std::vector<double> y, Interpolation kind) {
  try {
    Spline s(std::move(x), std::move(y), kind);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

bool Contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

TEST(Spline, ReproducesTheDataPoints) {
  std::mt19937 rng(1);
  for (Interpolation kind : kAll) {
    for (int n : {2, 3, 4, 7, 20}) {
      std::vector<double> x, y;
      RandomData(rng, n, &x, &y);
      const Spline s(x, y, kind);
      for (int k = 0; k < n; ++k) {
        EXPECT_NEAR(s.Evaluate(x[k]), y[k], 1e-14) << Name(kind) << " n=" << n << " k=" << k;
      }
    }
  }
}

TEST(Spline, EveryKindIsExactOnAStraightLine) {
  // y = 3 - 2.5 x on irregular knots: the natural cubic and Akima reproduce it exactly
  // (all second derivatives of the data vanish), inside and outside the range.
  const std::vector<double> x = {-1, -0.3, 0.4, 2, 2.1, 5};
  std::vector<double> y;
  for (double xi : x) y.push_back(3 - 2.5 * xi);
  for (Interpolation kind : kAll) {
    const Spline s(x, y, kind);
    for (double t : {-4.0, -1.0, -0.7, 0.0, 1.3, 2.05, 4.9, 5.0, 9.0}) {
      double d1, d2;
      const double v = s.Evaluate(t, &d1, &d2);
      EXPECT_NEAR(v, 3 - 2.5 * t, 1e-13) << Name(kind) << " at " << t;
      EXPECT_NEAR(d1, -2.5, 1e-13) << Name(kind) << " at " << t;
      EXPECT_NEAR(d2, 0, 1e-12) << Name(kind) << " at " << t;
    }
  }
}

TEST(Spline, NaturalCubicHasZeroSecondDerivativeAtTheEnds) {
  std::mt19937 rng(2);
  std::vector<double> x, y;
  RandomData(rng, 9, &x, &y);
  const Spline s(x, y, Interpolation::kCubic);
  double d2;
  s.Evaluate(x.front(), nullptr, &d2);
  EXPECT_NEAR(d2, 0, 1e-12);
  s.Evaluate(x.back(), nullptr, &d2);
  EXPECT_NEAR(d2, 0, 1e-12);
  s.Evaluate(0.5 * (x[3] + x[4]), nullptr, &d2);
  EXPECT_GT(std::abs(d2), 1e-3);  // not zero elsewhere
}

// d1 against central differences of the value, d2 against central differences of d1,
// at random points inside and outside the range (not within 1e-4 of a knot, where d2
// of the linear and Akima splines jumps).
TEST(Spline, DerivativesMatchFiniteDifferences) {
  std::mt19937 rng(3);
  const double h = 1e-6;
  for (Interpolation kind : kAll) {
    std::vector<double> x, y;
    RandomData(rng, 8, &x, &y);
    const Spline s(x, y, kind);
    std::uniform_real_distribution<double> where(x.front() - 3, x.back() + 3);
    double worst1 = 0, worst2 = 0;
    int outside = 0, tested = 0;
    while (tested < 200) {
      const double t = where(rng);
      bool near_knot = false;
      for (double xk : x) near_knot |= std::abs(t - xk) < 1e-4;
      if (near_knot) continue;
      ++tested;
      outside += (t < x.front() || t > x.back());
      double d1, d2, d1p, d1m;
      s.Evaluate(t, &d1, &d2);
      const double vp = s.Evaluate(t + h, &d1p), vm = s.Evaluate(t - h, &d1m);
      const double fd1 = (vp - vm) / (2 * h), fd2 = (d1p - d1m) / (2 * h);
      worst1 = std::max(worst1, std::abs(fd1 - d1) / (1 + std::abs(d1)));
      worst2 = std::max(worst2, std::abs(fd2 - d2) / (1 + std::abs(d2)));
    }
    EXPECT_GT(outside, 20) << Name(kind);
    EXPECT_LT(worst1, 1e-8) << Name(kind);
    EXPECT_LT(worst2, 1e-7) << Name(kind);
  }
}

// Left and right limits at every interior knot: value and d1 continuous for cubic and
// Akima, d2 too for the natural cubic. Also at the ends, into the extrapolation.
TEST(Spline, CubicAndAkimaAreContinuousAtTheKnots) {
  std::mt19937 rng(4);
  for (Interpolation kind : {Interpolation::kCubic, Interpolation::kAkima}) {
    std::vector<double> x, y;
    RandomData(rng, 10, &x, &y);
    const Spline s(x, y, kind);
    for (size_t k = 1; k + 1 < x.size(); ++k) {
      // The polynomial of interval k-1 at its right end against interval k at its left.
      const double hk = x[k] - x[k - 1];
      const int i = static_cast<int>(k) - 1;
      const double left = y[k - 1] + hk * (s.b(i) + hk * (s.c(i) + hk * s.d(i)));
      const double left_d1 = s.b(i) + hk * (2 * s.c(i) + 3 * s.d(i) * hk);
      const double left_d2 = 2 * s.c(i) + 6 * s.d(i) * hk;
      EXPECT_NEAR(left, y[k], 1e-13) << Name(kind) << " knot " << k;
      EXPECT_NEAR(left_d1, s.b(i + 1), 1e-12) << Name(kind) << " knot " << k;
      if (kind == Interpolation::kCubic) EXPECT_NEAR(left_d2, 2 * s.c(i + 1), 1e-11) << "knot " << k;
      // Through Evaluate, one ulp on each side.
      double d1l, d1r;
      const double vl = s.Evaluate(std::nextafter(x[k], -1e300), &d1l);
      const double vr = s.Evaluate(std::nextafter(x[k], 1e300), &d1r);
      EXPECT_NEAR(vl, vr, 1e-13);
      EXPECT_NEAR(d1l, d1r, 1e-12);
    }
    for (double end : {x.front(), x.back()}) {
      double d1_in, d1_out;
      const double dir = end == x.front() ? -1 : 1;
      const double v_in = s.Evaluate(end, &d1_in);
      const double v_out = s.Evaluate(end + dir * 1e-12, &d1_out);
      EXPECT_NEAR(v_in, v_out, 1e-11);
      EXPECT_NEAR(d1_in, d1_out, 1e-12);
    }
  }
}

// Natural cubic through (0,0), (1,1), (2,0), by hand: the middle second derivative M
// solves 4 M = 6 (m1 - m0) = -12, M = -3; on [0, 1] y = 1.5 s - 0.5 s^3.
TEST(Spline, NaturalCubicThroughThreePointsByHand) {
  const Spline s({0, 1, 2}, {0, 1, 0}, Interpolation::kCubic);
  double d1, d2;
  EXPECT_NEAR(s.Evaluate(0.5, &d1, &d2), 0.6875, 1e-15);
  EXPECT_NEAR(d1, 1.125, 1e-15);
  EXPECT_NEAR(d2, -1.5, 1e-15);
  EXPECT_NEAR(s.Evaluate(1.5, &d1, &d2), 0.6875, 1e-15);
  EXPECT_NEAR(d1, -1.125, 1e-15);
  EXPECT_NEAR(d2, -1.5, 1e-15);
  EXPECT_NEAR(s.Evaluate(1, &d1, &d2), 1, 1e-15);
  EXPECT_NEAR(d1, 0, 1e-15);
  EXPECT_NEAR(d2, -3, 1e-15);
  // Outside: the end value and end slope (1.5 at x = 0, -1.5 at x = 2), d2 = 0.
  EXPECT_NEAR(s.Evaluate(-1, &d1, &d2), -1.5, 1e-15);
  EXPECT_NEAR(d1, 1.5, 1e-15);
  EXPECT_EQ(d2, 0);
  EXPECT_NEAR(s.Evaluate(4, &d1, &d2), -3, 1e-15);
  EXPECT_NEAR(d1, -1.5, 1e-15);
  EXPECT_EQ(d2, 0);
}

// Akima on x = 0..4, y = 0, 0, 1, 1, 1, by hand. Secants m0..m3 = 0, 1, 0, 0; end
// extension m_-1 = 2 m0 - m1 = -1, m_-2 = 2 m_-1 - m0 = -2, m4 = m5 = 0. Slopes
//   t0 = (|m1-m0| m_-1 + |m_-1-m_-2| m0) / (1 + 1) = -0.5
//   t1 = (|m2-m1| m0 + |m0-m_-1| m1) / (1 + 1) = 0.5
//   t2 = (0 * m1 + |m1-m0| m2) / 1 = 0,   t3 = 0,
//   t4: both weights zero, (m3 + m4) / 2 = 0.
// On [1, 2]: b = 0.5, c = 3*1 - 2*0.5 - 0 = 2, d = 0.5 + 0 - 2 = -1.5.
TEST(Spline, AkimaSlopesByHand) {
  const Spline s({0, 1, 2, 3, 4}, {0, 0, 1, 1, 1}, Interpolation::kAkima);
  const double slopes[] = {-0.5, 0.5, 0, 0, 0};
  for (int k = 0; k < 5; ++k) {
    double d1;
    s.Evaluate(k, &d1);
    EXPECT_NEAR(d1, slopes[k], 1e-15) << "knot " << k;
  }
  EXPECT_NEAR(s.b(1), 0.5, 1e-15);
  EXPECT_NEAR(s.c(1), 2, 1e-15);
  EXPECT_NEAR(s.d(1), -1.5, 1e-15);
  double d1, d2;
  EXPECT_NEAR(s.Evaluate(1.5, &d1, &d2), 0.5 * 0.5 + 2 * 0.25 - 1.5 * 0.125, 1e-15);  // 0.5625
  EXPECT_NEAR(d1, 0.5 + 4 * 0.5 - 4.5 * 0.25, 1e-15);
  EXPECT_NEAR(d2, 4 - 9 * 0.5, 1e-15);
  // On [0, 1]: b = -0.5, c = 0.5, d = 0: y(0.5) = -0.125.
  EXPECT_NEAR(s.Evaluate(0.5), -0.125, 1e-15);
  // Akima keeps the flat part flat (no overshoot, unlike the natural cubic).
  EXPECT_NEAR(s.Evaluate(2.5), 1, 1e-15);
  EXPECT_NEAR(s.Evaluate(3.5), 1, 1e-15);
  EXPECT_GT(std::abs(Spline({0, 1, 2, 3, 4}, {0, 0, 1, 1, 1}, Interpolation::kCubic).Evaluate(2.5) - 1), 1e-2);
  // Extrapolation: slope -0.5 before x = 0, 0 after x = 4.
  EXPECT_NEAR(s.Evaluate(-2, &d1, &d2), 1, 1e-15);
  EXPECT_NEAR(d1, -0.5, 1e-15);
  EXPECT_EQ(d2, 0);
  EXPECT_NEAR(s.Evaluate(7, &d1), 1, 1e-15);
  EXPECT_NEAR(d1, 0, 1e-15);
}

// A corner: secants 0, 0, 1, 1. At x = 2 both Akima weights are zero, and the slope is
// the mean of the two secants, 0.5 (Akima's rule for that case).
TEST(Spline, AkimaEqualSlopeDenominatorTakesTheMean) {
  const Spline s({0, 1, 2, 3, 4}, {0, 0, 0, 1, 2}, Interpolation::kAkima);
  double d1;
  s.Evaluate(2, &d1);
  EXPECT_NEAR(d1, 0.5, 1e-15);
  s.Evaluate(1, &d1);
  EXPECT_NEAR(d1, 0, 1e-15);  // t1 = (|m2-m1| m0 + 0 * m1) / 1 = 0
  s.Evaluate(3, &d1);
  EXPECT_NEAR(d1, 1, 1e-15);
  for (double t : {-1.0, 0.5, 1.5, 2.5, 3.5, 6.0}) EXPECT_TRUE(std::isfinite(s.Evaluate(t)));
}

TEST(Spline, LinearIsTheChordAndItsSlopeAtKnotsIsTheRightInterval) {
  const Spline s({0, 1, 3}, {1, 3, 2}, Interpolation::kLinear);
  double d1, d2;
  EXPECT_NEAR(s.Evaluate(0.25, &d1, &d2), 1.5, 1e-15);
  EXPECT_NEAR(d1, 2, 1e-15);
  EXPECT_EQ(d2, 0);
  EXPECT_NEAR(s.Evaluate(2, &d1, &d2), 2.5, 1e-15);
  EXPECT_NEAR(d1, -0.5, 1e-15);
  EXPECT_EQ(d2, 0);
  EXPECT_NEAR(s.Evaluate(1, &d1), 3, 1e-15);  // interior knot: the interval to the right
  EXPECT_NEAR(d1, -0.5, 1e-15);
  EXPECT_NEAR(s.Evaluate(3, &d1), 2, 1e-15);  // last knot: the last interval
  EXPECT_NEAR(d1, -0.5, 1e-15);
  EXPECT_NEAR(s.Evaluate(5, &d1, &d2), 1, 1e-15);  // extrapolated
  EXPECT_NEAR(d1, -0.5, 1e-15);
  EXPECT_EQ(d2, 0);
  EXPECT_NEAR(s.Evaluate(-1), -1, 1e-15);
}

TEST(Spline, TwoPointsGiveTheChordForEveryKind) {
  for (Interpolation kind : kAll) {
    const Spline s({1, 3}, {2, 6}, kind);
    double d1, d2;
    EXPECT_NEAR(s.Evaluate(2.5, &d1, &d2), 5, 1e-15) << Name(kind);
    EXPECT_NEAR(d1, 2, 1e-15);
    EXPECT_EQ(d2, 0);
  }
}

TEST(Spline, SetPointsChangesTheResultsAndKeepsTheKind) {
  Spline s({0, 1, 2}, {0, 1, 0}, Interpolation::kCubic);
  EXPECT_NEAR(s.Evaluate(0.5), 0.6875, 1e-15);
  s.SetPoints({0, 1, 2}, {0, 2, 0});  // twice the values: twice the spline
  EXPECT_EQ(s.kind(), Interpolation::kCubic);
  EXPECT_NEAR(s.Evaluate(0.5), 1.375, 1e-15);
  s.SetPoints({0, 2, 4, 6}, {0, 2, 4, 6});  // other size: the line y = x
  EXPECT_NEAR(s.Evaluate(5.5), 5.5, 1e-14);
  EXPECT_EQ(s.x().size(), 4u);
  // A bad replacement throws and leaves the spline as it was.
  EXPECT_THROW(s.SetPoints({0, 1}, {0}), std::invalid_argument);
  EXPECT_NEAR(s.Evaluate(5.5), 5.5, 1e-14);
  EXPECT_EQ(s.y().size(), 4u);
}

TEST(Spline, EvaluateDoesNotAllocate) {
  std::mt19937 rng(5);
  std::vector<double> x, y;
  RandomData(rng, 50, &x, &y);
  const Spline s(x, y, Interpolation::kAkima);
  double sum = 0, d1, d2;
  const long before = g_allocations;
  for (int k = 0; k < 1000; ++k) sum += s.Evaluate(-5 + 0.06 * k, &d1, &d2);
  EXPECT_EQ(g_allocations, before);
  EXPECT_TRUE(std::isfinite(sum));
}

TEST(Spline, InvalidPointsAreRejectedWithTheReason) {
  EXPECT_TRUE(Contains(ErrorOf({0, 1, 2}, {0, 1}, Interpolation::kAkima), "x has 3 entries but y has 2"));
  EXPECT_TRUE(Contains(ErrorOf({0}, {0}, Interpolation::kLinear), "at least 2 points, got 1"));
  EXPECT_TRUE(Contains(ErrorOf({}, {}, Interpolation::kCubic), "at least 2 points, got 0"));
  EXPECT_TRUE(Contains(ErrorOf({0, 1, 1}, {0, 1, 2}, Interpolation::kCubic),
                       "x must be strictly increasing: x[2] = 1 is not greater than x[1] = 1"));
  EXPECT_TRUE(Contains(ErrorOf({0, 2, 1}, {0, 1, 2}, Interpolation::kLinear), "x[2] = 1 is not greater than x[1] = 2"));
  EXPECT_TRUE(Contains(ErrorOf({0, NAN, 1}, {0, 1, 2}, Interpolation::kLinear), "x[1] is nan, not finite"));
  EXPECT_TRUE(Contains(ErrorOf({0, 1}, {0, INFINITY}, Interpolation::kAkima), "y[1] is inf, not finite"));
}

// ---- data files -------------------------------------------------------------------------

std::string WriteFile(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "spline_test_" + name;
  std::ofstream(path) << text;
  return path;
}

std::string ReadError(const std::string& path, int header, int xc, int yc) {
  std::vector<double> x, y;
  try {
    ReadSplineFile(path, header, xc, yc, &x, &y);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

TEST(SplineFile, CsvWithHeaderCommentsAndBlankLines) {
  const std::string path = WriteFile("a.csv",
                                     "time, height, other\n"
                                     "# a comment\n"
                                     "0, 1.5, 9\n"
                                     "\n"
                                     "  1 ,2.5e-1,8\r\n"
                                     "   # indented comment\n"
                                     "2.5,-3,7\n");
  std::vector<double> x, y;
  std::vector<int> lines;
  ReadSplineFile(path, 1, 0, 1, &x, &y, &lines);
  EXPECT_EQ(x, (std::vector<double>{0, 1, 2.5}));
  EXPECT_EQ(y, (std::vector<double>{1.5, 0.25, -3}));
  EXPECT_EQ(lines, (std::vector<int>{3, 5, 7}));
  // Other columns, either order.
  ReadSplineFile(path, 1, 2, 0, &x, &y);
  EXPECT_EQ(x, (std::vector<double>{9, 8, 7}));
  EXPECT_EQ(y, (std::vector<double>{0, 1, 2.5}));
}

TEST(SplineFile, WhitespaceSeparated) {
  const std::string path = WriteFile("b.txt",
                                     "# x y\n"
                                     "0\t10   20\n"
                                     "  1 11 21\n"
                                     "2 12\t22\n");
  std::vector<double> x, y;
  ReadSplineFile(path, 0, 0, 2, &x, &y);
  EXPECT_EQ(x, (std::vector<double>{0, 1, 2}));
  EXPECT_EQ(y, (std::vector<double>{20, 21, 22}));
  // Two header lines skip the comment and the first data line.
  ReadSplineFile(path, 2, 1, 2, &x, &y);
  EXPECT_EQ(x, (std::vector<double>{11, 12}));
}

TEST(SplineFile, ErrorsNameTheFileAndLine) {
  const std::string bad = WriteFile("bad.csv", "x,y\n0,1\n1,abc\n");
  EXPECT_EQ(ReadError(bad, 1, 0, 1), bad + ":3: column 1 is 'abc', not a number");
  const std::string header_not_skipped = ReadError(bad, 0, 0, 1);
  EXPECT_EQ(header_not_skipped, bad + ":1: column 0 is 'x', not a number");
  const std::string short_line = WriteFile("short.txt", "0 1 2\n1 2\n");
  EXPECT_EQ(ReadError(short_line, 0, 0, 2), short_line + ":2: column 2 (0-based) is missing: the line has 2 columns");
  const std::string empty_field = WriteFile("empty.csv", "0,1\n1,\n");
  EXPECT_EQ(ReadError(empty_field, 0, 0, 1), empty_field + ":2: column 1 is '', not a number");
  const std::string trailing = WriteFile("trailing.txt", "0 1\n1 2x\n");
  EXPECT_EQ(ReadError(trailing, 0, 0, 1), trailing + ":2: column 1 is '2x', not a number");
  const std::string inf = WriteFile("inf.txt", "0 1\n1 1e999\n");
  EXPECT_EQ(ReadError(inf, 0, 0, 1), inf + ":2: column 1 is '1e999', not a finite number");
  const std::string missing = ::testing::TempDir() + "spline_test_no_such_file.csv";
  EXPECT_TRUE(Contains(ReadError(missing, 0, 0, 1), missing + ": cannot open the spline data file"));
  EXPECT_TRUE(Contains(ReadError(bad, -1, 0, 1), "header_lines must be >= 0, got -1"));
  EXPECT_TRUE(Contains(ReadError(bad, 0, -2, 1), "x_column must be >= 0, got -2"));
}

TEST(SplineFile, ReadPointsMakeASpline) {
  const std::string path = WriteFile("c.csv", "s,z\n0,0\n1,1\n2,0\n");
  std::vector<double> x, y;
  ReadSplineFile(path, 1, 0, 1, &x, &y);
  const Spline s(x, y, Interpolation::kCubic);
  EXPECT_NEAR(s.Evaluate(0.5), 0.6875, 1e-15);
}

}  // namespace
}  // namespace mbdae::mbs
