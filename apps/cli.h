// The parts of the `mbdae` program that are worth testing on their own: the command
// line parser, the default results path, the progress display and the `info` report.
#pragma once

#include <chrono>
#include <functional>
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
  bool floating_base = false;  // --floating-base: a URDF model's root link is a free body
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

// MODEL.yaml|.yml|.json|.fds|.urdf -> MODEL.h5, next to the model; other names get .h5 appended.
std::string DefaultResultsPath(const std::string& model_path);

// Parses a whole argument as a finite number; throws UsageError naming the option.
double ParseNumber(const std::string& option, const std::string& text);

// Progress on a stream: a bar redrawn in place (terminal), a line every 10 % of the run
// (anything else), or nothing.
class ProgressReporter {
 public:
  enum class Mode { kNone, kBar, kLines };
  explicit ProgressReporter(Mode mode, std::FILE* out = stderr) : mode_(mode), out_(out) {}
  // The bar shows the time left, estimated from the wall time since the first Update
  // and the share of t_end reached (once 0.5 % and 0.2 s have passed).
  void Update(double t, double t_end);
  void Finish();  // ends the bar's line
  // Tests: a clock (seconds) instead of std::chrono::steady_clock.
  void set_clock(std::function<double()> seconds) { clock_ = std::move(seconds); }
  // "42 s", "3 min 20 s", "2 h 05 min".
  static std::string Duration(double seconds);

 private:
  double Now() const;
  Mode mode_;
  std::FILE* out_;
  int next_tenth_ = 1;
  bool drawn_ = false;
  std::function<double()> clock_;
  double start_ = -1;       // clock at the first Update
  double last_draw_s_ = -1;  // clock at the last drawing
};

// What `info` prints.
struct ModelInfo {
  std::string file, name;
  std::vector<std::string> bodies, joints, measures, forces, parameters, coordinates,
      constraints, redundant;
  std::vector<std::string> notes;  // Model::notes: what an import (URDF) changed or left out
  std::vector<double> parameter_values;
  int degrees_of_freedom = 0;  // nq - (nc - redundant)
  std::string Text() const;
  std::string Json() const;
};
ModelInfo Describe(const mbs::Model& model, const driver::Assembly& assembly);

std::string JsonString(const std::string& s);  // quoted and escaped

// True when a and b name the same existing file (same device and inode), whatever the
// spelling: `./m.yaml` and `m.yaml`, other directories, symbolic and hard links.
bool SameFile(const std::string& a, const std::string& b);

// Where a run's results file goes. The file is written under a temporary name beside
// its destination (temporary()) and renamed over it by Commit() when the run ends
// (done, failed or interrupted), so that an earlier file of that name stays whole until
// then; the destructor removes the temporary file of a run that did not get there. A
// process killed outright (SIGKILL) leaves the earlier file and the temporary one.
class ResultsDestination {
 public:
  // Checks that `path` may be written (its directory, and the file if it exists) and is
  // not the input file `input` (a model or a problem file). A destination that is a
  // symbolic link is written through it (the link is kept). Throws UsageError naming the
  // path, with the system's reason (strerror) when the system refuses.
  ResultsDestination(const std::string& path, const std::string& input);
  ~ResultsDestination();
  ResultsDestination(const ResultsDestination&) = delete;
  ResultsDestination& operator=(const ResultsDestination&) = delete;

  // Creates the empty temporary file PATH.PID.tmp beside the destination and returns its
  // name. Throws UsageError with the system's reason.
  const std::string& CreateTemporary();
  const std::string& path() const { return path_; }  // as given
  const std::string& temporary() const { return temporary_; }
  // Renames the temporary file over the destination. Throws std::runtime_error with the
  // system's reason.
  void Commit();

 private:
  [[noreturn]] void Refuse(const std::string& why) const;
  std::string path_, target_, temporary_;
  bool created_ = false, committed_ = false;
};

}  // namespace mbdae::app
