// Block elimination of a sparse matrix along a forest of nodes (dae/block_tree_lu.h).
#include "dae/block_tree_lu.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include "dae/dense_lu.h"
#include "dae/tree_kkt.h"

namespace mbdae::dae {

namespace {

// Kernels of one node with m unknowns and a parent of p unknowns (MT > 0 and PT >= 0 fix
// them at compile time; MT = 0, PT = -1 take m_rt, p_rt). Row-major blocks:
// d = A_ii (m x m), c = A_ip (m x p), r = A_pi (p x m), w = W_i (m x p).

// d = L U in place, w = d^-1 c, dp -= r w.
template <int MT, int PT>
struct Eliminate {
  static bool Run(int m_rt, int p_rt, double* d, int* piv, const double* c, const double* r,
                  double* w, double* dp, double* umin, double* umax) {
    const int m = MT > 0 ? MT : m_rt;
    const int p = PT >= 0 ? PT : p_rt;
    if (!DenseLu<MT>(d, m, piv, umin, umax)) return false;
    if (p == 0) return true;
    std::copy(c, c + m * p, w);
    DenseLuSolve<MT, PT>(d, m, piv, w, p);
    for (int a = 0; a < p; ++a) {
      const double* ra = r + a * m;
      double* dpa = dp + a * p;
      for (int k = 0; k < m; ++k) {
        const double rak = ra[k];
        if (rak == 0) continue;
        const double* wk = w + k * p;
        for (int b = 0; b < p; ++b) dpa[b] -= rak * wk[b];
      }
    }
    return true;
  }
};

// Upwards: x_i = d^-1 x_i, x_p -= r x_i.
template <int MT, int PT>
struct Forward {
  static void Run(int m_rt, int p_rt, const double* lu, const int* piv, const double* r,
                  double* xi, double* xp) {
    const int m = MT > 0 ? MT : m_rt;
    const int p = PT >= 0 ? PT : p_rt;
    DenseLuSolve<MT, 1>(lu, m, piv, xi, 1);
    for (int a = 0; a < p; ++a) {
      const double* ra = r + a * m;
      double s = 0;
      for (int k = 0; k < m; ++k) s += ra[k] * xi[k];
      xp[a] -= s;
    }
  }
};

// Downwards: x_i -= w x_p.
template <int MT, int PT>
struct Backward {
  static void Run(int m_rt, int p_rt, const double* w, const double* xp, double* xi) {
    const int m = MT > 0 ? MT : m_rt;
    const int p = PT >= 0 ? PT : p_rt;
    for (int k = 0; k < m; ++k) {
      const double* wk = w + k * p;
      double s = 0;
      for (int a = 0; a < p; ++a) s += wk[a] * xp[a];
      xi[k] -= s;
    }
  }
};

using EliminateFn = decltype(&Eliminate<0, -1>::Run);
using ForwardFn = decltype(&Forward<0, -1>::Run);
using BackwardFn = decltype(&Backward<0, -1>::Run);

// Tables of the fixed-size kernels: [m - 1][p] for m in 1..kFixed, p in 0..kFixed.
constexpr int kFixed = 12;
template <template <int, int> class K, int M, int... P>
constexpr auto KernelRow(std::integer_sequence<int, P...>) {
  return std::array<decltype(&K<0, -1>::Run), sizeof...(P)>{&K<M, P>::Run...};
}
template <template <int, int> class K, int... M>
constexpr auto KernelTable(std::integer_sequence<int, M...>) {
  return std::array<std::array<decltype(&K<0, -1>::Run), kFixed + 1>, sizeof...(M)>{
      KernelRow<K, M + 1>(std::make_integer_sequence<int, kFixed + 1>())...};
}
constexpr auto kEliminate = KernelTable<Eliminate>(std::make_integer_sequence<int, kFixed>());
constexpr auto kForward = KernelTable<Forward>(std::make_integer_sequence<int, kFixed>());
constexpr auto kBackward = KernelTable<Backward>(std::make_integer_sequence<int, kFixed>());

}  // namespace

struct BlockTreeLu::Impl {
  struct Node {
    int dim = 0;
    int parent = -1;  // position of the parent in the elimination order; -1: a root
    int pdim = 0;     // the parent's dim
    int x = 0;        // first entry of the node's unknowns in the node-ordered vector
    int d = 0;        // D_i (dim x dim) in values, then A_ip (dim x pdim), A_pi (pdim x dim)
    int w = 0;        // W_i (dim x pdim) in w
    EliminateFn eliminate = &Eliminate<0, -1>::Run;
    ForwardFn forward = &Forward<0, -1>::Run;
    BackwardFn backward = &Backward<0, -1>::Run;
    int c() const { return d + dim * dim; }
    int r() const { return d + dim * dim + dim * pdim; }
  };
  int n = 0;
  std::vector<Node> nodes;  // in elimination order (children before parents)
  std::vector<int> perm;    // node-ordered index -> unknown of A
  std::vector<int> to;      // entry k of A's pattern -> index into values
  std::vector<double> values, w;
  std::vector<int> piv;  // per node: dim entries at nodes[i].x
  mutable std::vector<double> x;
  double rcond = 0;
  int largest = 0;
};

BlockTreeLu::BlockTreeLu() : impl_(std::make_unique<Impl>()) {}
BlockTreeLu::~BlockTreeLu() = default;

std::unique_ptr<BlockTreeLu> BlockTreeLu::Analyze(const CscPattern& a,
                                                  const std::vector<std::vector<int>>& nodes,
                                                  const std::vector<int>& parent,
                                                  int max_node_size, std::string* why) {
  auto refuse = [&](const std::string& reason) {
    if (why) *why = reason;
    return std::unique_ptr<BlockTreeLu>();
  };
  const int n = a.cols;
  if (a.rows != n)
    return refuse("the matrix is " + std::to_string(a.rows) + " x " + std::to_string(n) +
                  ", not square");
  const int nn = static_cast<int>(nodes.size());
  if (static_cast<int>(parent.size()) != nn)
    return refuse(std::to_string(parent.size()) + " parents for " + std::to_string(nn) +
                  " nodes");
  std::vector<int> node_of(n, -1), local(n, 0);
  int largest = 0;
  for (int i = 0; i < nn; ++i) {
    if (nodes[i].empty()) return refuse("node " + std::to_string(i) + " has no unknowns");
    largest = std::max(largest, static_cast<int>(nodes[i].size()));
    for (size_t l = 0; l < nodes[i].size(); ++l) {
      const int u = nodes[i][l];
      if (u < 0 || u >= n) return refuse("unknown " + std::to_string(u) + " out of range");
      if (node_of[u] >= 0)
        return refuse("unknown " + std::to_string(u) + " is in nodes " +
                      std::to_string(node_of[u]) + " and " + std::to_string(i));
      node_of[u] = i;
      local[u] = static_cast<int>(l);
    }
    if (parent[i] < -1 || parent[i] >= nn || parent[i] == i)
      return refuse("node " + std::to_string(i) + " has parent " + std::to_string(parent[i]));
  }
  for (int u = 0; u < n; ++u)
    if (node_of[u] < 0) return refuse("unknown " + std::to_string(u) + " is in no node");
  if (largest > max_node_size)
    return refuse("a node has " + std::to_string(largest) + " unknowns (more than " +
                  std::to_string(max_node_size) + ")");
  // Breadth-first from the roots; a node not reached lies on a cycle of parents.
  std::vector<int> child_start(nn + 1, 0), children(nn);
  for (int i = 0; i < nn; ++i)
    if (parent[i] >= 0) ++child_start[parent[i] + 1];
  for (int i = 0; i < nn; ++i) child_start[i + 1] += child_start[i];
  {
    std::vector<int> fill(child_start.begin(), child_start.end() - 1);
    for (int i = 0; i < nn; ++i)
      if (parent[i] >= 0) children[fill[parent[i]]++] = i;
  }
  std::vector<int> bfs;
  bfs.reserve(nn);
  for (int i = 0; i < nn; ++i)
    if (parent[i] < 0) bfs.push_back(i);
  for (size_t k = 0; k < bfs.size(); ++k)
    for (int j = child_start[bfs[k]]; j < child_start[bfs[k] + 1]; ++j) bfs.push_back(children[j]);
  if (static_cast<int>(bfs.size()) != nn) return refuse("the parents of the nodes form a cycle");

  std::unique_ptr<BlockTreeLu> solver(new BlockTreeLu());
  Impl& m = *solver->impl_;
  m.n = n;
  m.largest = largest;
  std::vector<int> position(nn);
  for (int k = 0; k < nn; ++k) position[bfs[nn - 1 - k]] = k;
  m.nodes.resize(nn);
  m.perm.reserve(n);
  int x = 0, nvalues = 0, nw = 0;
  for (int k = 0; k < nn; ++k) {
    const int i = bfs[nn - 1 - k];
    Impl::Node& node = m.nodes[k];
    node.dim = static_cast<int>(nodes[i].size());
    node.parent = parent[i] < 0 ? -1 : position[parent[i]];
    node.pdim = parent[i] < 0 ? 0 : static_cast<int>(nodes[parent[i]].size());
    node.x = x;
    x += node.dim;
    for (int u : nodes[i]) m.perm.push_back(u);
    node.d = nvalues;
    nvalues += node.dim * node.dim + 2 * node.dim * node.pdim;
    node.w = nw;
    nw += node.dim * node.pdim;
    if (node.dim <= kFixed && node.pdim <= kFixed) {
      node.eliminate = kEliminate[node.dim - 1][node.pdim];
      node.forward = kForward[node.dim - 1][node.pdim];
      node.backward = kBackward[node.dim - 1][node.pdim];
    }
  }
  m.to.resize(a.nnz());
  for (int c = 0; c < n; ++c)
    for (int k = a.col_start[c]; k < a.col_start[c + 1]; ++k) {
      const int r = a.row_index[k];
      const int nr = position[node_of[r]], nc = position[node_of[c]];
      const Impl::Node& row_node = m.nodes[nr];
      const Impl::Node& col_node = m.nodes[nc];
      if (nr == nc)
        m.to[k] = row_node.d + local[r] * row_node.dim + local[c];
      else if (row_node.parent == nc)  // A_ip of the row's node
        m.to[k] = row_node.c() + local[r] * row_node.pdim + local[c];
      else if (col_node.parent == nr)  // A_pi of the column's node
        m.to[k] = col_node.r() + local[r] * col_node.dim + local[c];
      else
        return refuse("entry (" + std::to_string(r) + ", " + std::to_string(c) +
                      ") couples nodes " + std::to_string(node_of[r]) + " and " +
                      std::to_string(node_of[c]) + ", which are not parent and child");
    }
  m.values.assign(nvalues, 0.0);
  m.w.assign(nw, 0.0);
  m.piv.assign(n, 0);
  m.x.assign(n, 0.0);
  return solver;
}

std::unique_ptr<BlockTreeLu> BlockTreeLu::ForMechanicalSystem(const CscPattern& a,
                                                              const CscPattern& mass,
                                                              const CscPattern& cq,
                                                              int max_node_size,
                                                              std::string* why) {
  BodyJointForest f;
  if (!BodyJointForest::Find(mass, cq, &f, why)) return nullptr;
  const int nb = f.num_bodies, nn = static_cast<int>(f.vars.size());
  const int nq = mass.cols;
  std::vector<int> children(nn, 0);
  for (int i = 0; i < nn; ++i)
    if (f.parent[i] >= 0) ++children[f.parent[i]];
  for (int j = nb; j < nn; ++j)
    if (children[j] != 1) {
      if (why)
        *why = "constraint row " + std::to_string(f.vars[j][0] - nq) + " couples " +
               std::to_string(children[j] + 1) + " bodies";
      return nullptr;
    }
  // Body b with the rows of the joint above it (its parent in the forest, a joint unless
  // b is a root); the node above is the body above that joint.
  std::vector<std::vector<int>> nodes(nb);
  std::vector<int> parent(nb, -1);
  for (int b = 0; b < nb; ++b) {
    nodes[b] = f.vars[b];
    const int j = f.parent[b];
    if (j < 0) continue;
    nodes[b].insert(nodes[b].end(), f.vars[j].begin(), f.vars[j].end());
    parent[b] = f.parent[j];
  }
  return Analyze(a, nodes, parent, max_node_size, why);
}

bool BlockTreeLu::Factor(const double* values, std::string* error) {
  Impl& m = *impl_;
  std::fill(m.values.begin(), m.values.end(), 0.0);
  for (size_t k = 0; k < m.to.size(); ++k) m.values[m.to[k]] = values[k];
  double umin = INFINITY, umax = 0;
  double* v = m.values.data();
  for (size_t k = 0; k < m.nodes.size(); ++k) {
    const Impl::Node& node = m.nodes[k];
    double* dp = node.parent < 0 ? nullptr : v + m.nodes[node.parent].d;
    if (!node.eliminate(node.dim, node.pdim, v + node.d, m.piv.data() + node.x, v + node.c(),
                        v + node.r(), m.w.data() + node.w, dp, &umin, &umax)) {
      if (error)
        *error = "block tree elimination: zero pivot in the block of node " +
                 std::to_string(k) + " (" + std::to_string(node.dim) + " unknowns)";
      m.rcond = 0;
      return false;
    }
  }
  m.rcond = m.nodes.empty() ? 1.0 : umin / umax;
  return true;
}

void BlockTreeLu::Solve(double* b) const {
  const Impl& m = *impl_;
  double* x = m.x.data();
  const double* v = m.values.data();
  for (int j = 0; j < m.n; ++j) x[j] = b[m.perm[j]];
  for (const Impl::Node& node : m.nodes)
    node.forward(node.dim, node.pdim, v + node.d, m.piv.data() + node.x, v + node.r(),
                 x + node.x, node.parent < 0 ? nullptr : x + m.nodes[node.parent].x);
  for (auto it = m.nodes.rbegin(); it != m.nodes.rend(); ++it)
    if (it->parent >= 0)
      it->backward(it->dim, it->pdim, m.w.data() + it->w, x + m.nodes[it->parent].x, x + it->x);
  for (int j = 0; j < m.n; ++j) b[m.perm[j]] = x[j];
}

double BlockTreeLu::rcond() const { return impl_->rcond; }
int BlockTreeLu::num_nodes() const { return static_cast<int>(impl_->nodes.size()); }
int BlockTreeLu::largest_node() const { return impl_->largest; }

}  // namespace mbdae::dae
