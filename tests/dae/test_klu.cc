// The KLU wrapper against a dense LU solve (Eigen).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "dae/klu_solver.h"

namespace mbdae::dae {
namespace {

// A random sparse, diagonally non-dominant but regular matrix (diagonal always present).
struct Problem {
  CscPattern p;
  std::vector<double> val;
};

Problem MakeProblem(int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<std::pair<int, int>> e;
  for (int i = 0; i < n; ++i) e.push_back({i, i});
  for (int c = 0; c < n; ++c)
    for (int r = 0; r < n; ++r)
      if (u(rng) < 0.2) e.push_back({r, c});
  Problem pr;
  pr.p = CscPattern::FromEntries(n, n, e);
  pr.val.resize(pr.p.nnz());
  return pr;
}

void FillValues(Problem& pr, std::mt19937& rng) {
  std::uniform_real_distribution<double> v(-1, 1);
  for (int c = 0; c < pr.p.cols; ++c)
    for (int k = pr.p.col_start[c]; k < pr.p.col_start[c + 1]; ++k)
      pr.val[k] = v(rng) + (pr.p.row_index[k] == c ? 3.0 : 0.0);
}

Eigen::MatrixXd ToDense(const Problem& pr) {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(pr.p.rows, pr.p.cols);
  for (int c = 0; c < pr.p.cols; ++c)
    for (int k = pr.p.col_start[c]; k < pr.p.col_start[c + 1]; ++k)
      A(pr.p.row_index[k], c) = pr.val[k];
  return A;
}

TEST(KluSolver, SolvesLikeDenseLuOverRefactorisations) {
  std::mt19937 rng(3);
  for (int n : {1, 5, 40}) {
    Problem pr = MakeProblem(n, rng);
    KluSolver klu(pr.p);
    for (int round = 0; round < 4; ++round) {
      FillValues(pr, rng);
      std::string err;
      ASSERT_TRUE(klu.Factor(pr.val.data(), &err)) << err;
      const Eigen::MatrixXd A = ToDense(pr);
      Eigen::VectorXd b = Eigen::VectorXd::Random(n);
      const Eigen::VectorXd xref = A.partialPivLu().solve(b);
      std::vector<double> x(b.data(), b.data() + n);
      klu.Solve(x.data());
      for (int i = 0; i < n; ++i) EXPECT_NEAR(x[i], xref[i], 1e-11 * (1 + std::abs(xref[i])));
      EXPECT_GT(klu.rcond(), 0.0);
      EXPECT_LE(klu.rcond(), 1.0);
    }
    EXPECT_GE(klu.factorizations(), 4);
  }
}

// Refactorisation keeps the first pivot order; when the values change so that the old
// pivot becomes zero the wrapper must notice and pivot again.
TEST(KluSolver, FallsBackToFullFactorisationWhenPivotsGoBad) {
  // [[a, 1], [1, 1]] with a = 2 first (pivot a), then a = 0: refactor with the
  // same pivot order would divide by zero.
  const CscPattern p = CscPattern::FromEntries(2, 2, {{0, 0}, {1, 0}, {0, 1}, {1, 1}});
  KluSolver klu(p);
  std::vector<double> v = {2, 1, 1, 1};  // column major: (0,0), (1,0), (0,1), (1,1)
  ASSERT_TRUE(klu.Factor(v.data()));
  v = {0, 1, 1, 1};
  std::string err;
  ASSERT_TRUE(klu.Factor(v.data(), &err)) << err;
  // A x = b with b = (1, 3): x = (2, 1).
  double b[2] = {1, 3};
  klu.Solve(b);
  EXPECT_NEAR(b[0], 2.0, 1e-14);
  EXPECT_NEAR(b[1], 1.0, 1e-14);
}

TEST(KluSolver, ReportsSingularMatrix) {
  const CscPattern p = CscPattern::FromEntries(3, 3, {{0, 0}, {1, 1}, {2, 2}, {0, 2}});
  KluSolver klu(p);
  std::vector<double> v = {1, 0, 1, 1};  // (1,1) is zero
  std::string err;
  EXPECT_FALSE(klu.Factor(v.data(), &err));
  EXPECT_NE(err.find("singular"), std::string::npos) << err;
  // Recovers with regular values afterwards.
  v = {1, 2, 1, 3};
  ASSERT_TRUE(klu.Factor(v.data(), &err)) << err;
  double b[3] = {1, 2, 3};
  klu.Solve(b);
  // x2 = 1, x1 = 1, x0 + x2 = 1 -> x0 = 0
  EXPECT_NEAR(b[0], 0.0, 1e-14);
  EXPECT_NEAR(b[1], 1.0, 1e-14);
  EXPECT_NEAR(b[2], 1.0, 1e-14);
}

TEST(KluSolver, RejectsNonSquarePattern) {
  EXPECT_THROW(KluSolver(CscPattern::FromEntries(2, 3, {{0, 0}})), std::invalid_argument);
}

}  // namespace
}  // namespace mbdae::dae
