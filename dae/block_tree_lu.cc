// Block elimination of a sparse matrix along a forest of nodes (dae/block_tree_lu.h).
#include "dae/block_tree_lu.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>
#include <vector>

#include "dae/dense_lu.h"
#include "dae/tree_kkt.h"

namespace mbdae::dae {

namespace {

// Kernels of one node with m unknowns coupled to k unknowns of its parent (its
// interface: the parent's unknowns that A_ip or A_pi touch, idx[0..k) their places in the
// parent, whose block has pdim rows; MT > 0 and KT >= 0 fix m and k at compile time,
// MT = 0, KT = -1 take m_rt, k_rt). Row-major blocks: d = A_ii (m x m), c = A_ip on the
// interface (m x k), r = A_pi on the interface (k x m), w = W_i (m x k).

// d = L U in place, w = d^-1 c, dp -= r w on the interface.
template <int MT, int KT>
struct Eliminate {
  static bool Run(int m_rt, int k_rt, double* d, int* piv, const double* c, const double* r,
                  double* w, const int* idx, int pdim, double* dp, double* umin, double* umax) {
    const int m = MT > 0 ? MT : m_rt;
    const int k = KT >= 0 ? KT : k_rt;
    if (!DenseLu<MT>(d, m, piv, umin, umax)) return false;
    if (k == 0) return true;
    std::copy(c, c + m * k, w);
    DenseLuSolve<MT, KT>(d, m, piv, w, k);
    for (int a = 0; a < k; ++a) {
      const double* ra = r + a * m;
      double* dpa = dp + idx[a] * pdim;
      for (int b = 0; b < k; ++b) {
        double s = 0;
        for (int l = 0; l < m; ++l) s += ra[l] * w[l * k + b];
        dpa[idx[b]] -= s;
      }
    }
    return true;
  }
};

// Upwards: x_i = d^-1 x_i, x_p -= r x_i on the interface.
template <int MT, int KT>
struct Forward {
  static void Run(int m_rt, int k_rt, const double* lu, const int* piv, const double* r,
                  const int* idx, double* xi, double* xp) {
    const int m = MT > 0 ? MT : m_rt;
    const int k = KT >= 0 ? KT : k_rt;
    DenseLuSolve<MT, 1>(lu, m, piv, xi, 1);
    for (int a = 0; a < k; ++a) {
      const double* ra = r + a * m;
      double s = 0;
      for (int l = 0; l < m; ++l) s += ra[l] * xi[l];
      xp[idx[a]] -= s;
    }
  }
};

// Downwards: x_i -= w x_p on the interface.
template <int MT, int KT>
struct Backward {
  static void Run(int m_rt, int k_rt, const double* w, const int* idx, const double* xp,
                  double* xi) {
    const int m = MT > 0 ? MT : m_rt;
    const int k = KT >= 0 ? KT : k_rt;
    for (int l = 0; l < m; ++l) {
      const double* wl = w + l * k;
      double s = 0;
      for (int a = 0; a < k; ++a) s += wl[a] * xp[idx[a]];
      xi[l] -= s;
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
    int k = 0;        // the interface: k unknowns of the parent, their places at iface[idx]
    int idx = 0;
    int x = 0;        // first entry of the node's unknowns in the node-ordered vector
    int d = 0;        // D_i (dim x dim) in values, then A_ip (dim x k), A_pi (k x dim)
    int w = 0;        // W_i (dim x k) in w
    EliminateFn eliminate = &Eliminate<0, -1>::Run;
    ForwardFn forward = &Forward<0, -1>::Run;
    BackwardFn backward = &Backward<0, -1>::Run;
    int c() const { return d + dim * dim; }
    int r() const { return d + dim * dim + dim * k; }
  };
  int n = 0;
  std::vector<Node> nodes;  // in elimination order (children before parents)
  std::vector<int> perm;    // node-ordered index -> unknown of A
  std::vector<int> iface;   // per node: its interface's places in the parent's block
  std::vector<int> to;      // entry k of A's pattern -> index into values
  CscPattern pattern;       // A's (BackwardError)
  std::vector<double> check_b;                               // BackwardError's right side
  mutable std::vector<double> check_x, check_r, check_row;  // and its work
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
  int x = 0;
  for (int k = 0; k < nn; ++k) {
    const int i = bfs[nn - 1 - k];
    Impl::Node& node = m.nodes[k];
    node.dim = static_cast<int>(nodes[i].size());
    node.parent = parent[i] < 0 ? -1 : position[parent[i]];
    node.pdim = parent[i] < 0 ? 0 : static_cast<int>(nodes[parent[i]].size());
    node.x = x;
    x += node.dim;
    for (int u : nodes[i]) m.perm.push_back(u);
  }
  // Each entry's block: 0 within a node, 1 A_ip of the row's node, 2 A_pi of the column's
  // node; the interface of each node: the parent's unknowns its A_ip and A_pi touch.
  std::vector<char> kind(a.nnz());
  std::vector<int> pdim_start(nn + 1, 0);
  for (int k = 0; k < nn; ++k) pdim_start[k + 1] = pdim_start[k] + m.nodes[k].pdim;
  std::vector<int> slot(pdim_start[nn], -1);  // per node and parent unknown: interface place
  for (int c = 0; c < n; ++c)
    for (int k = a.col_start[c]; k < a.col_start[c + 1]; ++k) {
      const int r = a.row_index[k];
      const int nr = position[node_of[r]], nc = position[node_of[c]];
      if (nr == nc) {
        kind[k] = 0;
      } else if (m.nodes[nr].parent == nc) {
        kind[k] = 1;
        slot[pdim_start[nr] + local[c]] = 0;
      } else if (m.nodes[nc].parent == nr) {
        kind[k] = 2;
        slot[pdim_start[nc] + local[r]] = 0;
      } else {
        return refuse("entry (" + std::to_string(r) + ", " + std::to_string(c) +
                      ") couples nodes " + std::to_string(node_of[r]) + " and " +
                      std::to_string(node_of[c]) + ", which are not parent and child");
      }
    }
  int nvalues = 0, nw = 0;
  for (int k = 0; k < nn; ++k) {
    Impl::Node& node = m.nodes[k];
    node.idx = static_cast<int>(m.iface.size());
    for (int l = 0; l < node.pdim; ++l)
      if (slot[pdim_start[k] + l] == 0) {
        slot[pdim_start[k] + l] = node.k++;
        m.iface.push_back(l);
      }
    node.d = nvalues;
    nvalues += node.dim * node.dim + 2 * node.dim * node.k;
    node.w = nw;
    nw += node.dim * node.k;
    if (node.dim <= kFixed && node.k <= kFixed) {
      node.eliminate = kEliminate[node.dim - 1][node.k];
      node.forward = kForward[node.dim - 1][node.k];
      node.backward = kBackward[node.dim - 1][node.k];
    }
  }
  m.to.resize(a.nnz());
  for (int c = 0; c < n; ++c)
    for (int k = a.col_start[c]; k < a.col_start[c + 1]; ++k) {
      const int r = a.row_index[k];
      const Impl::Node& row_node = m.nodes[position[node_of[r]]];
      const Impl::Node& col_node = m.nodes[position[node_of[c]]];
      if (kind[k] == 0) {
        m.to[k] = row_node.d + local[r] * row_node.dim + local[c];
      } else if (kind[k] == 1) {
        const int s = slot[pdim_start[position[node_of[r]]] + local[c]];
        m.to[k] = row_node.c() + local[r] * row_node.k + s;
      } else {
        const int s = slot[pdim_start[position[node_of[c]]] + local[r]];
        m.to[k] = col_node.r() + s * col_node.dim + local[c];
      }
    }
  m.values.assign(nvalues, 0.0);
  m.w.assign(nw, 0.0);
  m.piv.assign(n, 0);
  m.x.assign(n, 0.0);
  m.pattern = a;
  m.check_b.resize(n);
  for (int i = 0; i < n; ++i) m.check_b[i] = 1.0 + 0.5 * std::sin(1.0 + i);
  m.check_x.assign(n, 0.0);
  m.check_r.assign(n, 0.0);
  m.check_row.assign(n, 0.0);
  return solver;
}

std::unique_ptr<BlockTreeLu> BlockTreeLu::ForMechanicalSystem(
    const CscPattern& a, const CscPattern& mass, const CscPattern& cq, int max_node_size,
    std::string* why, const std::vector<int>& coordinate_offsets,
    const std::vector<int>& row_offsets) {
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
  // The unknowns of the forest's variable u (coordinate u < nq, row u - nq).
  const std::vector<int> default_rows = {nq};
  const std::vector<int>& rows = row_offsets.empty() ? default_rows : row_offsets;
  auto append = [&](std::vector<int>& node, const std::vector<int>& vars) {
    for (const std::vector<int>* offsets : {&coordinate_offsets, &rows})
      for (int o : *offsets)
        for (int u : vars) {
          if (offsets == &coordinate_offsets && u < nq) node.push_back(u + o);
          if (offsets == &rows && u >= nq) node.push_back(u - nq + o);
        }
  };
  // Body b with the rows of the joint above it (its parent in the forest, a joint unless
  // b is a root); the node above is the body above that joint.
  std::vector<std::vector<int>> nodes(nb);
  std::vector<int> parent(nb, -1);
  for (int b = 0; b < nb; ++b) {
    append(nodes[b], f.vars[b]);
    const int j = f.parent[b];
    if (j < 0) continue;
    append(nodes[b], f.vars[j]);
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
    if (!node.eliminate(node.dim, node.k, v + node.d, m.piv.data() + node.x, v + node.c(),
                        v + node.r(), m.w.data() + node.w, m.iface.data() + node.idx, node.pdim,
                        dp, &umin, &umax)) {
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
    node.forward(node.dim, node.k, v + node.d, m.piv.data() + node.x, v + node.r(),
                 m.iface.data() + node.idx, x + node.x,
                 node.parent < 0 ? nullptr : x + m.nodes[node.parent].x);
  for (auto it = m.nodes.rbegin(); it != m.nodes.rend(); ++it)
    if (it->parent >= 0)
      it->backward(it->dim, it->k, m.w.data() + it->w, m.iface.data() + it->idx,
                   x + m.nodes[it->parent].x, x + it->x);
  for (int j = 0; j < m.n; ++j) b[m.perm[j]] = x[j];
}

double BlockTreeLu::rcond() const { return impl_->rcond; }

double BlockTreeLu::BackwardError(const double* values) const {
  const Impl& m = *impl_;
  const CscPattern& p = m.pattern;
  std::copy(m.check_b.begin(), m.check_b.end(), m.check_x.begin());
  Solve(m.check_x.data());
  std::fill(m.check_r.begin(), m.check_r.end(), 0.0);
  std::fill(m.check_row.begin(), m.check_row.end(), 0.0);
  double xmax = 0;
  for (int c = 0; c < m.n; ++c) {
    xmax = std::max(xmax, std::abs(m.check_x[c]));
    for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) {
      m.check_r[p.row_index[k]] += values[k] * m.check_x[c];
      m.check_row[p.row_index[k]] += std::abs(values[k]);
    }
  }
  double rmax = 0, amax = 0, bmax = 0;
  for (int i = 0; i < m.n; ++i) {
    rmax = std::max(rmax, std::abs(m.check_r[i] - m.check_b[i]));
    amax = std::max(amax, m.check_row[i]);
    bmax = std::max(bmax, std::abs(m.check_b[i]));
  }
  const double e = rmax / (amax * xmax + bmax);
  return std::isfinite(e) ? e : INFINITY;
}
int BlockTreeLu::num_nodes() const { return static_cast<int>(impl_->nodes.size()); }
int BlockTreeLu::largest_node() const { return impl_->largest; }

double BlockTreeLu::factor_flops() const {
  double f = 0;
  for (const Impl::Node& node : impl_->nodes) {
    const double m = node.dim, k = node.k;
    for (int j = 0; j < node.dim; ++j) {
      const double r = node.dim - j - 1;
      f += r + 2 * r * r;
    }
    f += 2 * m * m * k + 2 * m * k * k;
  }
  return f;
}

double BlockTreeLu::solve_flops() const {
  double f = 0;
  for (const Impl::Node& node : impl_->nodes) f += 2.0 * node.dim * node.dim + 4.0 * node.dim * node.k;
  return f;
}

}  // namespace mbdae::dae
