// Sparse patterns, products and the block assembler against dense references.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include "dae/sparse.h"

namespace mbdae::dae {
namespace {

using Dense = std::vector<std::vector<double>>;

// A random pattern with roughly `density` of the entries, and values; also dense.
struct RandomBlock {
  CscPattern p;
  std::vector<double> val;
  Dense dense;
};

RandomBlock MakeRandom(int rows, int cols, double density, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0, 1), v(-2, 2);
  std::vector<std::pair<int, int>> e;
  for (int c = 0; c < cols; ++c)
    for (int r = 0; r < rows; ++r)
      if (u(rng) < density) e.push_back({r, c});
  // Duplicates must merge.
  if (!e.empty()) e.push_back(e.front());
  RandomBlock b;
  b.p = CscPattern::FromEntries(rows, cols, e);
  b.dense.assign(rows, std::vector<double>(cols, 0.0));
  b.val.resize(b.p.nnz());
  for (int c = 0; c < cols; ++c)
    for (int k = b.p.col_start[c]; k < b.p.col_start[c + 1]; ++k) {
      b.val[k] = v(rng);
      b.dense[b.p.row_index[k]][c] = b.val[k];
    }
  return b;
}

TEST(CscPattern, FromEntriesSortsMergesAndFinds) {
  const CscPattern p = CscPattern::FromEntries(3, 3, {{2, 1}, {0, 0}, {1, 1}, {2, 1}, {0, 2}});
  std::string err;
  ASSERT_TRUE(p.IsValid(&err)) << err;
  EXPECT_EQ(p.nnz(), 4);
  EXPECT_EQ(p.col_start, (std::vector<int>{0, 1, 3, 4}));
  EXPECT_EQ(p.row_index, (std::vector<int>{0, 1, 2, 0}));
  EXPECT_EQ(p.find(0, 0), 0);
  EXPECT_EQ(p.find(1, 1), 1);
  EXPECT_EQ(p.find(2, 1), 2);
  EXPECT_EQ(p.find(0, 2), 3);
  EXPECT_EQ(p.find(1, 0), -1);
  EXPECT_EQ(p.find(5, 0), -1);
  EXPECT_EQ(p.find(0, 7), -1);
}

// The straightforward construction FromEntries replaced (sort by column then row, drop
// duplicates, count per column), as the reference.
CscPattern SortedReference(int rows, int cols, std::vector<std::pair<int, int>> e) {
  std::sort(e.begin(), e.end(), [](const auto& a, const auto& b) {
    return a.second != b.second ? a.second < b.second : a.first < b.first;
  });
  e.erase(std::unique(e.begin(), e.end()), e.end());
  CscPattern p;
  p.rows = rows;
  p.cols = cols;
  p.col_start.assign(cols + 1, 0);
  for (const auto& x : e) {
    p.row_index.push_back(x.first);
    ++p.col_start[x.second + 1];
  }
  for (int c = 0; c < cols; ++c) p.col_start[c + 1] += p.col_start[c];
  return p;
}

// Random entries in random order with many duplicates, empty columns, columns longer
// than the insertion-sort limit (32), no rows or no columns: the same pattern as the
// reference.
TEST(CscPattern, FromEntriesMatchesSortedReference) {
  std::mt19937 rng(2024);
  int long_columns = 0, empty_columns = 0, duplicates = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const int rows = trial % 23 == 0 ? 0 : 1 + static_cast<int>(rng() % (trial % 3 == 0 ? 200 : 12));
    const int cols = trial % 29 == 0 ? 0 : 1 + static_cast<int>(rng() % 40);
    const int n = rows == 0 || cols == 0 ? 0 : static_cast<int>(rng() % (3 * rows * cols / 2 + 1));
    std::vector<std::pair<int, int>> e;
    for (int k = 0; k < n; ++k) {
      // Half of the entries in a few columns: long columns and empty ones.
      const int c = rng() % 2 ? static_cast<int>(rng() % cols) : static_cast<int>(rng() % (1 + cols / 4));
      e.push_back({static_cast<int>(rng() % rows), c});
    }
    const CscPattern ref = SortedReference(rows, cols, e);
    const CscPattern p = CscPattern::FromEntries(rows, cols, e);
    std::string err;
    ASSERT_TRUE(p.IsValid(&err)) << err;
    EXPECT_EQ(p.rows, rows);
    EXPECT_EQ(p.cols, cols);
    ASSERT_EQ(p.col_start, ref.col_start) << "trial " << trial;
    ASSERT_EQ(p.row_index, ref.row_index) << "trial " << trial;
    for (int c = 0; c < cols; ++c) {
      long_columns += ref.col_start[c + 1] - ref.col_start[c] > 32;
      empty_columns += ref.col_start[c + 1] == ref.col_start[c];
    }
    duplicates += static_cast<int>(e.size()) - ref.nnz();
  }
  // The random cases cover what they are meant to.
  EXPECT_GT(long_columns, 20);
  EXPECT_GT(empty_columns, 100);
  EXPECT_GT(duplicates, 1000);
}

TEST(CscPattern, FromEntriesRejectsOutOfRange) {
  EXPECT_THROW(CscPattern::FromEntries(2, 2, {{2, 0}}), std::invalid_argument);
  EXPECT_THROW(CscPattern::FromEntries(2, 2, {{0, -1}}), std::invalid_argument);
}

TEST(CscPattern, IsValidReportsDefects) {
  CscPattern p = CscPattern::FromEntries(3, 2, {{0, 0}, {2, 0}, {1, 1}});
  std::string err;
  EXPECT_TRUE(p.IsValid(&err));
  CscPattern unsorted = p;
  std::swap(unsorted.row_index[0], unsorted.row_index[1]);
  EXPECT_FALSE(unsorted.IsValid(&err));
  EXPECT_NE(err.find("column 0"), std::string::npos) << err;
  CscPattern out = p;
  out.row_index[2] = 3;
  EXPECT_FALSE(out.IsValid(&err));
  CscPattern sizes = p;
  sizes.col_start.pop_back();
  EXPECT_FALSE(sizes.IsValid(&err));
  CscPattern empty;
  EXPECT_TRUE(empty.IsValid(&err));
}

TEST(Sparse, MultiplyAddMatchesDense) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const int rows = 1 + trial % 7, cols = 1 + (3 * trial) % 9;
    RandomBlock b = MakeRandom(rows, cols, 0.4, rng);
    std::uniform_real_distribution<double> v(-1, 1);
    std::vector<double> x(cols), xt(rows), y(rows), yt(cols);
    for (auto& e : x) e = v(rng);
    for (auto& e : xt) e = v(rng);
    for (auto& e : y) e = v(rng);
    for (auto& e : yt) e = v(rng);
    std::vector<double> yref = y, ytref = yt;
    const double alpha = -1.7;
    for (int r = 0; r < rows; ++r)
      for (int c = 0; c < cols; ++c) {
        yref[r] += alpha * b.dense[r][c] * x[c];
        ytref[c] += alpha * b.dense[r][c] * xt[r];
      }
    MultiplyAdd(b.p, b.val.data(), alpha, x.data(), y.data());
    MultiplyTransposeAdd(b.p, b.val.data(), alpha, xt.data(), yt.data());
    for (int r = 0; r < rows; ++r) EXPECT_NEAR(y[r], yref[r], 1e-13);
    for (int c = 0; c < cols; ++c) EXPECT_NEAR(yt[c], ytref[c], 1e-13);
  }
}

// The Newton-matrix layout: [A + s B, C^T; C, D] from random blocks, with a diagonal.
TEST(BlockAssembler, AssemblesRandomBlocksLikeDense) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 10; ++trial) {
    const int n = 3 + trial, m = 1 + trial / 2;
    RandomBlock A = MakeRandom(n, n, 0.3, rng), B = MakeRandom(n, n, 0.3, rng);
    RandomBlock C = MakeRandom(m, n, 0.5, rng), D = MakeRandom(m, m, 0.5, rng);
    BlockAssembler as;
    const int ia = as.AddBlock(A.p, 0, 0);
    const int ib = as.AddBlock(B.p, 0, 0);
    const int ict = as.AddBlock(C.p, 0, n, /*transpose=*/true);
    const int ic = as.AddBlock(C.p, n, 0);
    const int id = as.AddBlock(D.p, n, n);
    std::vector<std::pair<int, int>> diag;
    for (int i = 0; i < n + m; ++i) diag.push_back({i, i});
    const int idiag = as.AddEntries(diag);
    as.Finalize(n + m, n + m);
    std::string err;
    ASSERT_TRUE(as.pattern().IsValid(&err)) << err;
    EXPECT_EQ(as.num_blocks(), 6);

    const double s = 0.37;
    std::vector<double> ones(n + m, 1.0);
    std::vector<double> values(as.pattern().nnz(), 123.0);
    // Assemble twice: the second time must give the same as the first (no leftovers).
    for (int pass = 0; pass < 2; ++pass) {
      as.SetZero(values.data());
      as.Accumulate(ia, A.val.data(), 1.0, values.data());
      as.Accumulate(ib, B.val.data(), s, values.data());
      as.Accumulate(ict, C.val.data(), 1.0, values.data());
      as.Accumulate(ic, C.val.data(), 1.0, values.data());
      as.Accumulate(id, D.val.data(), -2.0, values.data());
      as.Accumulate(idiag, ones.data(), 0.5, values.data());
    }
    Dense ref(n + m, std::vector<double>(n + m, 0.0));
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) ref[r][c] = A.dense[r][c] + s * B.dense[r][c];
    for (int r = 0; r < m; ++r)
      for (int c = 0; c < n; ++c) {
        ref[n + r][c] = C.dense[r][c];
        ref[c][n + r] = C.dense[r][c];
      }
    for (int r = 0; r < m; ++r)
      for (int c = 0; c < m; ++c) ref[n + r][n + c] = -2.0 * D.dense[r][c];
    for (int i = 0; i < n + m; ++i) ref[i][i] += 0.5;
    // Every entry of the result: in the pattern equals the reference, outside is zero.
    for (int r = 0; r < n + m; ++r)
      for (int c = 0; c < n + m; ++c) {
        const int k = as.pattern().find(r, c);
        const double got = k >= 0 ? values[k] : 0.0;
        EXPECT_NEAR(got, ref[r][c], 1e-14) << "entry (" << r << ", " << c << ")";
      }
    // The pattern is exactly the union of the block patterns.
    int expected_nnz = 0;
    for (int r = 0; r < n + m; ++r)
      for (int c = 0; c < n + m; ++c) {
        bool present = r == c;
        if (r < n && c < n) present |= A.p.find(r, c) >= 0 || B.p.find(r, c) >= 0;
        if (r < n && c >= n) present |= C.p.find(c - n, r) >= 0;
        if (r >= n && c < n) present |= C.p.find(r - n, c) >= 0;
        if (r >= n && c >= n) present |= D.p.find(r - n, c - n) >= 0;
        expected_nnz += present;
        EXPECT_EQ(as.pattern().find(r, c) >= 0, present);
      }
    EXPECT_EQ(as.pattern().nnz(), expected_nnz);
    // map() agrees with find().
    for (int k = 0; k < C.p.nnz(); ++k) {
      int col = 0;
      while (C.p.col_start[col + 1] <= k) ++col;
      EXPECT_EQ(as.map(ict)[k], as.pattern().find(col, n + C.p.row_index[k]));
    }
  }
}

TEST(BlockAssembler, FinalizeRejectsBlocksOutsideTheResult) {
  BlockAssembler as;
  as.AddBlock(CscPattern::FromEntries(2, 2, {{1, 1}}), 1, 1);
  EXPECT_THROW(as.Finalize(2, 2), std::invalid_argument);
}

}  // namespace
}  // namespace mbdae::dae
