// Dense LU kernels for the small blocks of the tree eliminations (dae/tree_kkt.cc,
// dae/block_tree_lu.cc); internal to dae/.
#pragma once

#include <algorithm>
#include <cmath>

namespace mbdae::dae {

// The dense kernels are templates on the block sizes: MT, PT > 0 (PT >= 0) fix m and p at
// compile time, so that the loops of the common small blocks unroll (a spherical joint's
// 3 rows, a body's 7 coordinates and normalisation); MT = 0, PT = -1 take m_rt, p_rt.

// In-place LU with partial pivoting of the row-major m x m matrix a: P a = L U, L unit
// lower (below the diagonal), U upper; piv[k] the row swapped with row k at step k.
// Returns false at a zero or non-finite pivot; *umin, *umax take the pivots' magnitudes.
// (Out of line: one unrolled copy per block size, not one per caller.)
template <int MT>
__attribute__((noinline)) bool DenseLu(double* a, int m_rt, int* piv, double* umin, double* umax) {
  const int m = MT > 0 ? MT : m_rt;
#pragma GCC unroll 64
  for (int k = 0; k < m; ++k) {
    int p = k;
    double best = std::abs(a[k * m + k]);
    for (int r = k + 1; r < m; ++r)
      if (std::abs(a[r * m + k]) > best) best = std::abs(a[(p = r) * m + k]);
    piv[k] = p;
    if (!(best > 0) || !std::isfinite(best)) return false;
    if (p != k)
      for (int c = 0; c < m; ++c) std::swap(a[k * m + c], a[p * m + c]);
    *umin = std::min(*umin, best);
    *umax = std::max(*umax, best);
    const double inv = 1.0 / a[k * m + k];
#pragma GCC unroll 64
    for (int r = k + 1; r < m; ++r) {
      double* row = a + r * m;
      const double l = (row[k] *= inv);
      if (l == 0) continue;
      const double* urow = a + k * m;
#pragma GCC unroll 64
      for (int c = k + 1; c < m; ++c) row[c] -= l * urow[c];
    }
  }
  return true;
}

// DenseLuSolve for one right side of a size fixed at compile time (the tree eliminations'
// solves): the same operations in the same order, with the loops unrolled (their
// counters and the zero tests' branches cost as much as the products).
template <int M>
__attribute__((noinline)) void DenseLuSolveOne(const double* lu, const int* piv, double* b) {
#pragma GCC unroll 64
  for (int k = 0; k < M; ++k)
    if (piv[k] != k) std::swap(b[k], b[piv[k]]);
#pragma GCC unroll 64
  for (int k = 0; k < M; ++k) {
    const double bk = b[k];
#pragma GCC unroll 64
    for (int r = k + 1; r < M; ++r) {
      const double l = lu[r * M + k];
      if (l != 0) b[r] -= l * bk;
    }
  }
#pragma GCC unroll 64
  for (int k = M - 1; k >= 0; --k) {
    double bk = b[k];
#pragma GCC unroll 64
    for (int r = k + 1; r < M; ++r) {
      const double u = lu[k * M + r];
      if (u != 0) bk -= u * b[r];
    }
    b[k] = bk * (1.0 / lu[k * M + k]);
  }
}

// Solves (P^T L U) X = B in place for the row-major m x n matrix b.
template <int MT, int NT>
inline void DenseLuSolve(const double* lu, int m_rt, const int* piv, double* b, int n_rt) {
  if constexpr (MT > 0 && NT == 1) {
    DenseLuSolveOne<MT>(lu, piv, b);
    return;
  }
  const int m = MT > 0 ? MT : m_rt;
  const int n = NT >= 0 ? NT : n_rt;
  for (int k = 0; k < m; ++k)
    if (piv[k] != k)
      for (int c = 0; c < n; ++c) std::swap(b[k * n + c], b[piv[k] * n + c]);
  for (int k = 0; k < m; ++k) {
    const double* bk = b + k * n;
    for (int r = k + 1; r < m; ++r) {
      const double l = lu[r * m + k];
      if (l == 0) continue;
      double* br = b + r * n;
      for (int c = 0; c < n; ++c) br[c] -= l * bk[c];
    }
  }
  for (int k = m - 1; k >= 0; --k) {
    double* bk = b + k * n;
    for (int r = k + 1; r < m; ++r) {
      const double u = lu[k * m + r];
      if (u == 0) continue;
      const double* br = b + r * n;
      for (int c = 0; c < n; ++c) bk[c] -= u * br[c];
    }
    const double inv = 1.0 / lu[k * m + k];
    for (int c = 0; c < n; ++c) bk[c] *= inv;
  }
}

}  // namespace mbdae::dae
