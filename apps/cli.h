// The parts of the `mbdae` program that are worth testing on their own: the command
// line parser, the default results path, the progress display and the `info` report.
#pragma once

#include <chrono>
#include <cstdio>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "driver/simulation.h"
#include "mbs/model.h"

namespace mbdae::app {

// A mistake on the command line (exit code 2).
class UsageError : public std::runtime_error {
 public:
  explicit UsageError(const std::string& what, bool show_usage = false)
      : std::runtime_error(what), show_usage_(show_usage) {}
  bool show_usage() const { return show_usage_; }

 private:
  bool show_usage_;
};

enum class Command { kSimulate, kInfo, kCheck, kConvert, kGradient, kOptimize };

struct CommandLine {
  Command command = Command::kSimulate;
  bool help = false;
  bool version = false;
  std::string model_path;  // optimize: the problem file
  // simulate, optimize: empty means DefaultResultsPath(model_path); convert: stdout.
  std::string output_path;
  driver::SettingsOverrides overrides;
  std::map<std::string, double> parameter_overrides;
  bool quiet = false;
  bool json = false;
  // gradient (shared/spec/sensitivities.md): --objective (repeatable, or comma-separated),
  // --wrt NAME,NAME (repeatable), --wrt-splines, --method, --fd-step (relative),
  // --trajectory-memory (MiB; 0: store every step).
  std::vector<std::string> objectives, wrt;
  bool wrt_splines = false;
  std::string method = "adjoint";
  std::optional<double> fd_step, trajectory_memory_mib;
};

// args without the program name. Options may come before or after MODEL, as
// "--opt VALUE" or "--opt=VALUE"; "--set" takes NAME=VALUE and any NAME=VALUE arguments
// right after it. Throws UsageError naming the offending argument.
CommandLine ParseCommandLine(const std::vector<std::string>& args);

// MODEL.yaml|.yml|.json|.fds -> MODEL.h5, next to the model; other names get .h5 appended.
std::string DefaultResultsPath(const std::string& model_path);

// Parses a whole argument as a finite number; throws UsageError naming the option.
double ParseNumber(const std::string& option, const std::string& text);

// Progress on a stream: a bar redrawn in place (terminal), a line every 10 % of the run
// (anything else), or nothing.
class ProgressReporter {
 public:
  enum class Mode { kNone, kBar, kLines };
  explicit ProgressReporter(Mode mode, std::FILE* out = stderr) : mode_(mode), out_(out) {}
  void Update(double t, double t_end);
  void Finish();  // ends the bar's line

 private:
  Mode mode_;
  std::FILE* out_;
  int next_tenth_ = 1;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point last_draw_{};
};

// What `info` prints.
struct ModelInfo {
  std::string file, name;
  std::vector<std::string> bodies, joints, measures, forces, parameters, coordinates,
      constraints, redundant;
  std::vector<double> parameter_values;
  int degrees_of_freedom = 0;  // nq - (nc - redundant)
  std::string Text() const;
  std::string Json() const;
};
ModelInfo Describe(const mbs::Model& model, const driver::Assembly& assembly);

std::string JsonString(const std::string& s);  // quoted and escaped

}  // namespace mbdae::app
