// The /geometry group of the results file (docs/results-file.md, "Geometry"): what is
// drawn for each body (mbs/visual.h), the markers and the joints' markers, in body axes,
// so that a results file alone is enough to draw the run (`mbdae view`, docs/viewer.md).
// And a small reader of results files for the viewer.
#pragma once

#include <string>
#include <vector>

#include "io/results_file.h"
#include "mbs/model.h"

namespace mbdae::io {

// Writes /geometry for `model` into an open results file (at its creation, so that a
// failed or stopped run has it too). Mesh shapes carry their triangles (the file is read
// again here). Throws std::runtime_error on an HDF5 failure or an unreadable mesh.
void WriteModelGeometry(ResultsFile& file, const mbs::Model& model);

// Reads datasets and root attributes of an HDF5 file. The constructor throws
// NotAResultsFile when the file is not HDF5 or has no /time dataset (message: the path
// and what is missing), std::runtime_error when it cannot be opened.
class NotAResultsFile : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ResultsReader {
 public:
  explicit ResultsReader(const std::string& path);
  ~ResultsReader();
  ResultsReader(const ResultsReader&) = delete;
  ResultsReader& operator=(const ResultsReader&) = delete;

  bool Has(const std::string& object_path) const;  // a dataset or group
  // A numeric dataset as doubles (row-major) and its dimensions; throws if absent.
  std::vector<double> Doubles(const std::string& dataset_path, std::vector<size_t>* dims = nullptr) const;
  std::vector<std::string> Strings(const std::string& dataset_path) const;
  // The names in a group (in name order); empty if absent.
  std::vector<std::string> Children(const std::string& group_path) const;
  // Root attributes; `fallback` when absent or of another type.
  std::string StringAttribute(const std::string& name, const std::string& fallback = "") const;
  double NumberAttribute(const std::string& name, double fallback) const;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  long long file_ = -1;  // hid_t
};

}  // namespace mbdae::io
