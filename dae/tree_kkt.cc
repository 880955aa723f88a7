// Block elimination of [M C_q^T; C_q 0] along a body-joint tree (dae/tree_kkt.h).
#include "dae/tree_kkt.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <map>
#include <numeric>
#include <tuple>
#include <utility>

#include "dae/dense_lu.h"

namespace mbdae::dae {

namespace {

int FindRoot(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

// One node of the factorisation: D = L U (in place), W = D^-1 K_ip, D_p -= K_ip^T W.
template <int MT, int PT>
bool EliminateNode(int m_rt, int p_rt, double* d, int* piv, const double* c, double* w,
                   double* dp, double* umin, double* umax) {
  const int m = MT > 0 ? MT : m_rt;
  const int p = PT >= 0 ? PT : p_rt;
  if (!DenseLu<MT>(d, m, piv, umin, umax)) return false;
  if (p == 0) return true;
  std::copy(c, c + m * p, w);
  DenseLuSolve<MT, PT>(d, m, piv, w, p);
  for (int r = 0; r < m; ++r) {
    const double* cr = c + r * p;
    const double* wr = w + r * p;
    for (int a = 0; a < p; ++a) {
      const double cra = cr[a];
      if (cra == 0) continue;
      double* dpa = dp + a * p;
      for (int b = 0; b < p; ++b) dpa[b] -= cra * wr[b];
    }
  }
  return true;
}

// Upwards in the solve: z = D^-1 x_i, x_p -= K_ip^T z.
template <int MT, int PT>
void ForwardNode(int m_rt, int p_rt, const double* lu, const int* piv, const double* c,
                 double* xi, double* xp) {
  const int m = MT > 0 ? MT : m_rt;
  const int p = PT >= 0 ? PT : p_rt;
  DenseLuSolve<MT, 1>(lu, m, piv, xi, 1);
  for (int r = 0; r < m; ++r)
    for (int a = 0; a < p; ++a) xp[a] -= c[r * p + a] * xi[r];
}

using EliminateFn = bool (*)(int, int, double*, int*, const double*, double*, double*, double*,
                             double*);
using ForwardFn = void (*)(int, int, const double*, const int*, const double*, double*, double*);

// Fixed-size kernels for blocks of up to kFixed unknowns with parents of up to kFixed.
constexpr int kFixed = 12;
template <int M, int... P>
constexpr std::array<EliminateFn, sizeof...(P)> EliminateRow(std::integer_sequence<int, P...>) {
  return {&EliminateNode<M, P>...};
}
template <int... M>
constexpr std::array<std::array<EliminateFn, kFixed + 1>, sizeof...(M)> EliminateTable(
    std::integer_sequence<int, M...>) {
  return {EliminateRow<M + 1>(std::make_integer_sequence<int, kFixed + 1>())...};
}
template <int M, int... P>
constexpr std::array<ForwardFn, sizeof...(P)> ForwardRow(std::integer_sequence<int, P...>) {
  return {&ForwardNode<M, P>...};
}
template <int... M>
constexpr std::array<std::array<ForwardFn, kFixed + 1>, sizeof...(M)> ForwardTable(
    std::integer_sequence<int, M...>) {
  return {ForwardRow<M + 1>(std::make_integer_sequence<int, kFixed + 1>())...};
}
constexpr auto kEliminate = EliminateTable(std::make_integer_sequence<int, kFixed>());
constexpr auto kForward = ForwardTable(std::make_integer_sequence<int, kFixed>());

}  // namespace

struct TreeKktSolver::Impl {
  struct Node {
    int dim = 0;
    int parent = -1;  // position of the parent in the elimination order; -1: a root
    int pdim = 0;     // the parent's dim
    int x = 0;        // first entry of the node's unknowns in the node-ordered vector
    int d = 0;        // D_i (dim x dim, row-major) in values
    int c = 0;        // K_ip (dim x pdim, row-major) in values
    int w = 0;        // W_i = D_i^-1 K_ip (dim x pdim) in w
    EliminateFn eliminate = &EliminateNode<0, -1>;
    ForwardFn forward = &ForwardNode<0, -1>;
  };
  int n = 0;
  std::vector<Node> nodes;    // in elimination order (children before parents)
  std::vector<int> perm;      // node-ordered index -> index into K's unknowns
  std::vector<int> mass_to;   // mass entry k -> values index
  std::vector<int> cq_to[2];  // C_q entry k -> values index (second: -1 or its mirror)
  std::vector<double> values, w;
  std::vector<int> piv;       // per node: dim entries at nodes[i].x
  mutable std::vector<double> x;
  double rcond = 0;
  int largest = 0;
};

TreeKktSolver::TreeKktSolver() : impl_(std::make_unique<Impl>()) {}
TreeKktSolver::~TreeKktSolver() = default;

bool BodyJointForest::Find(const CscPattern& mass, const CscPattern& cq, BodyJointForest* f,
                           std::string* why) {
  auto refuse = [&](const std::string& reason) {
    if (why) *why = reason;
    return false;
  };
  const int nq = mass.cols, nc = cq.rows;
  if (mass.rows != nq || cq.cols != nq)
    return refuse("the patterns of M (" + std::to_string(mass.rows) + " x " +
                  std::to_string(mass.cols) + ") and C_q (" + std::to_string(cq.rows) + " x " +
                  std::to_string(cq.cols) + ") do not match");
  // Bodies: connected components of the pattern of M.
  std::vector<int> uf(nq);
  std::iota(uf.begin(), uf.end(), 0);
  for (int c = 0; c < nq; ++c)
    for (int k = mass.col_start[c]; k < mass.col_start[c + 1]; ++k) {
      const int a = FindRoot(uf, mass.row_index[k]), b = FindRoot(uf, c);
      if (a != b) uf[std::max(a, b)] = std::min(a, b);
    }
  std::vector<int> comp_of(nq), comp_id(nq, -1), comp_size;
  for (int c = 0; c < nq; ++c) {
    const int r = FindRoot(uf, c);
    if (comp_id[r] < 0) {
      comp_id[r] = static_cast<int>(comp_size.size());
      comp_size.push_back(0);
    }
    comp_of[c] = comp_id[r];
    ++comp_size[comp_of[c]];
  }
  // A body's M may fall apart into several components (a diagonal translational block
  // and the block of its Euler parameters): a component A goes to the component B whose
  // rows include all of A's rows (every constraint that moves A moves B), the one with
  // the fewest rows (the tightest), then the largest; merges go up the order (size,
  // rows, index), so they form no cycle.
  const int ncomp = static_cast<int>(comp_size.size());
  std::vector<std::vector<int>> comp_rows(ncomp), row_comps(nc);
  for (int c = 0; c < nq; ++c)
    for (int k = cq.col_start[c]; k < cq.col_start[c + 1]; ++k) {
      comp_rows[comp_of[c]].push_back(cq.row_index[k]);
      row_comps[cq.row_index[k]].push_back(comp_of[c]);
    }
  for (auto* lists : {&comp_rows, &row_comps})
    for (std::vector<int>& l : *lists) {
      std::sort(l.begin(), l.end());
      l.erase(std::unique(l.begin(), l.end()), l.end());
    }
  auto key = [&](int x) {
    return std::make_tuple(comp_size[x], static_cast<int>(comp_rows[x].size()), x);
  };
  std::vector<int> order(ncomp), merged(ncomp);
  std::iota(order.begin(), order.end(), 0);
  std::iota(merged.begin(), merged.end(), 0);
  std::sort(order.begin(), order.end(), [&](int x, int y) { return key(x) < key(y); });
  for (int a : order) {
    if (comp_rows[a].empty()) continue;
    int best = -1;
    for (int b : row_comps[comp_rows[a].front()]) {
      if (b == a || !(key(a) < key(b)) ||
          !std::includes(comp_rows[b].begin(), comp_rows[b].end(), comp_rows[a].begin(),
                         comp_rows[a].end()))
        continue;
      if (best < 0 || comp_rows[b].size() < comp_rows[best].size() ||
          (comp_rows[b].size() == comp_rows[best].size() && comp_size[b] > comp_size[best]))
        best = b;
    }
    if (best >= 0) merged[a] = best;
  }
  std::vector<int> body_of(nq), body_id(ncomp, -1);
  int nb = 0;
  for (int c = 0; c < nq; ++c) {
    int r = comp_of[c];
    while (merged[r] != r) r = merged[r];
    if (body_id[r] < 0) body_id[r] = nb++;
    body_of[c] = body_id[r];
  }
  // The bodies each constraint row touches.
  std::vector<std::vector<int>> row_bodies(nc);
  for (int c = 0; c < nq; ++c)
    for (int k = cq.col_start[c]; k < cq.col_start[c + 1]; ++k)
      row_bodies[cq.row_index[k]].push_back(body_of[c]);
  // Nodes 0..nb-1: bodies; then one per set of two or more bodies that rows touch.
  std::vector<std::vector<int>> vars(nb);  // unknowns of K (coordinates, nq + row)
  std::vector<std::vector<int>> adjacent(nb);
  for (int c = 0; c < nq; ++c) vars[body_of[c]].push_back(c);
  std::map<std::vector<int>, int> joint_of;
  for (int r = 0; r < nc; ++r) {
    std::vector<int>& b = row_bodies[r];
    std::sort(b.begin(), b.end());
    b.erase(std::unique(b.begin(), b.end()), b.end());
    if (b.empty()) return refuse("constraint row " + std::to_string(r) + " touches no coordinate");
    if (b.size() == 1) {
      vars[b[0]].push_back(nq + r);
      continue;
    }
    auto [it, fresh] = joint_of.emplace(b, static_cast<int>(vars.size()));
    if (fresh) {
      vars.emplace_back();
      adjacent.emplace_back(b);
      for (int body : b) adjacent[body].push_back(it->second);
    }
    vars[it->second].push_back(nq + r);
  }
  const int nn = static_cast<int>(vars.size());
  // A forest: no edge closes a loop.
  std::vector<int> comp(nn);
  std::iota(comp.begin(), comp.end(), 0);
  for (int j = nb; j < nn; ++j)
    for (int b : adjacent[j]) {
      const int a = FindRoot(comp, j), r = FindRoot(comp, b);
      if (a == r)
        return refuse("the bodies and joints form a closed loop (constraint row " +
                      std::to_string(vars[j][0] - nq) + ")");
      comp[a] = r;
    }
  int largest = 0;
  for (int i = 0; i < nn; ++i) largest = std::max(largest, static_cast<int>(vars[i].size()));
  // Breadth-first from the lowest-numbered body of each tree; reversed, every node comes
  // after its children.
  std::vector<int> bfs, parent(nn, -1);
  std::vector<char> seen(nn, 0);
  bfs.reserve(nn);
  for (int root = 0; root < nb; ++root) {
    if (seen[root]) continue;
    seen[root] = 1;
    size_t k = bfs.size();
    bfs.push_back(root);
    for (; k < bfs.size(); ++k) {
      const int i = bfs[k];
      for (int j : adjacent[i])
        if (!seen[j]) {
          seen[j] = 1;
          parent[j] = i;
          bfs.push_back(j);
        }
    }
  }
  assert(static_cast<int>(bfs.size()) == nn);
  f->num_bodies = nb;
  f->vars = std::move(vars);
  f->parent = std::move(parent);
  f->order = std::move(bfs);
  f->largest = largest;
  return true;
}

std::unique_ptr<TreeKktSolver> TreeKktSolver::Analyze(const CscPattern& mass,
                                                      const CscPattern& cq, int max_node_size,
                                                      std::string* why) {
  BodyJointForest f;
  if (!BodyJointForest::Find(mass, cq, &f, why)) return nullptr;
  if (f.largest > max_node_size) {
    if (why)
      *why = "a node has " + std::to_string(f.largest) + " unknowns (more than " +
             std::to_string(max_node_size) + ")";
    return nullptr;
  }
  const int nq = mass.cols, nc = cq.rows;
  const int nn = static_cast<int>(f.vars.size());
  const std::vector<std::vector<int>>& vars = f.vars;
  const std::vector<int>& parent = f.parent;
  const std::vector<int>& bfs = f.order;
  const int largest = f.largest;
  std::unique_ptr<TreeKktSolver> solver(new TreeKktSolver());
  Impl& m = *solver->impl_;
  m.n = nq + nc;
  m.largest = largest;
  std::vector<int> position(nn);
  for (int k = 0; k < nn; ++k) position[bfs[nn - 1 - k]] = k;
  m.nodes.resize(nn);
  std::vector<int> node_of(m.n), local(m.n);
  int x = 0;
  for (int k = 0; k < nn; ++k) {
    const int i = bfs[nn - 1 - k];
    Impl::Node& node = m.nodes[k];
    node.dim = static_cast<int>(vars[i].size());
    node.x = x;
    for (int l = 0; l < node.dim; ++l) {
      node_of[vars[i][l]] = k;
      local[vars[i][l]] = l;
      m.perm.push_back(vars[i][l]);
    }
    x += node.dim;
  }
  int nvalues = 0, nw = 0;
  for (int k = 0; k < nn; ++k) {
    Impl::Node& node = m.nodes[k];
    const int p = parent[bfs[nn - 1 - k]];
    node.parent = p < 0 ? -1 : position[p];
    node.pdim = p < 0 ? 0 : static_cast<int>(vars[p].size());
    node.d = nvalues;
    nvalues += node.dim * node.dim;
    node.c = nvalues;
    nvalues += node.dim * node.pdim;
    node.w = nw;
    nw += node.dim * node.pdim;
    if (node.dim <= kFixed && node.pdim <= kFixed) {
      node.eliminate = kEliminate[node.dim - 1][node.pdim];
      node.forward = kForward[node.dim - 1][node.pdim];
    }
  }
  m.values.assign(nvalues, 0.0);
  m.w.assign(nw, 0.0);
  m.piv.assign(m.n, 0);
  m.x.assign(m.n, 0.0);
  m.mass_to.resize(mass.nnz());
  for (int c = 0; c < nq; ++c)
    for (int k = mass.col_start[c]; k < mass.col_start[c + 1]; ++k) {
      const int r = mass.row_index[k];
      const Impl::Node& node = m.nodes[node_of[c]];
      m.mass_to[k] = node.d + local[r] * node.dim + local[c];
    }
  m.cq_to[0].resize(cq.nnz());
  m.cq_to[1].assign(cq.nnz(), -1);
  for (int c = 0; c < nq; ++c)
    for (int k = cq.col_start[c]; k < cq.col_start[c + 1]; ++k) {
      const int row = nq + cq.row_index[k];
      const int nr = node_of[row], ncol = node_of[c];
      if (nr == ncol) {  // a body's own row: both triangles of its block
        const Impl::Node& node = m.nodes[nr];
        m.cq_to[0][k] = node.d + local[row] * node.dim + local[c];
        m.cq_to[1][k] = node.d + local[c] * node.dim + local[row];
      } else if (m.nodes[nr].parent == ncol) {  // the joint below the body
        const Impl::Node& node = m.nodes[nr];
        m.cq_to[0][k] = node.c + local[row] * node.pdim + local[c];
      } else {  // the body below the joint
        assert(m.nodes[ncol].parent == nr);
        const Impl::Node& node = m.nodes[ncol];
        m.cq_to[0][k] = node.c + local[c] * node.pdim + local[row];
      }
    }
  return solver;
}

bool TreeKktSolver::Factor(const double* mass, const double* cq, std::string* error) {
  Impl& m = *impl_;
  std::fill(m.values.begin(), m.values.end(), 0.0);
  for (size_t k = 0; k < m.mass_to.size(); ++k) m.values[m.mass_to[k]] += mass[k];
  for (size_t k = 0; k < m.cq_to[0].size(); ++k) {
    m.values[m.cq_to[0][k]] += cq[k];
    if (m.cq_to[1][k] >= 0) m.values[m.cq_to[1][k]] += cq[k];
  }
  double umin = INFINITY, umax = 0;
  double* values = m.values.data();
  for (size_t k = 0; k < m.nodes.size(); ++k) {
    const Impl::Node& node = m.nodes[k];
    double* dp = node.parent < 0 ? nullptr : values + m.nodes[node.parent].d;
    if (!node.eliminate(node.dim, node.pdim, values + node.d, m.piv.data() + node.x,
                        values + node.c, m.w.data() + node.w, dp, &umin, &umax)) {
      if (error)
        *error = "tree elimination: zero pivot in the block of node " + std::to_string(k) +
                 " (" + std::to_string(node.dim) + " unknowns)";
      m.rcond = 0;
      return false;
    }
  }
  m.rcond = m.nodes.empty() ? 1.0 : umin / umax;
  return true;
}

void TreeKktSolver::Solve(double* b) const {
  const Impl& m = *impl_;
  double* x = m.x.data();
  for (int j = 0; j < m.n; ++j) x[j] = b[m.perm[j]];
  for (const Impl::Node& node : m.nodes)  // upwards: z_i = D_i^-1 (b_i - sum K_ic z_c)
    node.forward(node.dim, node.pdim, m.values.data() + node.d, m.piv.data() + node.x,
                 m.values.data() + node.c, x + node.x,
                 node.parent < 0 ? nullptr : x + m.nodes[node.parent].x);
  for (auto it = m.nodes.rbegin(); it != m.nodes.rend(); ++it) {  // downwards
    if (it->parent < 0) continue;
    double* xi = x + it->x;
    const double* xp = x + m.nodes[it->parent].x;
    const double* w = m.w.data() + it->w;
    for (int r = 0; r < it->dim; ++r) {
      double s = 0;
      for (int a = 0; a < it->pdim; ++a) s += w[r * it->pdim + a] * xp[a];
      xi[r] -= s;
    }
  }
  for (int j = 0; j < m.n; ++j) b[m.perm[j]] = x[j];
}

double TreeKktSolver::rcond() const { return impl_->rcond; }
int TreeKktSolver::num_nodes() const { return static_cast<int>(impl_->nodes.size()); }
int TreeKktSolver::largest_node() const { return impl_->largest; }

}  // namespace mbdae::dae
