// Seconds per phase of a simulation, for one model file (bench/phases/README.md).
//
//   bench_phases MODEL.yaml [--skip PHASE,...] [--min-calls K]
//
// Prints one JSON object: the sizes, and for every phase the CPU seconds of one call: the
// median of at least K calls (default 3; up to 7 while they take under a budget of
// seconds in all), so that every model size is timed alike, on memory the process has
// touched before ("seconds"); and the first of those calls ("first_call": with the page
// faults of fresh memory, as a run pays them once). Phases, in the order a simulation
// meets them:
//   load         mbs::LoadModel of the file (parse, checks)
//   build        mbs::MultibodySystem of the model (patterns, workspaces)
//   redundancy   dae::FindRedundantConstraints at the initial positions (the rank
//                decision of driver::Assemble: normalisations first)
//   consistent   dae::MakeConsistent of the full system (positions, velocities,
//                redundancy, accelerations)
//   determinacy  driver::UndeterminedBodies of the kept system at the consistent state
//   assemble     driver::Assemble, the whole set-up (build + consistent + determinacy)
//   residual     MultibodySystem::Evaluate of Q, C, C_t and gamma
//   jacobian     MultibodySystem::Evaluate of the seven matrices
//   hht_step     one fixed HHT step (h = 1e-3, the model's other HHT settings), the mean
//                over the steps to t = 0.02 s
//   hht_step_tree  the same with hht: {linear_solver: tree} (dae/block_tree_lu.h)
//   ida_step     one IDA step (rtol = atol = 1e-6), the mean over the steps to 0.02 s
//   ida_step_tree  the same with ida: {linear_solver: tree}
//   row          driver::OutputRowBuilder::Compute of a row (with the model's
//                output_accelerations: by default the acceleration-level solve of the row)
//   create_file  io::ResultsFile of the run's layout and its attributes (once per run)
//   write        io::ResultsFile::AppendRow of a row, written as `mbdae simulate` does
//                (flush interval 0.2 s): the mean over 20 rows and the final flush
// hht_step, hht_step_tree, ida_step, ida_step_tree and write are means over their steps or rows (one run each); the
// phases named in --skip are not run (their value is null).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

#include "dae/consistent.h"
#include "dae/hht.h"
#include "dae/ida.h"
#include "driver/simulation.h"
#include "io/results_file.h"
#include "mbs/loader.h"
#include "mbs/system.h"

namespace {

namespace dae = mbdae::dae;
namespace mbs = mbdae::mbs;
namespace driver = mbdae::driver;
namespace io = mbdae::io;

// CPU seconds of the process (every phase runs on one thread): on a machine shared with
// other work, wall time measures the other work too.
double Now() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

// Seconds of one call of f: the median of at least `min_calls` and up to 7 calls,
// repeated while the calls so far took less than `budget` seconds in all; *first: the
// first call's. `reset` (if given) runs before every call, untimed: it frees what the
// previous call made, so that a call does not pay for its predecessor's destruction.
// (Before, a slow call was not repeated: small models were timed on memory the process
// had touched before, large ones on fresh memory, whose page faults cost about 17 us
// each on this machine (README). Load's exponent of 1.16 came from that mix: each kind
// of call alone is linear in N.)
double TimeIt(const std::function<void()>& f, double budget, int min_calls, double* first,
              const std::function<void()>& reset) {
  std::vector<double> t;
  double total = 0;
  do {
    if (reset) reset();
    const double t0 = Now();
    f();
    t.push_back(Now() - t0);
    total += t.back();
  } while (t.size() < 7 && (static_cast<int>(t.size()) < min_calls || total < budget));
  *first = t.front();
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_phases MODEL.yaml [--skip PHASE,...] [--min-calls K]\n");
    return 2;
  }
  const std::string path = argv[1];
  std::set<std::string> skip;
  int min_calls = 3;
  for (int i = 2; i + 1 < argc; i += 2) {
    if (std::string(argv[i]) == "--skip") {
      std::stringstream s(argv[i + 1]);
      for (std::string p; std::getline(s, p, ',');) skip.insert(p);
    } else if (std::string(argv[i]) == "--min-calls") {
      min_calls = std::max(1, std::min(7, std::atoi(argv[i + 1])));
    }
  }
  std::map<std::string, double> seconds, first_call;
  auto run = [&](const std::string& name, const std::function<void()>& f, double budget = 0.5,
                 const std::function<void()>& reset = nullptr) {
    if (skip.count(name)) return;
    seconds[name] = TimeIt(f, budget, min_calls, &first_call[name], reset);
    std::fprintf(stderr, "bench_phases: %-12s %.6g s (first call %.6g s)\n", name.c_str(), seconds[name],
                 first_call[name]);
  };

  mbs::Model model;
  run("load", [&] { model = mbs::LoadModel(path); }, 0.5, [&] { model = mbs::Model(); });
  if (skip.count("load")) model = mbs::LoadModel(path);
  std::unique_ptr<mbs::MultibodySystem> system;
  run("build", [&] { system = std::make_unique<mbs::MultibodySystem>(model); }, 0.5, [&] { system.reset(); });
  if (!system) system = std::make_unique<mbs::MultibodySystem>(model);
  mbs::MultibodySystem& sys = *system;
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  dae::State x;
  x.Resize(nq, nc);
  sys.InitialState(x.q, x.v);
  std::vector<int> order;  // normalisations first, as driver::Assemble
  for (int e = 0; e < nc; ++e)
    if (sys.constraint_joint()[e] < 0) order.push_back(e);
  for (int e = 0; e < nc; ++e)
    if (sys.constraint_joint()[e] >= 0) order.push_back(e);
  dae::ConsistencyOptions consistency;
  consistency.elimination_order = order;
  run("redundancy", [&] { dae::FindRedundantConstraints(sys, 0.0, x.q.data(), consistency.rank_tolerance, order); });
  run("consistent", [&] {
    dae::State y = x;
    dae::MakeConsistent(sys, y, consistency);
  });
  driver::Assembly asmb;
  run("assemble", [&] { asmb = driver::Assemble(model); }, 0.0, [&] { asmb = driver::Assembly(); });
  bool later = false;
  for (const char* p : {"determinacy", "residual", "jacobian", "hht_step", "hht_step_tree", "ida_step", "ida_step_tree", "row", "write"})
    later = later || !skip.count(p);
  if (!later) skip.insert({"determinacy", "residual", "jacobian", "hht_step", "hht_step_tree", "ida_step", "ida_step_tree", "row", "write"});
  if (!asmb.system && later) {
    driver::AssemblyOptions no_determinacy;
    no_determinacy.check_determinacy = false;
    asmb = driver::Assemble(model, no_determinacy);
  }
  run("determinacy", [&] {
    bool singular = false;
    driver::UndeterminedBodies(model, *asmb.kept_system, asmb.x0, driver::AssemblyOptions().singularity_tolerance,
                               &singular);
  });

  // Residual and Jacobian of the full system at the consistent state.
  std::vector<double> force(nq), c(nc), ct(nc), gamma(nc), w(nc, 1.0);
  std::vector<std::vector<double>> mats(dae::kNumMatrices);
  for (int m = 0; m < dae::kNumMatrices; ++m) mats[m].assign(sys.pattern(static_cast<dae::Matrix>(m)).nnz(), 0.0);
  dae::EvalInput in;
  in.t = 0;
  in.q = asmb.x0.q.data();
  in.v = asmb.x0.v.data();
  in.a = asmb.x0.a.data();
  in.w = w.data();
  run("residual", [&] {
    dae::EvalOutput out;
    out.force = force.data();
    out.constraint = c.data();
    out.constraint_dt = ct.data();
    out.acc_rhs = gamma.data();
    sys.Evaluate(in, out);
  }, 0.2);
  run("jacobian", [&] {
    dae::EvalOutput out;
    for (int m = 0; m < dae::kNumMatrices; ++m) out.matrix[m] = mats[m].data();
    sys.Evaluate(in, out);
  }, 0.2);

  const double t_steps = 0.02;
  long hht_steps = 0, ida_steps = 0;
  for (const char* solver : {"klu", "tree"}) {
    const std::string phase = std::string("hht_step") + (solver == std::string("tree") ? "_tree" : "");
    if (skip.count(phase)) continue;
    mbs::SimulationSettings s = model.simulation;
    s.integrator = mbs::IntegratorKind::kHht;
    s.hht_step = 1e-3;
    s.hht_adaptive = false;
    s.hht_linear_solver = solver;
    auto integ = driver::MakeIntegrator(*asmb.kept_system, s);
    integ->Initialize(asmb.x0);
    const double t0 = Now();
    integ->AdvanceTo(t_steps);
    const double dt = Now() - t0;
    hht_steps = integ->summary().steps_accepted;
    seconds[phase] = dt / std::max(1L, hht_steps);
    std::fprintf(stderr, "bench_phases: %-12s %.6g s (%ld steps, %s)\n", phase.c_str(), seconds[phase],
                 hht_steps, integ->summary().linear_solver.c_str());
  }
  for (const char* solver : {"klu", "tree"}) {
    const std::string phase = std::string("ida_step") + (solver == std::string("tree") ? "_tree" : "");
    if (skip.count(phase)) continue;
    mbs::SimulationSettings s = model.simulation;
    s.integrator = mbs::IntegratorKind::kIda;
    s.ida_rtol = 1e-6;
    s.ida_atol = 1e-6;
    s.ida_linear_solver = solver;
    auto integ = driver::MakeIntegrator(*asmb.kept_system, s);
    integ->Initialize(asmb.x0);
    const double t0 = Now();
    integ->AdvanceTo(t_steps);
    const double dt = Now() - t0;
    ida_steps = integ->summary().steps_accepted;
    seconds[phase] = dt / std::max(1L, ida_steps);
    std::fprintf(stderr, "bench_phases: %-12s %.6g s (%ld steps, %s)\n", phase.c_str(), seconds[phase],
                 ida_steps, integ->summary().linear_solver.c_str());
  }
  if (!skip.count("row")) {
    driver::OutputRowBuilder rows(model, asmb, model.simulation);
    rows.Compute(asmb.x0);  // the first row (initial measure values)
    int k = 0;
    dae::State y = asmb.x0;
    run("row", [&] {
      y.t = 1e-3 * ++k;
      rows.Compute(y);
    }, 0.3);
  }
  if (!skip.count("write")) {
    // As `mbdae simulate` writes: rows kept in memory and written at most every 0.2 s.
    char name[] = "bench_phases_XXXXXX";
    const int fd = mkstemp(name);
    if (fd >= 0) close(fd);
    {
      driver::RunDescription run_description =
          driver::DescribeRun(model, asmb, model.simulation, path, "bench");
      std::unique_ptr<io::ResultsFile> file;
      run("create_file", [&] {
        file = std::make_unique<io::ResultsFile>(name, run_description.layout);
        file->set_flush_interval(0.2);
        driver::WriteRunAttributes(*file, run_description);
      }, 0.0, [&] { file.reset(); });
      driver::OutputRowBuilder rows(model, asmb, model.simulation);
      const io::ResultsRow& row = rows.Compute(asmb.x0);
      constexpr int kRows = 20;
      const double t0 = Now();
      for (int r = 0; r < kRows; ++r) file->AppendRow(row);
      file->Flush();
      seconds["write"] = (Now() - t0) / kRows;
      std::fprintf(stderr, "bench_phases: %-12s %.6g s\n", "write", seconds["write"]);
    }
    std::remove(name);
  }

  std::printf("{\"model\": \"%s\", \"bodies\": %zu, \"coordinates\": %d, \"constraints\": %d, "
              "\"redundant\": %zu, \"hht_steps\": %ld, \"ida_steps\": %ld, \"seconds\": {",
              path.c_str(), model.bodies.size(), nq, nc, asmb.redundant.size(), hht_steps, ida_steps);
  bool first = true;
  for (const auto& [k, v] : seconds) {
    std::printf("%s\"%s\": %.9g", first ? "" : ", ", k.c_str(), v);
    first = false;
  }
  std::printf("}, \"first_call\": {");
  first = true;
  for (const auto& [k, v] : first_call) {
    std::printf("%s\"%s\": %.9g", first ? "" : ", ", k.c_str(), v);
    first = false;
  }
  std::printf("}}\n");
  return 0;
}
