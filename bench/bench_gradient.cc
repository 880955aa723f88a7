// The cost of gradients (bench/README.md, "Gradients: cost"): one measurement per
// invocation, so that every measurement's peak memory (getrusage ru_maxrss) is its own;
// bench/run_gradient.sh runs the measurements round after round, side by side, and
// bench/report_gradient.py turns their output into bench/results/gradient.md.
//
//   bench_gradient MODEL simulate            the plain simulation: driver::Assemble +
//                                            driver::Simulate of the model's settings,
//                                            no results file
//   bench_gradient MODEL simulate-file PATH  the same writing the results file PATH (what
//                                            `mbdae simulate` does; PATH is removed after)
//   bench_gradient MODEL adjoint N [--trajectory-mib X]
//   bench_gradient MODEL forward N
//   bench_gradient MODEL fd N [--fd-step S]
//                                            driver::ComputeGradient (what `mbdae gradient
//                                            --method adjoint|forward|fd` runs) with respect
//                                            to the first N parameters of the benchmark's
//                                            order (below), no results file.
//                                            --trajectory-mib: GradientRequest::
//                                            trajectory_memory in MiB (0: store every step;
//                                            default: the request's default)
//   bench_gradient MODEL adjoint-direct N [--trajectory-mib X]
//                                            the same adjoint gradient through the calls
//                                            ComputeGradient makes (driver::Assemble with
//                                            the parameters, driver::Simulate recording the
//                                            trajectory, ConsistentInitialStateDerivatives,
//                                            ModelObjectives, HhtAdjointGradient), each
//                                            timed, and with the trajectory's memory
//                                            budget (HhtTrajectory::set_memory_budget,
//                                            checkpoints) when X > 0
//   bench_gradient MODEL parts N             the cost of one evaluation of the system
//                                            (built with the first N parameters) at the
//                                            initial state, per kind of request: what a
//                                            Newton iteration asks (Q, C), a Jacobian
//                                            update (the seven matrices), the parameter
//                                            matrices alone, and what the sweeps ask at
//                                            every step (the matrices and the parameter
//                                            matrices); the mean over repeated calls
//   bench_gradient MODEL list                the parameter order, one name a line
// Every case takes --integrator hht|ida and --step H (the HHT step) to override the
// model's settings.
//
// The parameter order: all parameters of the model in file order, then every spline
// ordinate, taken with the stride 379 (coprime with 1000): entry i is all[(379 i) mod P].
// The first 10 are then a mix of the kinds of the model (masses, inertias, springs,
// dampers, rest angles, loads, spline ordinates) rather than ten of one rod.
//
// Output: one JSON object on stdout, with the model's load time, the wall and process
// CPU time of the measured call (the model is loaded before, not timed), the run's own
// split (GradientResult: forward run's CPU time and the CPU time beyond it; Simulate:
// the integrator's CPU time), counters, the objective values and the whole gradient, the
// trajectory's bytes, and the process's peak resident memory after loading the model and
// at the end (ru_maxrss, KiB).
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <exception>
#include <iostream>
#include <map>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include "dae/format.h"
#include "dae/mechanical_system.h"
#include "driver/gradient.h"
#include "driver/simulation.h"
#include "mbs/loader.h"
#include "mbs/model.h"
#include "mbs/sensitivity_parameters.h"
#include "sensitivities/hht_sensitivity.h"
#include "sensitivities/initial_state.h"
#include "sensitivities/model_objectives.h"

namespace {

namespace driver = mbdae::driver;
namespace mbs = mbdae::mbs;

constexpr long kStride = 379;

double CpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

double WallSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

long PeakRssKib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss;  // KiB on Linux
}

std::string Num(double x) { return std::isfinite(x) ? mbdae::FormatG(x, 17) : "null"; }

std::string Str(const std::string& s) {
  std::string o = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') o += '\\';
    if (static_cast<unsigned char>(c) < 0x20) {
      char b[8];
      std::snprintf(b, sizeof b, "\\u%04x", c);
      o += b;
      continue;
    }
    o += c;
  }
  return o + "\"";
}

template <class T, class F>
std::string Array(const std::vector<T>& v, F f) {
  std::string o = "[";
  for (size_t i = 0; i < v.size(); ++i) o += (i ? ", " : "") + f(v[i]);
  return o + "]";
}

std::vector<std::string> BenchmarkOrder(const mbs::Model& model) {
  std::vector<std::string> all;
  for (const auto& p : mbs::AllSensitivityParameters(model, true)) all.push_back(p.name);
  const long n = static_cast<long>(all.size());
  if (n % kStride == 0) throw std::runtime_error("the parameter count is a multiple of the stride");
  std::vector<std::string> order(n);
  for (long i = 0; i < n; ++i) order[i] = all[(kStride * i) % n];
  return order;
}

int Usage() {
  std::cerr << "usage: bench_gradient MODEL simulate | simulate-file PATH | parts N | list\n"
               "       bench_gradient MODEL adjoint|forward|fd N [--trajectory-mib X] [--fd-step S]\n"
               "       (every case: [--integrator hht|ida] [--step H], default: the model's)\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  // Positional arguments and --option value pairs, anywhere.
  std::vector<std::string> pos;
  std::map<std::string, std::string> opts;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("--", 0) == 0) {
      if (i + 1 >= argc) return Usage();
      opts[a] = argv[++i];
    } else {
      pos.push_back(a);
    }
  }
  for (const auto& [k, v] : opts)
    if (k != "--trajectory-mib" && k != "--fd-step" && k != "--integrator" && k != "--step")
      return Usage();
  if (pos.size() < 2) return Usage();
  const std::string path = pos[0];
  const std::string what = pos[1];
  const std::string arg = pos.size() > 2 ? pos[2] : "";
  try {
    const double load_start = WallSeconds();
    const mbs::Model model = mbs::LoadModel(path);
    const double load_s = WallSeconds() - load_start;
    driver::SettingsOverrides overrides;
    if (opts.count("--integrator")) {
      if (opts["--integrator"] == "ida")
        overrides.integrator = mbs::IntegratorKind::kIda;
      else if (opts["--integrator"] != "hht")
        return Usage();
    }
    if (opts.count("--step")) overrides.hht_step = std::atof(opts["--step"].c_str());
    const mbs::SimulationSettings settings = driver::ResolveSettings(model.simulation, overrides);
    const std::vector<std::string> order = BenchmarkOrder(model);
    if (what == "list") {
      for (const auto& n : order) std::cout << n << "\n";
      return 0;
    }
    const long rss_loaded = PeakRssKib();
    std::ostringstream o;
    o << "{\"case\": " << Str(what) << ", \"integrator_kind\": "
      << Str(driver::IntegratorName(settings.integrator)) << ", \"hht_step\": " << Num(settings.hht_step)
      << ", \"model\": " << Str(model.name)
      << ", \"parameters_in_model\": " << order.size() << ", \"load_s\": " << Num(load_s);

    if (what == "simulate" || what == "simulate-file") {
      if (what == "simulate-file" && arg.empty()) return Usage();
      driver::SimulationOptions so;
      so.model_path = path;
      if (what == "simulate-file") {
        so.results_path = arg;
        so.flush_interval = 0.2;  // as `mbdae simulate` (apps/main.cc)
      }
      const double w0 = WallSeconds(), c0 = CpuSeconds();
      driver::Assembly asmb = driver::Assemble(model);
      const double assembly_cpu = CpuSeconds() - c0;
      const driver::SimulationSummary s = driver::Simulate(model, asmb, settings, so);
      const double wall = WallSeconds() - w0, cpu = CpuSeconds() - c0;
      if (!so.results_path.empty()) std::remove(so.results_path.c_str());
      if (s.status != driver::SimulationSummary::Status::kDone)
        throw std::runtime_error("the simulation failed: " + s.failure_reason);
      o << ", \"n\": 0, \"wall_s\": " << Num(wall) << ", \"cpu_s\": " << Num(cpu)
        << ", \"assembly_cpu_s\": " << Num(assembly_cpu)
        << ", \"solver_cpu_s\": " << Num(s.solver_cpu_time)
        << ", \"steps\": " << s.counters.steps_accepted
        << ", \"newton_iterations\": " << s.counters.newton_iterations
        << ", \"factorizations\": " << s.counters.factorizations
        << ", \"nq\": " << asmb.kept_system->num_coordinates()
        << ", \"nc\": " << asmb.kept_system->num_constraints()
        << ", \"values\": "
        << Array(s.objectives, [](const driver::SimulationSummary::ObjectiveValue& v) { return Num(v.value); });
    } else if (what == "adjoint-direct") {
      const int n = std::atoi(arg.c_str());
      if (n < 1 || n > static_cast<int>(order.size())) return Usage();
      if (settings.integrator != mbs::IntegratorKind::kHht) return Usage();
      const double budget =
          opts.count("--trajectory-mib") ? std::atof(opts["--trajectory-mib"].c_str()) * 1024.0 * 1024.0 : 0.0;
      const driver::GradientRequest defaults;  // its Newton factor, as ComputeGradient
      const double w0 = WallSeconds(), c0 = CpuSeconds();
      driver::AssemblyOptions ao;
      ao.sensitivity = mbs::ResolveSensitivityParameters(
          model, std::vector<std::string>(order.begin(), order.begin() + n));
      driver::Assembly asmb = driver::Assemble(model, ao);
      const double c_asm = CpuSeconds();
      const int nq = asmb.kept_system->num_coordinates(), nc = asmb.kept_system->num_constraints();
      mbdae::sens::HhtTrajectory trajectory(nq, nc);
      if (budget > 0) trajectory.set_memory_budget(static_cast<size_t>(budget));
      driver::SimulationOptions so;
      so.model_path = path;
      const double newton_factor = defaults.newton_factor;
      so.adjust_hht = [newton_factor](mbdae::dae::HhtOptions& ho) {
        ho.adaptive_newton_factor = std::min(ho.adaptive_newton_factor, newton_factor);
      };
      so.prepare = [&trajectory](mbdae::dae::Integrator& integrator) { trajectory.Attach(integrator); };
      const driver::SimulationSummary fw = driver::Simulate(model, asmb, settings, so);
      const double c_fw = CpuSeconds();
      if (fw.status != driver::SimulationSummary::Status::kDone)
        throw std::runtime_error("the forward run failed: " + fw.failure_reason);
      const size_t recorded_bytes = trajectory.memory();
      mbdae::sens::InitialStateDerivatives dx0;
      std::vector<double> dq_raw, dv_raw;
      std::string error;
      asmb.system->InitialStateParameterDerivatives(dq_raw, dv_raw);
      if (!mbdae::sens::ConsistentInitialStateDerivatives(*asmb.kept_system, asmb.x0, asmb.v_raw, dq_raw,
                                                          dv_raw, &dx0, &error))
        throw std::runtime_error("initial state derivatives: " + error);
      const double c_dx0 = CpuSeconds();
      mbdae::sens::ModelObjectives objectives(model, *asmb.system, asmb.kept, ao.sensitivity);
      mbdae::dae::HhtOptions ho = driver::HhtOptionsOf(settings);
      ho.adaptive_newton_factor = std::min(ho.adaptive_newton_factor, newton_factor);
      mbdae::sens::HhtSensitivityResult sr;
      const double c_obj = CpuSeconds();
      if (!mbdae::sens::HhtAdjointGradient(*asmb.kept_system, ho, objectives, trajectory, dx0, &sr, &error))
        throw std::runtime_error("the adjoint sweep failed: " + error);
      const double c_end = CpuSeconds();
      const double wall = WallSeconds() - w0;
      std::vector<std::string> wrt(order.begin(), order.begin() + n);
      o << ", \"n\": " << n << ", \"trajectory_memory_request\": " << Num(budget)
        << ", \"wall_s\": " << Num(wall) << ", \"cpu_s\": " << Num(c_end - c0)
        << ", \"assembly_cpu_s\": " << Num(c_asm - c0) << ", \"forward_cpu_s\": " << Num(c_fw - c_asm)
        << ", \"solver_cpu_s\": " << Num(fw.solver_cpu_time)
        << ", \"initial_state_cpu_s\": " << Num(c_dx0 - c_fw) << ", \"objectives_cpu_s\": " << Num(c_obj - c_dx0)
        << ", \"sweep_cpu_s\": " << Num(c_end - c_obj) << ", \"gradient_cpu_s\": " << Num(c_end - c_fw)
        << ", \"steps\": " << fw.counters.steps_accepted
        << ", \"newton_iterations\": " << fw.counters.newton_iterations
        << ", \"factorizations\": " << fw.counters.factorizations
        << ", \"linear_solves\": " << sr.linear_solves
        << ", \"sweep_factorizations\": " << sr.factorizations
        << ", \"trajectory_bytes\": " << recorded_bytes
        << ", \"trajectory_peak_bytes\": " << trajectory.peak_memory()
        << ", \"sweep_peak_trajectory_bytes\": " << sr.peak_trajectory_bytes
        << ", \"checkpoints\": " << trajectory.num_checkpoints()
        << ", \"checkpoint_interval\": " << trajectory.checkpoint_interval()
        << ", \"recomputed_steps\": " << sr.recomputed_steps
        << ", \"recompute_deviation\": " << Num(sr.recompute_deviation)
        << ", \"values\": " << Array(sr.values, Num) << ", \"wrt\": " << Array(wrt, Str)
        << ", \"gradient\": " << Array(sr.gradient, Num);
    } else if (what == "parts") {
      const int n = std::atoi(arg.c_str());
      if (n < 1 || n > static_cast<int>(order.size())) return Usage();
      driver::AssemblyOptions ao;
      ao.sensitivity = mbs::ResolveSensitivityParameters(
          model, std::vector<std::string>(order.begin(), order.begin() + n));
      driver::Assembly asmb = driver::Assemble(model, ao);
      mbdae::dae::MechanicalSystem& sys = *asmb.kept_system;
      const int nq = sys.num_coordinates(), nc = sys.num_constraints();
      std::vector<double> force(nq), con(nc);
      std::vector<std::vector<double>> mat(mbdae::dae::kNumMatrices), par(mbdae::dae::kNumParameterMatrices);
      long par_nnz = 0;
      for (int m = 0; m < mbdae::dae::kNumMatrices; ++m)
        mat[m].resize(sys.pattern(static_cast<mbdae::dae::Matrix>(m)).nnz());
      for (int m = 0; m < mbdae::dae::kNumParameterMatrices; ++m) {
        par[m].resize(sys.parameter_pattern(static_cast<mbdae::dae::ParameterMatrix>(m)).nnz());
        par_nnz += static_cast<long>(par[m].size());
      }
      mbdae::dae::EvalInput in;
      in.t = 0.5;  // inside the run, where the drive spline is not at its first point
      in.q = asmb.x0.q.data();
      in.v = asmb.x0.v.data();
      in.a = asmb.x0.a.data();
      in.w = asmb.x0.lambda.data();
      auto time_calls = [&](bool residual, bool matrices, bool parameters) {
        mbdae::dae::EvalOutput out;
        if (residual) {
          out.force = force.data();
          out.constraint = con.data();
        }
        if (matrices)
          for (int m = 0; m < mbdae::dae::kNumMatrices; ++m) out.matrix[m] = mat[m].data();
        if (parameters)
          for (int m = 0; m < mbdae::dae::kNumParameterMatrices; ++m) out.parameter_matrix[m] = par[m].data();
        int calls = 0;
        const double c0 = CpuSeconds();
        double c = 0;
        while (calls < 5 || c < 0.5) {  // at least 5 calls and 0.5 s of CPU time
          if (sys.Evaluate(in, out) != 0) throw std::runtime_error(sys.last_error());
          ++calls;
          c = CpuSeconds() - c0;
        }
        return 1e6 * c / calls;  // us per call
      };
      o << ", \"n\": " << n << ", \"parameter_nnz\": " << par_nnz
        << ", \"residual_us\": " << Num(time_calls(true, false, false))
        << ", \"jacobian_us\": " << Num(time_calls(false, true, false))
        << ", \"parameter_matrices_us\": " << Num(time_calls(false, false, true))
        << ", \"sweep_request_us\": " << Num(time_calls(false, true, true));
    } else if (what == "adjoint" || what == "forward" || what == "fd") {
      const int n = std::atoi(arg.c_str());
      if (n < 1 || n > static_cast<int>(order.size())) return Usage();
      driver::GradientRequest request;
      driver::ParseGradientMethod(what, &request.method);
      request.wrt.assign(order.begin(), order.begin() + n);
      if (opts.count("--trajectory-mib"))
        request.trajectory_memory = std::atof(opts["--trajectory-mib"].c_str()) * 1024.0 * 1024.0;
      if (opts.count("--fd-step")) request.fd_step = std::atof(opts["--fd-step"].c_str());
      driver::GradientOptions go;
      go.model_path = path;
      go.reload = [&path](const std::map<std::string, double>& values) {
        mbs::LoadOptions lo;
        lo.parameter_overrides = values;
        return mbs::LoadModel(path, lo);
      };
      const double w0 = WallSeconds(), c0 = CpuSeconds();
      const driver::GradientResult r = driver::ComputeGradient(model, settings, request, go);
      const double wall = WallSeconds() - w0, cpu = CpuSeconds() - c0;
      if (r.status != driver::GradientResult::Status::kDone)
        throw std::runtime_error("the gradient failed: " + r.failure_reason);
      o << ", \"n\": " << n << ", \"trajectory_memory_request\": " << Num(request.trajectory_memory)
        << ", \"wall_s\": " << Num(wall) << ", \"cpu_s\": " << Num(cpu)
        << ", \"solver_cpu_s\": " << Num(r.solver_cpu_time)
        << ", \"gradient_cpu_s\": " << Num(r.gradient_cpu_time)
        << ", \"result_wall_s\": " << Num(r.wall_time)
        << ", \"steps\": " << r.forward_steps
        << ", \"newton_iterations\": " << r.forward.counters.newton_iterations
        << ", \"factorizations\": " << r.forward.counters.factorizations
        << ", \"linear_solves\": " << r.linear_solves
        << ", \"trajectory_bytes\": " << Num(r.trajectory_bytes) << ", \"runs\": " << r.runs
        << ", \"integrator\": " << Str(r.integrator_detail)
        << ", \"values\": " << Array(r.values, Num)
        << ", \"wrt\": " << Array(r.wrt, Str) << ", \"gradient\": " << Array(r.gradient, Num)
        << ", \"fd_steps\": " << Array(r.fd_steps, Num);
    } else {
      return Usage();
    }
    o << ", \"rss_loaded_kib\": " << rss_loaded << ", \"rss_peak_kib\": " << PeakRssKib() << "}";
    std::cout << o.str() << std::endl;
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "bench_gradient: " << e.what() << "\n";
    return 1;
  }
}
