// A square sparse matrix whose unknowns fall into nodes that form a forest (every entry
// lies within a node or between a node and its parent), factorised by block elimination
// along the forest with no fill: for node i with parent p, children first,
//   D_i = A_ii - sum over children c of A_ic W_c,   W_i = D_i^-1 A_ip,
// and A x = b is solved by z_i = D_i^-1 (b_i - sum_c A_ic z_c) upwards, then
// x_i = z_i - W_i x_p downwards. The matrix need not be symmetric (A_ip and A_pi are kept
// apart); each D_i is factorised by dense LU with partial pivoting within the node.
//
// Its use: HHT's Newton matrix (dae/hht.h, HhtOptions::linear_solver) of a tree of bodies
// and joints. Its unknowns are the accelerations of the coordinates and the multipliers;
// besides M and C_q it has the blocks of d(C_q^T lambda)/dq and of the forces, which
// couple the two bodies of a joint directly, so the body-joint graph of
// dae/tree_kkt.h (bodies and joints as separate nodes) has a triangle at every joint.
// With every joint merged into the body below it (ForMechanicalSystem) the nodes form a
// tree again: a body with the rows of the joint to its parent. The same elimination order
// as D. Baraff, "Linear-time dynamics using Lagrange multipliers", SIGGRAPH 1996, on the
// merged nodes.
//
// Stability: there is no pivoting across nodes. Factor reports the reciprocal pivot
// ratio min |U_ii| / max |U_ii| over all blocks for the caller to decide on a fallback
// (HHT refactorises with KLU when it is tiny or has dropped, as AccelerationSolver does
// for dae/tree_kkt.h).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "dae/sparse.h"

namespace mbdae::dae {

class BlockTreeLu {
 public:
  // nodes[i]: the unknowns (rows and columns of the square pattern a) of node i, each
  // unknown in exactly one node; parent[i]: the parent node of i, -1 for a root, the
  // graph a forest. Null with the reason in *why when they do not fit a (an entry between
  // nodes that are not parent and child, an unknown in no node or in two, a cycle) or a
  // node has more than max_node_size unknowns.
  static std::unique_ptr<BlockTreeLu> Analyze(const CscPattern& a,
                                              const std::vector<std::vector<int>>& nodes,
                                              const std::vector<int>& parent, int max_node_size,
                                              std::string* why);
  // The nodes of a mechanical system's Newton-type matrix a (unknowns: nq coordinates,
  // then nc multipliers) from the patterns of M and C_q: the bodies and joints of
  // BodyJointForest (dae/tree_kkt.h), each joint merged into the one body below it. Null
  // with the reason when the forest does not exist, a joint couples more than two bodies,
  // or a does not fit the merged nodes (e.g. a force between bodies that no joint joins).
  // The unknowns of coordinate j are j + o for every o in coordinate_offsets, those of
  // constraint row r are r + o for every o in row_offsets: {0} and {nq} (empty: the
  // default) for HHT's (a, lambda); {0, nq} and {2 nq, 2 nq + nc} for IDA's
  // (q, v, lambda, mu) of the stabilised index-2 form.
  static std::unique_ptr<BlockTreeLu> ForMechanicalSystem(
      const CscPattern& a, const CscPattern& mass, const CscPattern& constraint_dq,
      int max_node_size, std::string* why, const std::vector<int>& coordinate_offsets = {0},
      const std::vector<int>& row_offsets = {});
  ~BlockTreeLu();
  BlockTreeLu(const BlockTreeLu&) = delete;
  BlockTreeLu& operator=(const BlockTreeLu&) = delete;

  // Factorises the matrix with these values (the pattern's order). False with a reason
  // when a block has a zero or non-finite pivot; then Solve must not be called.
  bool Factor(const double* values, std::string* error = nullptr);
  // Solves A x = b in place.
  void Solve(double* b) const;
  // min |U_ii| / max |U_ii| over the pivots of every block of the last Factor.
  double rcond() const;
  // The normwise backward error |A x - b|_inf / (|A|_inf |x|_inf + |b|_inf) of the last
  // Factor's solve of one fixed right side b (values: the matrix that was factorised),
  // infinity when not finite: a check of the factors where the pivot ratio says nothing
  // (IDA's index-2 iteration matrix, dae/ida.cc).
  double BackwardError(const double* values) const;
  int num_nodes() const;
  int largest_node() const;
  // Floating-point operations of one Factor and of one Solve, counted from the blocks (a
  // multiply-add as 2): per node with m unknowns and an interface of k, the LU of D_i
  // (sum over the pivots of (m - j - 1) divisions and 2 (m - j - 1)^2), W_i = D_i^-1 A_ip
  // (2 m^2 k) and the update of the parent (2 m k^2); a Solve 2 m^2 + 4 m k per node.
  double factor_flops() const;
  double solve_flops() const;

 private:
  BlockTreeLu();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mbdae::dae
