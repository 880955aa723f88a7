#include "dae/sparse.h"

#include <algorithm>
#include <cassert>
#include <limits>
#include <stdexcept>
#include <string>

namespace mbdae::dae {

int CscPattern::find(int r, int c) const {
  if (c < 0 || c >= cols || r < 0 || r >= rows) return -1;
  const auto begin = row_index.begin() + col_start[c];
  const auto end = row_index.begin() + col_start[c + 1];
  const auto it = std::lower_bound(begin, end, r);
  if (it == end || *it != r) return -1;
  return static_cast<int>(it - row_index.begin());
}

bool CscPattern::IsValid(std::string* error) const {
  auto fail = [&](const std::string& why) {
    if (error) *error = why;
    return false;
  };
  if (rows < 0 || cols < 0) return fail("negative dimensions");
  if (col_start.size() != static_cast<size_t>(cols) + 1)
    return fail("col_start has " + std::to_string(col_start.size()) + " entries, expected " +
                std::to_string(static_cast<long long>(cols) + 1));
  if (col_start[0] != 0) return fail("col_start[0] is not 0");
  if (col_start[cols] != nnz())
    return fail("col_start[cols] = " + std::to_string(col_start[cols]) + " but nnz = " +
                std::to_string(nnz()));
  for (int c = 0; c < cols; ++c) {
    if (col_start[c + 1] < col_start[c])
      return fail("col_start decreases at column " + std::to_string(c));
    for (int k = col_start[c]; k < col_start[c + 1]; ++k) {
      const int r = row_index[k];
      if (r < 0 || r >= rows)
        return fail("row index " + std::to_string(r) + " out of range in column " +
                    std::to_string(c));
      if (k > col_start[c] && row_index[k - 1] >= r)
        return fail("row indices not strictly increasing in column " + std::to_string(c));
    }
  }
  return true;
}

CscPattern CscPattern::FromEntries(int rows, int cols,
                                   const std::vector<std::pair<int, int>>& entries) {
  if (rows < 0 || cols < 0) throw std::invalid_argument("CscPattern::FromEntries: negative size");
  // col_start has cols + 1 entries, indexed by int.
  if (cols == std::numeric_limits<int>::max())
    throw std::invalid_argument("CscPattern::FromEntries: " + std::to_string(cols) +
                                " columns are too many (col_start needs cols + 1 entries)");
  // Entries are counted in int.
  if (entries.size() > static_cast<size_t>(std::numeric_limits<int>::max()))
    throw std::invalid_argument("CscPattern::FromEntries: " + std::to_string(entries.size()) +
                                " entries are too many (at most 2^31 - 1)");
  for (const auto& e : entries)
    if (e.first < 0 || e.first >= rows || e.second < 0 || e.second >= cols)
      throw std::invalid_argument("CscPattern::FromEntries: entry (" + std::to_string(e.first) +
                                  ", " + std::to_string(e.second) + ") outside " +
                                  std::to_string(rows) + " x " + std::to_string(cols));
  const int n = static_cast<int>(entries.size());
  CscPattern p;
  p.rows = rows;
  p.cols = cols;
  // 1. The rows bucketed by column (a counting sort: col_start counts the entries of
  //    every column, then says where its bucket starts).
  p.col_start.assign(static_cast<size_t>(cols) + 1, 0);
  for (const auto& e : entries) ++p.col_start[e.second + 1];
  for (int c = 0; c < cols; ++c) p.col_start[c + 1] += p.col_start[c];
  std::vector<int> row(n);
  {
    std::vector<int> next(p.col_start.begin(), p.col_start.end() - 1);
    for (const auto& e : entries) row[next[e.second]++] = e.first;
  }
  // 2. Every column sorted (insertion sort for the short columns of multibody matrices)
  //    and its duplicates merged, moved down in place.
  int out = 0;
  for (int c = 0; c < cols; ++c) {
    int* const first = row.data() + p.col_start[c];
    int* const last = row.data() + p.col_start[c + 1];
    if (last - first > 32) {
      std::sort(first, last);
    } else {
      for (int* i = first + 1; i < last; ++i) {
        const int x = *i;
        int* j = i;
        for (; j > first && *(j - 1) > x; --j) *j = *(j - 1);
        *j = x;
      }
    }
    p.col_start[c] = out;
    for (const int* i = first; i < last; ++i)
      if (i == first || *i != *(i - 1)) row[out++] = *i;
  }
  p.col_start[cols] = out;
  row.resize(out);
  if (static_cast<size_t>(out) < row.capacity() / 2) row.shrink_to_fit();
  p.row_index = std::move(row);
  return p;
}

void MultiplyAdd(const CscPattern& p, const double* val, double alpha, const double* x,
                 double* y) {
  for (int c = 0; c < p.cols; ++c) {
    const double xc = alpha * x[c];
    if (xc == 0.0) continue;
    for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) y[p.row_index[k]] += val[k] * xc;
  }
}

void MultiplyTransposeAdd(const CscPattern& p, const double* val, double alpha, const double* x,
                          double* y) {
  for (int c = 0; c < p.cols; ++c) {
    double s = 0;
    for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) s += val[k] * x[p.row_index[k]];
    y[c] += alpha * s;
  }
}

int BlockAssembler::AddBlock(const CscPattern& p, int row_offset, int col_offset,
                             bool transpose) {
  assert(!finalized_);
  Block b;
  b.entries.reserve(p.nnz());
  for (int c = 0; c < p.cols; ++c)
    for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) {
      const int r = p.row_index[k];
      if (transpose)
        b.entries.push_back({row_offset + c, col_offset + r});
      else
        b.entries.push_back({row_offset + r, col_offset + c});
    }
  blocks_.push_back(std::move(b));
  return static_cast<int>(blocks_.size()) - 1;
}

int BlockAssembler::AddEntries(const std::vector<std::pair<int, int>>& entries) {
  assert(!finalized_);
  Block b;
  b.entries = entries;
  blocks_.push_back(std::move(b));
  return static_cast<int>(blocks_.size()) - 1;
}

void BlockAssembler::Finalize(int rows, int cols) {
  std::vector<std::pair<int, int>> all;
  size_t total = 0;
  for (const auto& b : blocks_) total += b.entries.size();
  all.reserve(total);
  for (const auto& b : blocks_) all.insert(all.end(), b.entries.begin(), b.entries.end());
  pattern_ = CscPattern::FromEntries(rows, cols, all);  // throws if out of range
  maps_.assign(blocks_.size(), {});
  for (size_t i = 0; i < blocks_.size(); ++i) {
    auto& m = maps_[i];
    m.resize(blocks_[i].entries.size());
    for (size_t k = 0; k < m.size(); ++k) {
      m[k] = pattern_.find(blocks_[i].entries[k].first, blocks_[i].entries[k].second);
      assert(m[k] >= 0);
    }
  }
  finalized_ = true;
}

void BlockAssembler::Accumulate(int block, const double* block_values, double scale,
                                double* values) const {
  assert(finalized_);
  assert(block >= 0 && block < static_cast<int>(maps_.size()));
  const std::vector<int>& m = maps_[block];
  const int n = static_cast<int>(m.size());
  for (int k = 0; k < n; ++k) values[m[k]] += scale * block_values[k];
}

}  // namespace mbdae::dae
