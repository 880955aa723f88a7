// The HDF5 results file of the command-line contract: one row per output time,
// extendible datasets flushed as the run goes.
//
// Datasets (N rows so far):
//   /time N; /q /v /a N x nq; /q_names nq; /lambda N x nc; /lambda_names nc;
//   /bodies/NAME/{position N x 3, orientation N x 4, velocity N x 3, angular_velocity N x 3};
//   /measures/NAME N; /joints/NAME/{force,torque} N x 3, /joints/NAME/effort N (driven
//   joints); /forces/NAME/{force,torque} N x 3;
//   /energy/{kinetic,potential} N; /violation/{position,velocity} N (max |C|, max |C_q v + C_t|).
// Name lists are variable-length UTF-8 string datasets. Every dataset is chunked with an
// unlimited first dimension and, by default, the rows are written and the file flushed
// after every row, so a run that is stopped keeps the rows it computed (see
// set_flush_interval for the cheaper variant).
#pragma once

#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace mbdae::io {

struct ResultsLayout {
  std::vector<std::string> q_names;       // nq
  std::vector<std::string> lambda_names;  // nc (kept equations)
  std::vector<std::string> bodies;        // /bodies/NAME/{position,orientation,velocity,angular_velocity}
  std::vector<std::string> measures;      // /measures/NAME
  std::vector<std::string> joints;        // /joints/NAME/{force,torque}
  // Joints of `joints` that also have /joints/NAME/effort (the actuator effort of a
  // driven joint), in the order of ResultsRow::effort_data.
  std::vector<std::string> efforts;
  // Joints of `joints` with a joint coordinate (revolute, prismatic joints of a tree:
  // mbs/joint_space.h), /joints/NAME/{position,rate,acceleration,generalized_force}, in
  // the order of ResultsRow::joint_coordinate_data.
  std::vector<std::string> joint_coordinates;
  std::vector<std::string> forces;        // /forces/NAME/{force,torque}
  // Added: which entries of `bodies`, `measures`, `joints` and `forces` get their
  // datasets (flags parallel to those lists; an empty vector: all of them). A joint left
  // out has no /joints/NAME group at all (no force, torque, effort or joint-coordinate
  // datasets). The rows still carry every element's values (ResultsRow's layout does not
  // change); /q, /v, /a and /lambda are always written. Each per-element dataset costs
  // HDF5 object creation, writes and a flush (0.6 to 0.9 ms per body with its joint), so a
  // large model whose run needs a few of them leaves the others out.
  std::vector<bool> write_bodies, write_measures, write_joints, write_forces;
  // The rows the run writes if it completes (0: not known). Only the storage depends on
  // it: a dataset's chunks (about 8 KiB, at least 16 rows) hold at most this many rows,
  // so that a short run of a large model does not allocate a full chunk per dataset
  // (8 KiB x 9000 datasets for 1000 bodies). More rows may be written all the same.
  long expected_rows = 0;
};

// One output row. Body data per body: position(3) orientation(4) velocity(3) angular_velocity(3).
// Null pointers write zeros (so a partial row is still well formed).
struct ResultsRow {
  double t = 0;
  const double* q = nullptr;
  const double* v = nullptr;
  const double* a = nullptr;
  const double* lambda = nullptr;
  const double* body_data = nullptr;     // 13 per body
  const double* measures = nullptr;      // one per measure
  const double* joint_data = nullptr;    // 6 per joint: force(3), torque(3)
  const double* effort_data = nullptr;   // one per ResultsLayout::efforts entry
  const double* joint_coordinate_data = nullptr;  // 4 per ResultsLayout::joint_coordinates entry
  const double* force_data = nullptr;    // 6 per force element: force(3), torque(3)
  double kinetic_energy = 0;             // /energy/kinetic
  double potential_energy = 0;           // /energy/potential
  double position_violation = 0;         // /violation/position
  double velocity_violation = 0;         // /violation/velocity
};

class ResultsFile {
 public:
  // Creates (truncates) the file; throws std::runtime_error on failure (the message
  // names the path). Names containing '/' or empty names are rejected the same way.
  ResultsFile(const std::string& path, const ResultsLayout& layout);
  ~ResultsFile();
  ResultsFile(const ResultsFile&) = delete;
  ResultsFile& operator=(const ResultsFile&) = delete;

  // Adds one row to every dataset; written and flushed now or, with a flush interval,
  // at the next flush.
  void AppendRow(const ResultsRow& row);
  // Root attributes (numbers and strings); setting one again replaces it.
  void SetAttribute(const std::string& name, double value);
  void SetAttribute(const std::string& name, const std::string& value);
  // Added: integer attributes (stored as 64-bit integers) and string lists.
  void SetAttribute(const std::string& name, int value) { SetAttribute(name, static_cast<long>(value)); }
  void SetAttribute(const std::string& name, long value);
  void SetAttribute(const std::string& name, const char* value) { SetAttribute(name, std::string(value)); }
  void SetAttribute(const std::string& name, const std::vector<std::string>& values);
  // Added: numeric attributes of the group at `path` ("objectives/G"; created with its
  // parents if absent), each replacing an attribute of that name.
  void SetGroupAttributes(const std::string& path,
                          const std::vector<std::pair<std::string, double>>& attributes);
  // Added: a string-list attribute of the group at `path`, and a 1-D float64 dataset in
  // it (both created with the group if absent, replacing one of that name).
  void SetGroupAttribute(const std::string& path, const std::string& name,
                         const std::vector<std::string>& values);
  void WriteGroupDataset(const std::string& path, const std::string& name,
                         const std::vector<double>& values);
  // Added (the /geometry group, io/results_geometry.h): fixed-size datasets written
  // once, parent groups created, replacing one of the same path: rows x cols float64
  // (cols >= 1; 0: a 1-D dataset) or int64 from row-major values, and 1-D
  // variable-length UTF-8 strings.
  // Throw std::runtime_error when values.size() is not a multiple of cols.
  void WriteTable(const std::string& dataset_path, int cols, const std::vector<double>& values);
  void WriteIntegerTable(const std::string& dataset_path, int cols, const std::vector<long>& values);
  void WriteStringDataset(const std::string& dataset_path, const std::vector<std::string>& values);
  void Flush();  // writes the pending rows and flushes the file
  // Added: AppendRow flushes when at least this many seconds (wall clock), and at least
  // 10 times what the last flush took, passed since the last flush; 0 (the default)
  // flushes after every row. A positive value bounds what a killed run loses to that
  // much computing time (or 10 flushes' time) and makes long outputs cheap.
  void set_flush_interval(double seconds);
  long rows() const;
  const std::string& path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Additions to an existing results file (e.g. the gradient of its run): per group
// (created with its parents if absent) numeric attributes, string-list attributes and
// 1-D float64 datasets, and string attributes of the root; each replaces one of the
// same name. Throws std::runtime_error if the file cannot be opened or written.
struct ResultsGroup {
  std::string path;  // e.g. "objectives/G"
  std::vector<std::pair<std::string, double>> numbers;
  std::vector<std::pair<std::string, std::vector<std::string>>> strings;
  std::vector<std::pair<std::string, std::vector<double>>> datasets;
};
void AddToResultsFile(const std::string& path, const std::vector<ResultsGroup>& groups,
                      const std::vector<std::pair<std::string, std::string>>& root_strings = {});

// Added to an existing results file: a rows x cols float64 dataset at dataset_path (e.g.
// "optimization/history"; parent groups created) from row-major values (rows =
// values.size() / cols), with the string-list attribute `columns` naming the columns;
// and a 1-D dataset of variable-length UTF-8 strings. Each replaces a dataset of the same
// path. Throw std::runtime_error if the file cannot be opened or written, or (table) if
// cols < 1, values.size() is not a multiple of cols or columns.size() != cols.
void AddTableToResultsFile(const std::string& path, const std::string& dataset_path, int cols,
                           const std::vector<double>& values, const std::vector<std::string>& columns);
void AddStringsToResultsFile(const std::string& path, const std::string& dataset_path,
                             const std::vector<std::string>& values);

}  // namespace mbdae::io
