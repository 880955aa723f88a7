// The HDF5 results file of the command-line contract: one row per output time,
// extendible datasets flushed as the run goes.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace mbdae::io {

struct ResultsLayout {
  std::vector<std::string> q_names;       // nq
  std::vector<std::string> lambda_names;  // nc (kept equations)
  std::vector<std::string> bodies;        // /bodies/NAME/{position,orientation,velocity,angular_velocity}
  std::vector<std::string> measures;      // /measures/NAME
  std::vector<std::string> joints;        // /joints/NAME/{force,torque}
  std::vector<std::string> forces;        // /forces/NAME/{force,torque}
};

// One output row. Body data per body: position(3) orientation(4) velocity(3) angular_velocity(3).
struct ResultsRow {
  double t = 0;
  const double* q = nullptr;
  const double* v = nullptr;
  const double* a = nullptr;
  const double* lambda = nullptr;
  const double* body_data = nullptr;     // 13 per body
  const double* measures = nullptr;      // one per measure
  const double* joint_data = nullptr;    // 6 per joint: force(3), torque(3)
  const double* force_data = nullptr;    // 6 per force element: force(3), torque(3)
};

class ResultsFile {
 public:
  // Creates (truncates) the file; throws std::runtime_error on failure.
  ResultsFile(const std::string& path, const ResultsLayout& layout);
  ~ResultsFile();
  ResultsFile(const ResultsFile&) = delete;
  ResultsFile& operator=(const ResultsFile&) = delete;

  void AppendRow(const ResultsRow& row);  // extends every dataset by one row and flushes
  // Root attributes (numbers and strings).
  void SetAttribute(const std::string& name, double value);
  void SetAttribute(const std::string& name, const std::string& value);
  void Flush();
  long rows() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mbdae::io
