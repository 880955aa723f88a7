// The acceleration-level matrix K = [M C_q^T; C_q 0] of a system whose bodies and joints
// form a tree, factorised by block elimination along the tree with no fill.
//
// Nodes: a body is a connected component of the pattern of M (its coordinates), merged
// with the components all of whose constraint rows also touch it (a diagonal
// translational block goes with the block of the Euler parameters of the same body),
// with the constraint rows that touch it alone (e.g. its Euler-parameter normalisation, a
// joint to the ground); a joint node is the constraint rows that touch the same set of
// two or more bodies. A joint node is adjacent to the bodies it touches; when this graph
// is a forest, eliminating every node after its children (children first, the root last)
// creates no fill, and K = L D L^T with dense blocks: for node i with parent p,
//   D_i = K_ii - sum over children c of K_ic D_c^-1 K_ci,   W_i = D_i^-1 K_ip,
// and K x = b is solved by z_i = D_i^-1 (b_i - sum_c K_ic z_c) upwards, then
// x_i = z_i - W_i x_p downwards (D. Baraff, "Linear-time dynamics using Lagrange
// multipliers", SIGGRAPH 1996: the same elimination order on the body-joint graph). The
// cost is linear in the number of bodies (bench/bench_kkt.cc: 2.5 times faster than
// KLU's refactorisation + solve on a chain of 1000 rods). The ground is no node: a loop
// closed through it (two bodies each jointed to the ground and to each other) looks like
// a tree here and shows as a zero pivot in Factor.
//
// Each D_i is factorised by dense LU with partial pivoting (rows within the block only);
// a body's block [M_b c_b^T; c_b 0] is nonsingular when M_b is positive definite on the
// null space of its own rows c_b (Euler parameters: the normalisation row covers the
// direction M_b lacks). There is no pivoting across nodes: Analyze refuses patterns
// that are not trees (closed loops, a constraint row that touches no coordinate, a node
// larger than max_node_size), and Factor reports the reciprocal pivot ratio
// min |U_ii| / max |U_ii| over all blocks (the measure klu_rcond gives for KLU's factors)
// for the caller to decide on a fallback (dae/consistent.h AccelerationSolver).
#pragma once

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "dae/sparse.h"

namespace mbdae::dae {

// The body-joint graph of a system, from the patterns of M (nq x nq) and C_q (nc x nq) as
// described above: nodes 0..num_bodies-1 are the bodies, the others the joints; vars[i]
// the unknowns of node i (coordinate j as j, constraint row r as nq + r); parent[i] the
// neighbour of node i towards its tree's root (-1: a root, always a body); order every
// node breadth-first from the roots (parents before children); largest the most
// unknowns of a node. Find returns false with the reason in *why when the graph is not a
// forest or a constraint row touches no coordinate.
struct BodyJointForest {
  int num_bodies = 0;
  std::vector<std::vector<int>> vars;
  std::vector<int> parent;
  std::vector<int> order;
  int largest = 0;

  static bool Find(const CscPattern& mass, const CscPattern& constraint_dq,
                   BodyJointForest* forest, std::string* why);
};

// When a tree elimination's factorisation is used (AccelerationSolver with
// TreeKktSolver, HHT with BlockTreeLu; the caller factorises by KLU otherwise): its pivot
// ratio rcond() above kMinRcond and not below kDrop times that of the first factorisation
// that passed. seen_usable(): one has passed (a first one that fails means the tree is no
// use for this system, e.g. a loop closed through the ground).
class TreePivotRule {
 public:
  static constexpr double kMinRcond = 1e-14;
  static constexpr double kDrop = 1e-6;
  bool Accept(double rcond) {
    if (first_ == 0 && rcond > kMinRcond) first_ = rcond;
    return std::isfinite(rcond) && rcond > kMinRcond && rcond > kDrop * first_;
  }
  bool seen_usable() const { return first_ > 0; }

 private:
  double first_ = 0;
};

class TreeKktSolver {
 public:
  // The tree structure of K from the patterns of M (nq x nq) and C_q (nc x nq), or null
  // with the reason in *why when there is none (see above).
  static std::unique_ptr<TreeKktSolver> Analyze(const CscPattern& mass,
                                                const CscPattern& constraint_dq,
                                                int max_node_size, std::string* why);
  ~TreeKktSolver();
  TreeKktSolver(const TreeKktSolver&) = delete;
  TreeKktSolver& operator=(const TreeKktSolver&) = delete;

  // Factorises K with these values of M and C_q (their patterns' order). False with a
  // reason when a block has a zero or non-finite pivot (the matrix or the elimination
  // order is singular); then Solve must not be called.
  bool Factor(const double* mass, const double* constraint_dq, std::string* error = nullptr);
  // Solves K x = b in place (b: nq + nc entries, a then lambda).
  void Solve(double* b) const;
  // min |U_ii| / max |U_ii| over the pivots of every block of the last Factor.
  double rcond() const;
  int num_nodes() const;
  int largest_node() const;

 private:
  TreeKktSolver();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mbdae::dae
