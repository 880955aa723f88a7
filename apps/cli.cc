#include "apps/cli.h"

#include "dae/format.h"
#include "dae/hht.h"
#include "mbs/model_writer.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <sstream>
#include <vector>

namespace mbdae::app {
namespace {

bool IsIdentifier(const std::string& s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.';
  });
}

// NAME=VALUE with NAME an identifier and VALUE a number.
bool LooksLikeAssignment(const std::string& s) {
  const auto eq = s.find('=');
  if (eq == std::string::npos || !IsIdentifier(s.substr(0, eq))) return false;
  const std::string value = s.substr(eq + 1);
  char* end = nullptr;
  std::strtod(value.c_str(), &end);
  return !value.empty() && end == value.c_str() + value.size();
}

// Shortest of 15 or 17 significant digits that reads back exactly.
std::string Num(double x) { return FormatRoundTrip(x); }

}  // namespace

double ParseNumber(const std::string& option, const std::string& text) {
  char* end = nullptr;
  const double x = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(x))
    throw UsageError(option + ": expected a number, got '" + text + "'");
  return x;
}

CommandLine ParseCommandLine(const std::vector<std::string>& args) {
  CommandLine cl;
  size_t i = 0;
  if (args.empty()) throw UsageError("no command given", true);
  const std::string& first = args[0];
  if (first == "--help" || first == "-h" || first == "help") {
    cl.help = true;
    return cl;
  }
  if (first == "--version") {
    cl.version = true;
    return cl;
  }
  if (first == "simulate")
    cl.command = Command::kSimulate;
  else if (first == "info")
    cl.command = Command::kInfo;
  else if (first == "check")
    cl.command = Command::kCheck;
  else if (first == "convert")
    cl.command = Command::kConvert;
  else if (first == "gradient")
    cl.command = Command::kGradient;
  else if (first == "optimize")
    cl.command = Command::kOptimize;
  else
    throw UsageError("unknown command '" + first + "'", true);
  ++i;

  const bool grad = cl.command == Command::kGradient;
  // `optimize` takes -o, --json and --quiet only (its settings are in the problem file).
  const bool opt = cl.command == Command::kOptimize;
  // `gradient` takes every option of `simulate` (its forward run is a simulation).
  const bool sim = cl.command == Command::kSimulate || grad;
  while (i < args.size()) {
    std::string arg = args[i++];
    std::optional<std::string> inline_value;
    if (arg.rfind("--", 0) == 0) {
      const auto eq = arg.find('=');
      if (eq != std::string::npos) {
        inline_value = arg.substr(eq + 1);
        arg = arg.substr(0, eq);
      }
    }
    auto value = [&]() -> std::string {
      if (inline_value) return *inline_value;
      if (i >= args.size()) throw UsageError(arg + ": missing value");
      return args[i++];
    };
    auto number = [&]() { return ParseNumber(arg, value()); };
    auto no_value = [&]() {
      if (inline_value) throw UsageError(arg + ": takes no value");
    };
    // One of `allowed`, else "ARG: expected A, B or C, got 'V'".
    auto choice = [&](const std::vector<std::string>& allowed) {
      const std::string v = value();
      if (std::find(allowed.begin(), allowed.end(), v) != allowed.end()) return v;
      throw UsageError(arg + ": expected " + JoinOr(allowed) + ", got '" + v + "'");
    };
    auto only_simulate = [&]() {
      if (!sim) throw UsageError("option " + arg + " is only for `simulate` and `gradient`", true);
    };
    auto only_gradient = [&]() {
      if (!grad) throw UsageError("option " + arg + " is only for `gradient`", true);
    };
    // Comma-separated names, each non-empty.
    auto names = [&]() {
      std::vector<std::string> out;
      const std::string v = value();
      size_t start = 0;
      while (true) {
        const size_t comma = v.find(',', start);
        std::string n = v.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
        if (n.empty()) throw UsageError(arg + ": empty name in '" + v + "'");
        out.push_back(n);
        if (comma == std::string::npos) break;
        start = comma + 1;
      }
      return out;
    };

    if (arg == "--help" || arg == "-h") {
      no_value();
      cl.help = true;
    } else if (arg == "--version") {
      no_value();
      cl.version = true;
    } else if (arg == "--json" && (cl.command == Command::kInfo || grad || opt)) {
      no_value();
      cl.json = true;
    } else if (arg == "--floating-base") {
      if (opt) throw UsageError("option --floating-base is not for `optimize` (the problem file names the model)", true);
      no_value();
      cl.floating_base = true;
    } else if (arg == "--set") {
      if (opt) throw UsageError("option --set is not for `optimize` (the problem file names the model)", true);
      const std::string a = value();
      if (!LooksLikeAssignment(a)) throw UsageError("--set: expected NAME=VALUE, got '" + a + "'");
      std::vector<std::string> assignments{a};
      while (!inline_value && i < args.size() && LooksLikeAssignment(args[i]))
        assignments.push_back(args[i++]);
      for (const auto& s : assignments) {
        const auto eq = s.find('=');
        cl.parameter_overrides[s.substr(0, eq)] = ParseNumber("--set " + s, s.substr(eq + 1));
      }
    } else if (arg == "-o" || arg == "--output") {
      if (!sim && !opt && cl.command != Command::kConvert)
        throw UsageError("option " + arg + " is only for `simulate`, `gradient`, `optimize` and `convert`", true);
      cl.output_path = value();
      if (cl.output_path.empty()) throw UsageError(arg + ": empty file name");
    } else if (arg == "--integrator") {
      only_simulate();
      const std::string v = choice({"hht", "ida", "kinematic", "erk"});
      cl.overrides.integrator = v == "hht"   ? mbs::IntegratorKind::kHht
                                : v == "ida" ? mbs::IntegratorKind::kIda
                                : v == "erk" ? mbs::IntegratorKind::kErk
                                             : mbs::IntegratorKind::kKinematic;
    } else if (arg == "--t-end") {
      only_simulate();
      cl.overrides.t_end = number();
    } else if (arg == "--output-step") {
      only_simulate();
      cl.overrides.output_step = number();
    } else if (arg == "--step") {
      only_simulate();
      cl.overrides.hht_step = number();
    } else if (arg == "--alpha") {
      only_simulate();
      cl.overrides.hht_alpha = number();
    } else if (arg == "--tolerance") {
      only_simulate();
      cl.overrides.hht_tolerance = number();
    } else if (arg == "--newton-tolerance") {
      only_simulate();
      cl.overrides.hht_newton_tolerance = number();
    } else if (arg == "--jacobian-cost") {
      only_simulate();
      const std::string v = value();
      cl.overrides.hht_jacobian_cost = driver::ParseJacobianCost(v);
      if (!cl.overrides.hht_jacobian_cost)
        throw UsageError(arg + ": expected auto or a number >= 0, got '" + v + "'");
    } else if (arg == "--adaptive") {
      only_simulate();
      no_value();
      cl.overrides.hht_adaptive = true;
    } else if (arg == "--fixed-step") {
      only_simulate();
      no_value();
      cl.overrides.hht_adaptive = false;
    } else if (arg == "--modified") {
      only_simulate();
      no_value();
      cl.overrides.hht_modified = true;
    } else if (arg == "--no-modified") {
      only_simulate();
      no_value();
      cl.overrides.hht_modified = false;
    } else if (arg == "--dense-output") {
      only_simulate();
      no_value();
      cl.overrides.hht_dense_output = cl.overrides.ida_dense_output = true;
    } else if (arg == "--no-dense-output") {
      only_simulate();
      no_value();
      cl.overrides.hht_dense_output = cl.overrides.ida_dense_output = false;
    } else if (arg == "--hht-form") {
      only_simulate();
      cl.overrides.hht_form = choice(dae::HhtFormNames());
    } else if (arg == "--hht-start") {
      only_simulate();
      cl.overrides.hht_start = choice(dae::HhtStartNames());
    } else if (arg == "--predictor") {
      only_simulate();
      cl.overrides.hht_predictor = choice(dae::HhtPredictorNames());
    } else if (arg == "--rotation-jacobian") {
      only_simulate();
      cl.overrides.hht_rotation_jacobian = choice(dae::HhtRotationJacobianNames());
    } else if (arg == "--linear-solver") {
      only_simulate();
      cl.overrides.hht_linear_solver = cl.overrides.ida_linear_solver =
          choice(dae::HhtLinearSolverNames());
    } else if (arg == "--output-bodies" || arg == "--output-joints" || arg == "--output-forces" ||
               arg == "--output-measures") {
      // all, none or comma-separated names: the elements given datasets in the results file.
      only_simulate();
      std::optional<std::vector<std::string>> chosen;
      try {
        chosen = driver::ParseElementChoice(value());
      } catch (const driver::InputError& e) {
        throw UsageError(arg + ": " + e.what());
      }
      auto& o = cl.overrides;
      (arg == "--output-bodies"   ? o.output_bodies
       : arg == "--output-joints" ? o.output_joints
       : arg == "--output-forces" ? o.output_forces
                                  : o.output_measures) = chosen;
    } else if (arg == "--output-accelerations") {
      only_simulate();
      cl.overrides.output_accelerations = choice({"solved", "integrator"});
    } else if (arg == "--rtol") {
      only_simulate();
      cl.overrides.ida_rtol = cl.overrides.erk_rtol = number();
    } else if (arg == "--atol") {
      only_simulate();
      cl.overrides.ida_atol = cl.overrides.erk_atol = number();
    } else if (arg == "--objective") {
      only_gradient();
      for (auto& n : names()) cl.objectives.push_back(n);
    } else if (arg == "--wrt") {
      only_gradient();
      for (auto& n : names()) cl.wrt.push_back(n);
    } else if (arg == "--wrt-splines") {
      only_gradient();
      no_value();
      cl.wrt_splines = true;
    } else if (arg == "--method") {
      only_gradient();
      cl.method = choice({"adjoint", "forward", "fd"});
    } else if (arg == "--fd-step") {
      only_gradient();
      cl.fd_step = number();
      if (!(*cl.fd_step > 0 && *cl.fd_step < 1))
        throw UsageError("--fd-step: expected a relative step in (0, 1), got '" + Num(*cl.fd_step) + "'");
    } else if (arg == "--trajectory-memory") {
      only_gradient();
      cl.trajectory_memory_mib = number();
      if (!(*cl.trajectory_memory_mib >= 0))
        throw UsageError("--trajectory-memory: expected MiB >= 0, got '" + Num(*cl.trajectory_memory_mib) + "'");
    } else if (arg == "--quiet" || arg == "-q") {
      no_value();
      cl.quiet = true;
    } else if (arg.size() > 1 && arg[0] == '-') {
      throw UsageError("unknown option '" + arg + "'", true);
    } else if (cl.model_path.empty()) {
      cl.model_path = arg;
    } else {
      throw UsageError("unexpected argument '" + arg + "' (the model is '" + cl.model_path + "')",
                       true);
    }
  }
  if (!cl.help && !cl.version && cl.model_path.empty())
    throw UsageError(opt ? "no problem file given" : "no model file given", true);
  return cl;
}

std::string DefaultResultsPath(const std::string& model_path) {
  const auto slash = model_path.find_last_of('/');
  const auto dot = model_path.find_last_of('.');
  if (dot != std::string::npos && (slash == std::string::npos || dot > slash)) {
    std::string ext = model_path.substr(dot);
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (ext == ".yaml" || ext == ".yml" || ext == ".json" || ext == ".fds" || ext == ".urdf") return model_path.substr(0, dot) + ".h5";
  }
  return model_path + ".h5";
}

double ProgressReporter::Now() const {
  if (clock_) return clock_();
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string ProgressReporter::Duration(double seconds) {
  char text[48];
  const long s = std::lround(std::max(0.0, seconds));
  if (s < 60) std::snprintf(text, sizeof text, "%ld s", s);
  else if (s < 3600) std::snprintf(text, sizeof text, "%ld min %02ld s", s / 60, s % 60);
  else std::snprintf(text, sizeof text, "%ld h %02ld min", s / 3600, (s % 3600) / 60);
  return text;
}

void ProgressReporter::Update(double t, double t_end) {
  if (mode_ == Mode::kNone || !(t_end > 0)) return;
  const double fraction = std::clamp(t / t_end, 0.0, 1.0);
  if (mode_ == Mode::kLines) {
    // One line per tenth of the run passed (several tenths at once print one line).
    if (fraction + 1e-12 >= next_tenth_ / 10.0) {
      while (next_tenth_ <= 10 && fraction + 1e-12 >= next_tenth_ / 10.0) ++next_tenth_;
      std::fprintf(out_, "mbdae: t = %-10.6g of %g (%3.0f %%)\n", t, t_end, 100 * fraction);
      std::fflush(out_);
    }
    return;
  }
  const double now = Now();
  if (start_ < 0) start_ = now;
  if (drawn_ && fraction < 1.0 && now - last_draw_s_ < 0.1) return;
  last_draw_s_ = now;
  drawn_ = true;
  constexpr int kWidth = 30;
  const int filled = static_cast<int>(fraction * kWidth);
  std::string bar(kWidth, ' ');
  for (int k = 0; k < filled; ++k) bar[k] = '=';
  if (filled < kWidth) bar[filled] = '>';
  const double elapsed = now - start_;
  std::string when;
  if (fraction >= 1.0) when = "  " + Duration(elapsed) + " in all";
  else if (fraction >= 0.005 && elapsed >= 0.2) when = "  " + Duration(elapsed * (1 - fraction) / fraction) + " left";
  // Trailing blanks wipe a longer text drawn before.
  std::fprintf(out_, "\r[%s] %3.0f %%  t = %-10.6g of %g%s        ", bar.c_str(), 100 * fraction, t, t_end, when.c_str());
  std::fflush(out_);
}

void ProgressReporter::Finish() {
  if (mode_ == Mode::kBar && drawn_) {
    std::fputc('\n', out_);
    std::fflush(out_);
  }
  drawn_ = false;
}

ModelInfo Describe(const mbs::Model& model, const driver::Assembly& assembly) {
  ModelInfo info;
  info.file = model.file;
  info.name = model.name;
  for (const auto& b : model.bodies) info.bodies.push_back(b.name);
  for (const auto& j : model.joints) info.joints.push_back(j.name);
  for (const auto& m : model.measures) info.measures.push_back(m.name);
  for (const auto& f : model.forces) info.forces.push_back(f.name);
  for (const auto& p : model.parameters) {
    info.parameters.push_back(p.name);
    info.parameter_values.push_back(p.value);
  }
  info.notes = model.notes;
  info.coordinates = assembly.system->coordinate_names();
  info.constraints = assembly.system->constraint_names();
  info.redundant = assembly.redundant_names();
  info.degrees_of_freedom = static_cast<int>(info.coordinates.size()) -
                            (static_cast<int>(info.constraints.size()) -
                             static_cast<int>(info.redundant.size()));
  return info;
}

std::string JsonString(const std::string& s) { return mbs::DoubleQuoted(s); }

namespace {
std::string JsonList(const std::vector<std::string>& names) {
  std::string out = "[";
  for (size_t i = 0; i < names.size(); ++i) out += (i ? ", " : "") + JsonString(names[i]);
  return out + "]";
}
std::string TextList(const std::vector<std::string>& names) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i ? ", " : "") + names[i];
  return out;
}
}  // namespace

std::string ModelInfo::Text() const {
  std::ostringstream s;
  s << "model:                 " << (name.empty() ? "(unnamed)" : name) << " (" << file << ")\n";
  auto line = [&s](const char* label, size_t n, const std::vector<std::string>* names) {
    s << label << n;
    if (names && !names->empty()) s << ": " << TextList(*names);
    s << "\n";
  };
  line("bodies:                ", bodies.size(), &bodies);
  line("coordinates:           ", coordinates.size(), nullptr);
  line("constraint equations:  ", constraints.size(), nullptr);
  line("redundant equations:   ", redundant.size(), &redundant);
  s << "degrees of freedom:    " << degrees_of_freedom;
  if (degrees_of_freedom == 0)
    s << " (every motion driven: `integrator: kinematic` solves the model by kinematic analysis)";
  s << "\n";
  line("joints:                ", joints.size(), &joints);
  line("measures:              ", measures.size(), &measures);
  line("forces:                ", forces.size(), &forces);
  s << "parameters:            " << parameters.size();
  for (size_t i = 0; i < parameters.size(); ++i)
    s << (i ? ", " : ": ") << parameters[i] << " = " << parameter_values[i];
  s << "\n";
  for (const std::string& note : notes) s << "note:                  " << note << "\n";
  return s.str();
}

std::string ModelInfo::Json() const {
  std::ostringstream s;
  s << "{\n  \"file\": " << JsonString(file) << ",\n  \"name\": " << JsonString(name) << ",\n";
  s << "  \"counts\": {\"bodies\": " << bodies.size() << ", \"coordinates\": " << coordinates.size()
    << ", \"constraint_equations\": " << constraints.size()
    << ", \"redundant_equations\": " << redundant.size()
    << ", \"degrees_of_freedom\": " << degrees_of_freedom << ", \"joints\": " << joints.size()
    << ", \"measures\": " << measures.size() << ", \"forces\": " << forces.size()
    << ", \"parameters\": " << parameters.size() << "},\n";
  s << "  \"bodies\": " << JsonList(bodies) << ",\n";
  s << "  \"coordinates\": " << JsonList(coordinates) << ",\n";
  s << "  \"constraint_equations\": " << JsonList(constraints) << ",\n";
  s << "  \"redundant_equations\": " << JsonList(redundant) << ",\n";
  s << "  \"joints\": " << JsonList(joints) << ",\n";
  s << "  \"measures\": " << JsonList(measures) << ",\n";
  s << "  \"forces\": " << JsonList(forces) << ",\n";
  s << "  \"parameters\": {";
  for (size_t i = 0; i < parameters.size(); ++i)
    s << (i ? ", " : "") << JsonString(parameters[i]) << ": " << Num(parameter_values[i]);
  s << "}";
  if (!notes.empty()) s << ",\n  \"notes\": " << JsonList(notes);  // imported models (URDF)
  s << "\n}\n";
  return s.str();
}

bool SameFile(const std::string& a, const std::string& b) {
  struct stat sa, sb;
  if (stat(a.c_str(), &sa) != 0 || stat(b.c_str(), &sb) != 0) return false;
  return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

ResultsDestination::ResultsDestination(const std::string& path, const std::string& input)
    : path_(path), target_(path) {
  auto directory_of = [](const std::string& file) -> std::string {
    const auto slash = file.find_last_of('/');
    return slash == std::string::npos ? "." : slash == 0 ? "/" : file.substr(0, slash);
  };
  // Write where a symbolic link points, also one to a file still to be made (renaming
  // over the link would replace the link).
  struct stat st;
  for (int links = 0; lstat(target_.c_str(), &st) == 0 && S_ISLNK(st.st_mode); ++links) {
    if (links == 40) Refuse(std::strerror(ELOOP));
    std::vector<char> buffer(static_cast<size_t>(st.st_size > 0 ? st.st_size : 255) + 1);
    const ssize_t n = readlink(target_.c_str(), buffer.data(), buffer.size() - 1);
    if (n < 0) Refuse(std::strerror(errno));
    const std::string next(buffer.data(), static_cast<size_t>(n));
    target_ = next.empty() || next[0] == '/' ? next : directory_of(target_) + "/" + next;
  }
  if (stat(target_.c_str(), &st) == 0) {
    if (!input.empty() && SameFile(target_, input))
      throw UsageError("the results file '" + path + "' is the input file '" + input +
                       "' itself: give another name with -o");
    if (S_ISDIR(st.st_mode)) Refuse(std::strerror(EISDIR));
    if (access(target_.c_str(), W_OK) != 0) Refuse(std::strerror(errno));
  }
  // The temporary file is created in the destination's directory and renamed there.
  const std::string dir = directory_of(target_);
  if (stat(dir.c_str(), &st) != 0) Refuse(std::strerror(errno));
  if (!S_ISDIR(st.st_mode)) Refuse(std::strerror(ENOTDIR));
  if (access(dir.c_str(), W_OK | X_OK) != 0) Refuse(std::strerror(errno));
}

void ResultsDestination::Refuse(const std::string& why) const {
  throw UsageError("cannot write the results file '" + path_ + "': " + why);
}

const std::string& ResultsDestination::CreateTemporary() {
  if (created_) return temporary_;
  temporary_ = target_ + "." + std::to_string(static_cast<long>(getpid())) + ".tmp";
  const int fd = open(temporary_.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0666);
  if (fd < 0) Refuse(std::strerror(errno));
  close(fd);
  created_ = true;
  return temporary_;
}

ResultsDestination::~ResultsDestination() {
  if (created_ && !committed_) unlink(temporary_.c_str());
}

void ResultsDestination::Commit() {
  if (std::rename(temporary_.c_str(), target_.c_str()) != 0)
    throw std::runtime_error("cannot rename '" + temporary_ + "' to '" + path_ + "': " + std::strerror(errno));
  committed_ = true;
}

}  // namespace mbdae::app
