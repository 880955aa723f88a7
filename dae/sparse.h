// Compressed sparse column patterns and matrices, and the block assembler that
// places several sparse blocks (with offsets, scales and transposes) into one
// matrix whose pattern is computed once.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace mbdae::dae {

// Compressed sparse column pattern: row indices of column c are
// row_index[col_start[c] .. col_start[c+1]), sorted ascending, no duplicates.
struct CscPattern {
  int rows = 0;
  int cols = 0;
  std::vector<int> col_start{0};  // size cols + 1
  std::vector<int> row_index;     // size nnz

  int nnz() const { return static_cast<int>(row_index.size()); }
  // Index into the value array of entry (r, c), or -1 if (r, c) is not in the pattern.
  int find(int r, int c) const;
  // Checks sizes, sortedness and bounds; returns false with a reason on failure.
  bool IsValid(std::string* error) const;

  // Builds a pattern from (row, col) pairs (duplicates merged): a counting sort by
  // column, then each column sorted; time O(n + cols + sum of m log m over the columns),
  // n entries and m per column (linear in n when the columns are short), memory
  // O(n + cols) and independent of rows.
  static CscPattern FromEntries(int rows, int cols, const std::vector<std::pair<int, int>>& entries);
};

// y += alpha * A x, A with pattern p and values val.
void MultiplyAdd(const CscPattern& p, const double* val, double alpha, const double* x, double* y);
// y += alpha * A^T x.
void MultiplyTransposeAdd(const CscPattern& p, const double* val, double alpha, const double* x,
                          double* y);

// Places blocks into one matrix. Usage: add blocks, call Finalize() once, then for
// every evaluation: SetZero(values), Accumulate(block, block_values, scale, values).
class BlockAssembler {
 public:
  // Adds block `p` with its (0,0) entry at (row_offset, col_offset) of the result;
  // if `transpose`, p^T is placed there. Returns the block's id.
  int AddBlock(const CscPattern& p, int row_offset, int col_offset, bool transpose = false);
  // Adds explicit entries (e.g. a diagonal) that are always in the pattern.
  int AddEntries(const std::vector<std::pair<int, int>>& entries);
  // Computes the union pattern of size rows x cols and the scatter maps.
  void Finalize(int rows, int cols);

  const CscPattern& pattern() const { return pattern_; }
  // Sets all nnz values of the result to zero.
  void SetZero(double* values) const {
    for (int k = 0; k < pattern_.nnz(); ++k) values[k] = 0.0;
  }
  int num_blocks() const { return static_cast<int>(blocks_.size()); }
  // values[map[block][k]] += scale * block_values[k] for every entry k of the block.
  void Accumulate(int block, const double* block_values, double scale, double* values) const;
  // Position in the result of entry k of a block.
  const std::vector<int>& map(int block) const { return maps_[block]; }

 private:
  struct Block {
    std::vector<std::pair<int, int>> entries;  // (row, col) in the result, in block order
  };
  std::vector<Block> blocks_;
  std::vector<std::vector<int>> maps_;
  CscPattern pattern_;
  bool finalized_ = false;
};

}  // namespace mbdae::dae
