// The results files of the C API (mbdae_write_results, mbdae_gradient, mbdae_optimize)
// are written as `mbdae simulate -o` writes its own: into PATH.PID.tmp beside PATH and
// renamed over it at the end, so that an earlier file stays whole until then and after a
// call that fails; a path that is the model (or problem) file, by any spelling or link,
// is refused with MBDAE_ERROR_IO; no temporary file is left behind. Through the shared
// library and the C header only.
#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "mbdae.h"

namespace {

namespace fs = std::filesystem;

#define ASSERT_MBDAE_OK(expr) ASSERT_EQ((expr), MBDAE_OK) << mbdae_last_error()

const std::string kEarlier = "an earlier results file\n";

std::string Read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void Write(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

bool IsHdf5(const std::string& path) { return Read(path).rfind("\x89HDF\r\n\x1a\n", 0) == 0; }

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

// A folder of its own for each test, removed at the end.
class Folder {
 public:
  Folder() {
    std::string pattern = ::testing::TempDir() + "mbdae_results_XXXXXX";
    path_ = mkdtemp(&pattern[0]);
  }
  ~Folder() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string operator/(const std::string& name) const { return path_ + "/" + name; }
  // The files of the folder whose names end in ".tmp".
  std::vector<std::string> Temporaries() const {
    std::vector<std::string> out;
    for (const auto& entry : fs::directory_iterator(path_)) {
      const std::string name = entry.path().filename().string();
      if (name.size() > 4 && name.compare(name.size() - 4, 4, ".tmp") == 0) out.push_back(name);
    }
    return out;
  }

 private:
  std::string path_;
};

const std::vector<std::string> kNone;

class Model {
 public:
  explicit Model(const std::string& path) {
    EXPECT_EQ(mbdae_model_from_file(path.c_str(), &m_), MBDAE_OK) << mbdae_last_error();
  }
  ~Model() { mbdae_model_free(m_); }
  Model(const Model&) = delete;
  Model& operator=(const Model&) = delete;
  operator mbdae_model*() const { return m_; }

 private:
  mbdae_model* m_ = nullptr;
};

// The model file, by its own name, through "/./" and through a symbolic link: each is
// refused with MBDAE_ERROR_IO naming both, and leaves the model as it was.
template <class Call>
void ExpectTheModelFileIsRefused(const Folder& folder, const std::string& model, Call call) {
  const std::string before = Read(model);
  const std::string name = fs::path(model).filename().string();
  std::error_code ec;
  fs::create_symlink(name, folder / "link.yaml", ec);
  for (const std::string& path : {model, folder / ("./" + name), folder / "link.yaml"}) {
    EXPECT_EQ(call(path), MBDAE_ERROR_IO) << path;
    const std::string message = mbdae_last_error();
    EXPECT_TRUE(Contains(message, "the results file '" + path + "' is the ")) << message;
    EXPECT_TRUE(Contains(message, name + "' itself")) << message;
  }
  EXPECT_EQ(Read(model), before);
  EXPECT_EQ(folder.Temporaries(), kNone);
}

// ---- mbdae_write_results ----------------------------------------------------------------

TEST(ApiResultsFile, WriteResultsReplacesAnEarlierFileOnlyWhenComplete) {
  Folder folder;
  const std::string model_path = folder / "pendulum.yaml";
  Write(model_path, Read(MBDAE_PENDULUM));
  Model m(model_path);
  ASSERT_MBDAE_OK(mbdae_set_option(m, "t_end", "0.1"));
  const std::string out = folder / "out.h5";
  Write(out, kEarlier);
  // Nothing to write yet (no rows): an error, and the earlier file as it was.
  EXPECT_EQ(mbdae_write_results(m, out.c_str()), MBDAE_ERROR_ORDER);
  EXPECT_EQ(Read(out), kEarlier);
  ASSERT_MBDAE_OK(mbdae_solve(m));
  // A destination the system refuses (a folder): its reason, the earlier file kept.
  const std::string sub = folder / "sub";
  fs::create_directory(sub);
  EXPECT_EQ(mbdae_write_results(m, sub.c_str()), MBDAE_ERROR_IO);
  EXPECT_TRUE(Contains(mbdae_last_error(), "cannot write the results file '" + sub + "': Is a directory"))
      << mbdae_last_error();
  EXPECT_EQ(mbdae_write_results(m, ""), MBDAE_ERROR_IO);
  EXPECT_EQ(folder.Temporaries(), kNone);
  // Written and renamed over the earlier file; written again over itself.
  ASSERT_MBDAE_OK(mbdae_write_results(m, out.c_str()));
  EXPECT_TRUE(IsHdf5(out));
  const std::string first = Read(out);
  ASSERT_MBDAE_OK(mbdae_write_results(m, out.c_str()));
  EXPECT_EQ(Read(out).size(), first.size());
  // Through a symbolic link: the file it points to is replaced, the link kept.
  fs::create_symlink("out.h5", folder / "results_link.h5");
  Write(out, kEarlier);
  ASSERT_MBDAE_OK(mbdae_write_results(m, (folder / "results_link.h5").c_str()));
  EXPECT_TRUE(fs::is_symlink(folder / "results_link.h5"));
  EXPECT_TRUE(IsHdf5(out));
  EXPECT_EQ(folder.Temporaries(), kNone);
}

TEST(ApiResultsFile, WriteResultsRefusesTheModelFile) {
  Folder folder;
  const std::string model_path = folder / "pendulum.yaml";
  Write(model_path, Read(MBDAE_PENDULUM));
  Model m(model_path);
  ASSERT_MBDAE_OK(mbdae_set_option(m, "t_end", "0.05"));
  ASSERT_MBDAE_OK(mbdae_solve(m));
  ExpectTheModelFileIsRefused(folder, model_path,
                              [&](const std::string& path) { return mbdae_write_results(m, path.c_str()); });
  EXPECT_TRUE(Contains(mbdae_last_error(), "is the model file")) << mbdae_last_error();
}

// ---- mbdae_gradient -------------------------------------------------------------------

TEST(ApiResultsFile, GradientKeepsTheEarlierFileWhenItFailsAndReplacesItAtTheEnd) {
  Folder folder;
  const std::string model_path = folder / "oscillator.yaml";
  Write(model_path, Read(std::string(MBDAE_API_TEST_MODELS) + "/gradient_oscillator.yaml"));
  Model m(model_path);
  ASSERT_MBDAE_OK(mbdae_set_option(m, "t_end", "0.2"));
  const std::string out = folder / "g.h5";
  Write(out, kEarlier);
  const char* wrt[] = {"k"};
  // An error of the call after the results file was set up (an unknown method is found
  // first; a bad option value inside the driver: a trajectory budget below one step):
  // the earlier file as it was, no temporary file.
  EXPECT_EQ(mbdae_gradient(m, "newton", nullptr, 0, wrt, 1, 0, out.c_str()), MBDAE_ERROR_ARGUMENT);
  ASSERT_MBDAE_OK(mbdae_set_option(m, "gradient.trajectory_memory", "1"));
  EXPECT_EQ(mbdae_gradient(m, "adjoint", nullptr, 0, wrt, 1, 0, out.c_str()), MBDAE_ERROR_INPUT)
      << mbdae_last_error();
  EXPECT_EQ(Read(out), kEarlier);
  EXPECT_EQ(folder.Temporaries(), kNone);
  // Success: renamed over the earlier file; the report names the path given.
  ASSERT_MBDAE_OK(mbdae_set_option(m, "gradient.trajectory_memory", "1e9"));
  ASSERT_MBDAE_OK(mbdae_gradient(m, "adjoint", nullptr, 0, wrt, 1, 0, out.c_str()));
  EXPECT_TRUE(IsHdf5(out));
  size_t length = 0;
  ASSERT_MBDAE_OK(mbdae_gradient_report(m, 0, nullptr, 0, &length));
  std::string report(length, '\0');
  ASSERT_MBDAE_OK(mbdae_gradient_report(m, 0, &report[0], length, nullptr));
  EXPECT_TRUE(Contains(report, "results: " + out + "\n")) << report;
  EXPECT_FALSE(Contains(report, ".tmp")) << report;
  EXPECT_EQ(folder.Temporaries(), kNone);
  ExpectTheModelFileIsRefused(folder, model_path, [&](const std::string& path) {
    return mbdae_gradient(m, "adjoint", nullptr, 0, wrt, 1, 0, path.c_str());
  });
}

// A forward run that fails is MBDAE_ERROR_SOLVER and its file (status "failed") replaces
// the earlier one, as `mbdae gradient -o` does (exit 3).
TEST(ApiResultsFile, GradientWritesAFailedForwardRun) {
  Folder folder;
  const std::string model_path = folder / "failing.yaml";
  std::string text = Read(std::string(MBDAE_API_TEST_MODELS) + "/gradient_oscillator.yaml");
  text = Replace(text, "\"spline(u, t)\"", "\"spline(u, t) + 0.01*log(0.1 - t)\"");
  Write(model_path, text);
  Model m(model_path);
  ASSERT_MBDAE_OK(mbdae_set_option(m, "t_end", "0.2"));
  const std::string out = folder / "g.h5";
  Write(out, kEarlier);
  const char* wrt[] = {"k"};
  EXPECT_EQ(mbdae_gradient(m, "adjoint", nullptr, 0, wrt, 1, 0, out.c_str()), MBDAE_ERROR_SOLVER)
      << mbdae_last_error();
  EXPECT_TRUE(IsHdf5(out));
  EXPECT_TRUE(Contains(Read(out), "failed"));
  EXPECT_EQ(folder.Temporaries(), kNone);
}

// ---- mbdae_optimize -------------------------------------------------------------------

struct Watch {
  std::string out, folder;
  int calls = 0, kept = 0, temporaries = 0, stop_at = 1, answer = 1;
};

// Checks during the optimisation that the earlier file is whole and that the temporary
// file exists beside it; stops at iteration stop_at with `answer`.
int Check(int iteration, double, double, void* data) {
  auto* w = static_cast<Watch*>(data);
  ++w->calls;
  if (Read(w->out) == kEarlier) ++w->kept;
  const std::string temporary = w->out + "." + std::to_string(getpid()) + ".tmp";
  if (fs::exists(temporary)) ++w->temporaries;
  return iteration == w->stop_at ? w->answer : 0;
}

std::string OptimizationReport(const mbdae_optimization* r) {
  size_t length = 0;
  EXPECT_EQ(mbdae_optimization_report(r, 0, nullptr, 0, &length), MBDAE_OK) << mbdae_last_error();
  std::string text(length, '\0');
  EXPECT_EQ(mbdae_optimization_report(r, 0, &text[0], length, nullptr), MBDAE_OK) << mbdae_last_error();
  return text;
}

TEST(ApiResultsFile, OptimizeKeepsTheEarlierFileUntilTheEnd) {
  Folder folder;
  Write(folder / "rotor.yaml", Read(std::string(MBDAE_OPTIMIZE_DIR) + "/rotor.yaml"));
  const std::string problem = folder / "problem.yaml";
  Write(problem, Read(std::string(MBDAE_OPTIMIZE_DIR) + "/rotor_problem.yaml"));
  Watch w;
  w.out = folder / "o.h5";
  Write(w.out, kEarlier);
  // Stopped at iteration 1 (positive answer): the final run is written and renamed.
  mbdae_optimization* r = nullptr;
  ASSERT_MBDAE_OK(mbdae_optimize(problem.c_str(), w.out.c_str(), Check, &w, &r));
  EXPECT_EQ(w.calls, 2);
  EXPECT_EQ(w.kept, 2);         // the earlier file whole during the run
  EXPECT_EQ(w.temporaries, 2);  // and the temporary file beside it
  EXPECT_TRUE(IsHdf5(w.out));
  EXPECT_TRUE(Contains(OptimizationReport(r), "results: " + w.out + "\n")) << OptimizationReport(r);
  mbdae_optimization_free(r);
  EXPECT_EQ(folder.Temporaries(), kNone);

  // A negative answer abandons the results file: the earlier one stays.
  Write(w.out, kEarlier);
  w = Watch{w.out};
  w.answer = -1;
  r = nullptr;
  ASSERT_MBDAE_OK(mbdae_optimize(problem.c_str(), w.out.c_str(), Check, &w, &r));
  EXPECT_EQ(w.calls, 2);
  EXPECT_EQ(Read(w.out), kEarlier);
  EXPECT_FALSE(Contains(OptimizationReport(r), "results:")) << OptimizationReport(r);
  mbdae_optimization_free(r);
  EXPECT_EQ(folder.Temporaries(), kNone);

  // A mistake found before anything runs: the earlier file as it was.
  const std::string bad = Replace(Read(problem), "upper: 40}", "upper: 40, start: 41}");
  r = nullptr;
  EXPECT_EQ(mbdae_optimize_string(bad.c_str(), problem.c_str(), w.out.c_str(), nullptr, nullptr, &r),
            MBDAE_ERROR_INPUT);
  EXPECT_EQ(Read(w.out), kEarlier);
  EXPECT_EQ(folder.Temporaries(), kNone);

  // The problem file and the problem's model file are refused (as a string: its model).
  ExpectTheModelFileIsRefused(folder, problem, [&](const std::string& path) {
    mbdae_optimization* none = nullptr;
    return mbdae_optimize(problem.c_str(), path.c_str(), nullptr, nullptr, &none);
  });
  EXPECT_TRUE(Contains(mbdae_last_error(), "is the problem file")) << mbdae_last_error();
  fs::remove(folder / "link.yaml");
  ExpectTheModelFileIsRefused(folder, folder / "rotor.yaml", [&](const std::string& path) {
    mbdae_optimization* none = nullptr;
    return mbdae_optimize(problem.c_str(), path.c_str(), nullptr, nullptr, &none);
  });
  EXPECT_TRUE(Contains(mbdae_last_error(), "is the model file of the problem")) << mbdae_last_error();
  const std::string text = Read(problem);
  mbdae_optimization* none = nullptr;
  EXPECT_EQ(mbdae_optimize_string(text.c_str(), problem.c_str(), (folder / "rotor.yaml").c_str(), nullptr,
                                  nullptr, &none),
            MBDAE_ERROR_IO);
  EXPECT_EQ(none, nullptr);
  EXPECT_EQ(folder.Temporaries(), kNone);
}

}  // namespace
