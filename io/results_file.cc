#include "io/results_file.h"

#include <hdf5.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <map>
#include <stdexcept>
#include <utility>

namespace mbdae::io {
namespace {

// Owns one HDF5 identifier and closes it with the matching H5?close.
class Handle {
 public:
  using Closer = herr_t (*)(hid_t);
  Handle() = default;
  Handle(hid_t id, Closer close) : id_(id), close_(close) {}
  Handle(Handle&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)), close_(o.close_) {}
  Handle& operator=(Handle&& o) noexcept {
    if (this != &o) {
      Reset();
      id_ = std::exchange(o.id_, H5I_INVALID_HID);
      close_ = o.close_;
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { Reset(); }
  void Reset() {
    if (id_ >= 0 && close_) close_(id_);
    id_ = H5I_INVALID_HID;
  }
  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }

 private:
  hid_t id_ = H5I_INVALID_HID;
  Closer close_ = nullptr;
};

// Silences the HDF5 error stack printing while alive (errors become exceptions).
class QuietErrors {
 public:
  QuietErrors() {
    H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~QuietErrors() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }

 private:
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

Handle Check(hid_t id, herr_t (*close)(hid_t), const std::string& what) {
  if (id < 0) throw std::runtime_error("HDF5: cannot " + what);
  return Handle(id, close);
}
void Check(herr_t status, const std::string& what) {
  if (status < 0) throw std::runtime_error("HDF5: cannot " + what);
}

Handle VariableStringType() {
  Handle type = Check(H5Tcopy(H5T_C_S1), H5Tclose, "copy the string type");
  Check(H5Tset_size(type.get(), H5T_VARIABLE), "make a variable-length string type");
  Check(H5Tset_cset(type.get(), H5T_CSET_UTF8), "set the UTF-8 character set");
  return type;
}

void CheckName(const std::string& name, const std::string& kind) {
  if (name.empty() || name.find('/') != std::string::npos || name == "." || name == "..")
    throw std::runtime_error("results file: " + kind + " name '" + name +
                             "' cannot be an HDF5 group or dataset name");
}

// One extendible dataset of rows x cols doubles (cols == 0: a 1-D dataset of rows).
struct RowDataset {
  Handle id;
  std::vector<double> pending;  // rows appended but not written yet
  int cols = 0;     // 0 for a 1-D dataset
  int rank = 1;
};

// Creates the run's extendible datasets. Their dataspaces and property lists depend only
// on the rank and the width, so they are made once per (rank, width) and shared (made
// per dataset they cost 3-6 % of a two-row run of the 1000-rod chain's CPU time).
class RowDatasetMaker {
 public:
  explicit RowDatasetMaker(long expected_rows) : expected_rows_(expected_rows) {
    // A chunk cache of 11 slots instead of 521: rows are appended, so a dataset only
    // ever holds its last chunk or two in the cache, and the default slot table (4 KiB
    // for every open dataset; all stay open for the run, four per body and two per
    // joint) was a page-faulting allocation. The cache's size in bytes stays HDF5's
    // default.
    dapl_ = Check(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose, "create a property list");
    Check(H5Pset_chunk_cache(dapl_.get(), 11, H5D_CHUNK_CACHE_NBYTES_DEFAULT, H5D_CHUNK_CACHE_W0_DEFAULT),
          "set a chunk cache");
  }

  RowDataset operator()(hid_t parent, const std::string& name, int cols, bool one_dim) {
    RowDataset d;
    d.cols = one_dim ? 0 : cols;
    d.rank = one_dim ? 1 : 2;
    Shape& shape = shapes_[{d.rank, d.cols}];
    if (!shape.space.valid()) {
      const int width = std::max(1, d.cols);
      hsize_t dims[2] = {0, static_cast<hsize_t>(d.cols)};
      // Unlimited in both dimensions: a fixed zero-width second dimension cannot be chunked.
      hsize_t max_dims[2] = {H5S_UNLIMITED, H5S_UNLIMITED};
      // About 8 KiB per chunk, at least 16 rows; at most the rows expected.
      hsize_t chunk_rows = std::max<hsize_t>(16, 1024 / static_cast<hsize_t>(width));
      if (expected_rows_ > 0) chunk_rows = std::min<hsize_t>(chunk_rows, static_cast<hsize_t>(expected_rows_));
      hsize_t chunk[2] = {chunk_rows, static_cast<hsize_t>(width)};
      shape.space = Check(H5Screate_simple(d.rank, dims, max_dims), H5Sclose, "create a dataspace");
      shape.dcpl = Check(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, "create a property list");
      Check(H5Pset_chunk(shape.dcpl.get(), d.rank, chunk), "set the chunk size of " + name);
    }
    d.id = Check(H5Dcreate2(parent, name.c_str(), H5T_NATIVE_DOUBLE, shape.space.get(), H5P_DEFAULT,
                            shape.dcpl.get(), dapl_.get()),
                 H5Dclose, "create dataset " + name);
    return d;
  }

 private:
  struct Shape {
    Handle space, dcpl;
  };
  long expected_rows_;
  Handle dapl_;
  std::map<std::pair<int, int>, Shape> shapes_;
};

void WriteStrings(hid_t parent, const std::string& name, const std::vector<std::string>& values) {
  Handle type = VariableStringType();
  hsize_t n = values.size();
  Handle space = Check(H5Screate_simple(1, &n, nullptr), H5Sclose, "create a dataspace");
  Handle ds = Check(H5Dcreate2(parent, name.c_str(), type.get(), space.get(), H5P_DEFAULT,
                               H5P_DEFAULT, H5P_DEFAULT),
                    H5Dclose, "create dataset " + name);
  if (values.empty()) return;
  std::vector<const char*> ptrs;
  ptrs.reserve(values.size());
  for (const auto& s : values) ptrs.push_back(s.c_str());
  // The conversion of variable-length strings goes through HDF5's type-conversion
  // buffer, 1 MiB by default and zeroed at every write: sized to the strings' handles
  // instead (32 bytes per string: the 16-byte file handle and the pointer, with room).
  // A 10-rod chain's `mbdae simulate` takes 0.093-0.098 s of wall time instead of
  // 0.139-0.142 s (bench/process_time.py, bench/results/process_time.md); in perf the
  // memset and its page faults had been 18 % of the process. The file's contents are
  // unchanged.
  Handle xfer = Check(H5Pcreate(H5P_DATASET_XFER), H5Pclose, "create a transfer property list");
  Check(H5Pset_buffer(xfer.get(), std::max<size_t>(4096, 32 * values.size()), nullptr, nullptr),
        "set the conversion buffer of dataset " + name);
  Check(H5Dwrite(ds.get(), type.get(), H5S_ALL, H5S_ALL, xfer.get(), ptrs.data()),
        "write dataset " + name);
}

Handle CreateGroup(hid_t parent, const std::string& name) {
  return Check(H5Gcreate2(parent, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose,
               "create group " + name);
}

}  // namespace

struct ResultsFile::Impl {
  std::string path;
  ResultsLayout layout;
  Handle file;
  long rows = 0;
  RowDataset time, q, v, a, lambda;
  std::vector<RowDataset> body_datasets;  // 4 per body
  std::vector<RowDataset> measures;
  std::vector<RowDataset> joints;         // 2 per joint
  std::vector<RowDataset> efforts;        // one per layout.efforts entry
  std::vector<RowDataset> joint_coordinates;  // 4 per layout.joint_coordinates entry
  std::vector<RowDataset> forces;         // 2 per force
  // The row entries given datasets (layout.write_* applied): indices into the row's
  // bodies, measures, joints, efforts, joint coordinates and forces, increasing.
  std::vector<int> body_rows, measure_rows, joint_rows, effort_rows, joint_coordinate_rows, force_rows;
  RowDataset kinetic, potential, position_violation, velocity_violation;
  std::vector<double> zeros;
  double flush_interval = 0;
  double last_flush_seconds = 0;  // wall time the last flush took
  std::chrono::steady_clock::time_point last_flush = std::chrono::steady_clock::now();

  long written = 0;  // rows already in the datasets; rows - written are pending

  // Queues one row of d (cols values, or one for 1-D; null: zeros).
  void Append(RowDataset& d, const double* values) {
    const int width = std::max(1, d.cols);
    if (d.rank == 2 && d.cols == 0) return;  // nothing to keep of a zero-width row
    if (values == nullptr)
      d.pending.insert(d.pending.end(), width, 0.0);
    else
      d.pending.insert(d.pending.end(), values, values + width);
  }

  // Extends d to `rows` rows and writes its pending rows there.
  void WritePending(RowDataset& d) {
    const hsize_t n = static_cast<hsize_t>(rows - written);
    hsize_t new_dims[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(d.cols)};
    Check(H5Dset_extent(d.id.get(), new_dims), "extend a dataset of " + path);
    if (n == 0 || d.pending.empty()) return;
    assert(d.pending.size() == n * std::max(1, d.cols));
    Handle file_space = Check(H5Dget_space(d.id.get()), H5Sclose, "get a dataspace");
    hsize_t start[2] = {static_cast<hsize_t>(written), 0};
    hsize_t count[2] = {n, static_cast<hsize_t>(d.cols)};
    Check(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr),
          "select rows");
    hsize_t mem_count = static_cast<hsize_t>(d.pending.size());
    Handle mem_space = Check(H5Screate_simple(1, &mem_count, nullptr), H5Sclose,
                             "create a dataspace");
    Check(H5Dwrite(d.id.get(), H5T_NATIVE_DOUBLE, mem_space.get(), file_space.get(), H5P_DEFAULT,
                   d.pending.data()),
          "write rows to " + path);
    d.pending.clear();
  }

  void WriteAllPending() {
    if (written == rows) return;
    for (RowDataset* d : {&time, &q, &v, &a, &lambda, &kinetic, &potential, &position_violation,
                          &velocity_violation})
      WritePending(*d);
    for (auto* group : {&body_datasets, &measures, &joints, &efforts, &joint_coordinates, &forces})
      for (auto& d : *group) WritePending(d);
    written = rows;
  }

  void DeleteAttributeIfPresent(const std::string& name) {
    htri_t exists = H5Aexists(file.get(), name.c_str());
    Check(exists < 0 ? -1 : 0, "query attribute " + name);
    if (exists > 0) Check(H5Adelete(file.get(), name.c_str()), "delete attribute " + name);
  }
};

ResultsFile::ResultsFile(const std::string& path, const ResultsLayout& layout)
    : impl_(std::make_unique<Impl>()) {
  QuietErrors quiet;
  Impl& m = *impl_;
  m.path = path;
  m.layout = layout;
  for (const auto& n : layout.bodies) CheckName(n, "body");
  for (const auto& n : layout.measures) CheckName(n, "measure");
  for (const auto& n : layout.joints) CheckName(n, "joint");
  // Joints by name (efforts and joint coordinates name their joint): one lookup each
  // instead of a search of the list, which grew as joints x efforts.
  std::map<std::string, int> joint_index;
  for (size_t j = 0; j < layout.joints.size(); ++j) joint_index.emplace(layout.joints[j], static_cast<int>(j));
  auto joint_of = [&](const std::string& n, const char* what) {
    const auto it = joint_index.find(n);
    if (it == joint_index.end())
      throw std::runtime_error(std::string("results file: ") + what + " of '" + n + "', which is not a joint");
    return it->second;
  };
  for (const auto& n : layout.efforts) joint_of(n, "effort");
  for (const auto& n : layout.joint_coordinates) joint_of(n, "joint coordinate");
  for (const auto& n : layout.forces) CheckName(n, "force");
  auto selected = [&](const std::vector<bool>& flags, size_t count, const char* what) {
    if (!flags.empty() && flags.size() != count)
      throw std::runtime_error("results file '" + path + "': " + std::to_string(flags.size()) + " flags for " +
                               std::to_string(count) + " " + what);
    std::vector<int> rows;
    for (size_t i = 0; i < count; ++i)
      if (flags.empty() || flags[i]) rows.push_back(static_cast<int>(i));
    return rows;
  };
  m.body_rows = selected(layout.write_bodies, layout.bodies.size(), "bodies");
  m.measure_rows = selected(layout.write_measures, layout.measures.size(), "measures");
  m.joint_rows = selected(layout.write_joints, layout.joints.size(), "joints");
  m.force_rows = selected(layout.write_forces, layout.forces.size(), "forces");
  std::vector<bool> joint_written(layout.joints.size(), false);
  for (int j : m.joint_rows) joint_written[j] = true;
  for (size_t i = 0; i < layout.efforts.size(); ++i)
    if (joint_written[joint_of(layout.efforts[i], "effort")]) m.effort_rows.push_back(static_cast<int>(i));
  for (size_t i = 0; i < layout.joint_coordinates.size(); ++i)
    if (joint_written[joint_of(layout.joint_coordinates[i], "joint coordinate")])
      m.joint_coordinate_rows.push_back(static_cast<int>(i));

  m.file = Handle(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
  if (!m.file.valid()) throw std::runtime_error("cannot create the results file '" + path + "'");
  const hid_t f = m.file.get();
  const int nq = static_cast<int>(layout.q_names.size());
  const int nc = static_cast<int>(layout.lambda_names.size());
  RowDatasetMaker make(layout.expected_rows);

  m.time = make(f, "time", 0, true);
  m.q = make(f, "q", nq, false);
  m.v = make(f, "v", nq, false);
  m.a = make(f, "a", nq, false);
  m.lambda = make(f, "lambda", nc, false);
  WriteStrings(f, "q_names", layout.q_names);
  WriteStrings(f, "lambda_names", layout.lambda_names);

  Handle bodies = CreateGroup(f, "bodies");
  for (int b : m.body_rows) {
    Handle g = CreateGroup(bodies.get(), layout.bodies[b]);
    m.body_datasets.push_back(make(g.get(), "position", 3, false));
    m.body_datasets.push_back(make(g.get(), "orientation", 4, false));
    m.body_datasets.push_back(make(g.get(), "velocity", 3, false));
    m.body_datasets.push_back(make(g.get(), "angular_velocity", 3, false));
  }
  Handle measures = CreateGroup(f, "measures");
  for (int i : m.measure_rows)
    m.measures.push_back(make(measures.get(), layout.measures[i], 0, true));
  Handle joints = CreateGroup(f, "joints");
  for (int j : m.joint_rows) {
    Handle g = CreateGroup(joints.get(), layout.joints[j]);
    m.joints.push_back(make(g.get(), "force", 3, false));
    m.joints.push_back(make(g.get(), "torque", 3, false));
  }
  for (int i : m.effort_rows) {
    const std::string& name = layout.efforts[i];
    Handle g = Check(H5Gopen2(joints.get(), name.c_str(), H5P_DEFAULT), H5Gclose,
                     "open the group of joint " + name);
    m.efforts.push_back(make(g.get(), "effort", 0, true));
  }
  for (int i : m.joint_coordinate_rows) {
    const std::string& name = layout.joint_coordinates[i];
    Handle g = Check(H5Gopen2(joints.get(), name.c_str(), H5P_DEFAULT), H5Gclose,
                     "open the group of joint " + name);
    for (const char* d : {"position", "rate", "acceleration", "generalized_force"})
      m.joint_coordinates.push_back(make(g.get(), d, 0, true));
  }
  Handle forces = CreateGroup(f, "forces");
  for (int i : m.force_rows) {
    Handle g = CreateGroup(forces.get(), layout.forces[i]);
    m.forces.push_back(make(g.get(), "force", 3, false));
    m.forces.push_back(make(g.get(), "torque", 3, false));
  }
  Handle energy = CreateGroup(f, "energy");
  m.kinetic = make(energy.get(), "kinetic", 0, true);
  m.potential = make(energy.get(), "potential", 0, true);
  Handle violation = CreateGroup(f, "violation");
  m.position_violation = make(violation.get(), "position", 0, true);
  m.velocity_violation = make(violation.get(), "velocity", 0, true);
  SetAttribute("format", 1L);
  Flush();
}

ResultsFile::~ResultsFile() {
  if (impl_ && impl_->file.valid()) {
    QuietErrors quiet;
    try {
      impl_->WriteAllPending();
    } catch (const std::exception&) {
      // A destructor cannot report; the rows already flushed stay in the file.
    }
    H5Fflush(impl_->file.get(), H5F_SCOPE_GLOBAL);
  }
}

void ResultsFile::AppendRow(const ResultsRow& row) {
  QuietErrors quiet;
  Impl& m = *impl_;
  m.Append(m.time, &row.t);
  m.Append(m.q, row.q);
  m.Append(m.v, row.v);
  m.Append(m.a, row.a);
  m.Append(m.lambda, row.lambda);
  static constexpr int kBodyOffsets[4] = {0, 3, 7, 10};
  for (size_t i = 0; i < m.body_rows.size(); ++i) {
    const int b = m.body_rows[i];
    for (int k = 0; k < 4; ++k)
      m.Append(m.body_datasets[4 * i + k],
               row.body_data ? row.body_data + 13 * b + kBodyOffsets[k] : nullptr);
  }
  for (size_t i = 0; i < m.measure_rows.size(); ++i)
    m.Append(m.measures[i], row.measures ? row.measures + m.measure_rows[i] : nullptr);
  for (size_t i = 0; i < m.joint_rows.size(); ++i) {
    const int j = m.joint_rows[i];
    for (int k = 0; k < 2; ++k)
      m.Append(m.joints[2 * i + k], row.joint_data ? row.joint_data + 6 * j + 3 * k : nullptr);
  }
  for (size_t i = 0; i < m.effort_rows.size(); ++i)
    m.Append(m.efforts[i], row.effort_data ? row.effort_data + m.effort_rows[i] : nullptr);
  // Four datasets per joint coordinate (position, rate, acceleration, generalized force).
  for (size_t i = 0; i < m.joint_coordinate_rows.size(); ++i)
    for (int k = 0; k < 4; ++k)
      m.Append(m.joint_coordinates[4 * i + k],
               row.joint_coordinate_data ? row.joint_coordinate_data + 4 * m.joint_coordinate_rows[i] + k : nullptr);
  for (size_t i = 0; i < m.force_rows.size(); ++i) {
    const int f = m.force_rows[i];
    for (int k = 0; k < 2; ++k)
      m.Append(m.forces[2 * i + k], row.force_data ? row.force_data + 6 * f + 3 * k : nullptr);
  }
  m.Append(m.kinetic, &row.kinetic_energy);
  m.Append(m.potential, &row.potential_energy);
  m.Append(m.position_violation, &row.position_violation);
  m.Append(m.velocity_violation, &row.velocity_violation);
  ++m.rows;
  const auto now = std::chrono::steady_clock::now();
  // With a positive interval, also at least 10 times as long as the last flush took, so
  // that flushing stays within about a tenth of the run's wall time: a flush writes
  // every dataset (four per body, two per joint) and the file's metadata; on the
  // 1000-rod chain one took about 60 ms, and at five a second the file cost more than
  // the integration (bench/README.md, "Flushing the results file").
  if (m.flush_interval <= 0 ||
      std::chrono::duration<double>(now - m.last_flush).count() >=
          std::max(m.flush_interval, 10 * m.last_flush_seconds))
    Flush();
}

void ResultsFile::set_flush_interval(double seconds) { impl_->flush_interval = seconds; }

void ResultsFile::SetAttribute(const std::string& name, double value) {
  QuietErrors quiet;
  impl_->DeleteAttributeIfPresent(name);
  Handle space = Check(H5Screate(H5S_SCALAR), H5Sclose, "create a dataspace");
  Handle attr = Check(H5Acreate2(impl_->file.get(), name.c_str(), H5T_NATIVE_DOUBLE, space.get(),
                                 H5P_DEFAULT, H5P_DEFAULT),
                      H5Aclose, "create attribute " + name);
  Check(H5Awrite(attr.get(), H5T_NATIVE_DOUBLE, &value), "write attribute " + name);
}

namespace {

// The group at `path`, created with its parents if absent.
Handle OpenOrCreateGroup(hid_t f, const std::string& path) {
  const htri_t exists = H5Lexists(f, path.c_str(), H5P_DEFAULT);
  if (exists > 0) return Check(H5Gopen2(f, path.c_str(), H5P_DEFAULT), H5Gclose, "open group " + path);
  Handle lcpl = Check(H5Pcreate(H5P_LINK_CREATE), H5Pclose, "create a property list");
  Check(H5Pset_create_intermediate_group(lcpl.get(), 1), "set a property list");
  return Check(H5Gcreate2(f, path.c_str(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT), H5Gclose,
               "create group " + path);
}

void DeleteAttribute(hid_t object, const std::string& name, const std::string& where) {
  const htri_t has = H5Aexists(object, name.c_str());
  Check(has < 0 ? -1 : 0, "query attribute " + where);
  if (has > 0) Check(H5Adelete(object, name.c_str()), "delete attribute " + where);
}

void WriteNumberAttribute(hid_t object, const std::string& name, double value, const std::string& where) {
  DeleteAttribute(object, name, where);
  Handle space = Check(H5Screate(H5S_SCALAR), H5Sclose, "create a dataspace");
  Handle attr = Check(H5Acreate2(object, name.c_str(), H5T_NATIVE_DOUBLE, space.get(), H5P_DEFAULT,
                                 H5P_DEFAULT),
                      H5Aclose, "create attribute " + where);
  Check(H5Awrite(attr.get(), H5T_NATIVE_DOUBLE, &value), "write attribute " + where);
}

void WriteStringAttribute(hid_t object, const std::string& name, const std::string& value,
                          const std::string& where) {
  DeleteAttribute(object, name, where);
  Handle type = VariableStringType();
  Handle space = Check(H5Screate(H5S_SCALAR), H5Sclose, "create a dataspace");
  Handle attr = Check(H5Acreate2(object, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT),
                      H5Aclose, "create attribute " + where);
  const char* p = value.c_str();
  Check(H5Awrite(attr.get(), type.get(), &p), "write attribute " + where);
}

void WriteStringsAttribute(hid_t object, const std::string& name, const std::vector<std::string>& values,
                           const std::string& where) {
  DeleteAttribute(object, name, where);
  Handle type = VariableStringType();
  hsize_t n = values.size();
  Handle space = Check(H5Screate_simple(1, &n, nullptr), H5Sclose, "create a dataspace");
  Handle attr = Check(H5Acreate2(object, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT),
                      H5Aclose, "create attribute " + where);
  if (values.empty()) return;
  std::vector<const char*> ptrs;
  for (const auto& s : values) ptrs.push_back(s.c_str());
  Check(H5Awrite(attr.get(), type.get(), ptrs.data()), "write attribute " + where);
}

void WriteDoubles(hid_t group, const std::string& name, const std::vector<double>& values,
                  const std::string& where) {
  if (H5Lexists(group, name.c_str(), H5P_DEFAULT) > 0)
    Check(H5Ldelete(group, name.c_str(), H5P_DEFAULT), "delete dataset " + where);
  hsize_t n = values.size();
  Handle space = Check(H5Screate_simple(1, &n, nullptr), H5Sclose, "create a dataspace");
  Handle ds = Check(H5Dcreate2(group, name.c_str(), H5T_IEEE_F64LE, space.get(), H5P_DEFAULT,
                               H5P_DEFAULT, H5P_DEFAULT),
                    H5Dclose, "create dataset " + where);
  if (values.empty()) return;
  Check(H5Dwrite(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()),
        "write dataset " + where);
}

void WriteGroup(hid_t f, const ResultsGroup& g) {
  Handle group = OpenOrCreateGroup(f, g.path);
  for (const auto& [name, value] : g.numbers) WriteNumberAttribute(group.get(), name, value, g.path + "/" + name);
  for (const auto& [name, values] : g.strings)
    WriteStringsAttribute(group.get(), name, values, g.path + "/" + name);
  for (const auto& [name, values] : g.datasets) WriteDoubles(group.get(), name, values, g.path + "/" + name);
}

}  // namespace

void ResultsFile::SetGroupAttributes(const std::string& path,
                                     const std::vector<std::pair<std::string, double>>& attributes) {
  QuietErrors quiet;
  ResultsGroup g;
  g.path = path;
  g.numbers = attributes;
  WriteGroup(impl_->file.get(), g);
}

void ResultsFile::SetGroupAttribute(const std::string& path, const std::string& name,
                                    const std::vector<std::string>& values) {
  QuietErrors quiet;
  ResultsGroup g;
  g.path = path;
  g.strings.emplace_back(name, values);
  WriteGroup(impl_->file.get(), g);
}

void ResultsFile::WriteGroupDataset(const std::string& path, const std::string& name,
                                    const std::vector<double>& values) {
  QuietErrors quiet;
  ResultsGroup g;
  g.path = path;
  g.datasets.emplace_back(name, values);
  WriteGroup(impl_->file.get(), g);
}

void AddToResultsFile(const std::string& path, const std::vector<ResultsGroup>& groups,
                      const std::vector<std::pair<std::string, std::string>>& root_strings) {
  QuietErrors quiet;
  Handle file = Check(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose, "open " + path);
  for (const ResultsGroup& g : groups) WriteGroup(file.get(), g);
  for (const auto& [name, value] : root_strings) WriteStringAttribute(file.get(), name, value, name);
  Check(H5Fflush(file.get(), H5F_SCOPE_LOCAL), "flush " + path);
}

namespace {

// The parent group of dataset_path (created) and the dataset's name in it; a dataset
// already there is deleted.
std::pair<Handle, std::string> PrepareDataset(hid_t file, const std::string& dataset_path) {
  const auto slash = dataset_path.find_last_of('/');
  const std::string name = slash == std::string::npos ? dataset_path : dataset_path.substr(slash + 1);
  CheckName(name, "dataset");
  Handle parent = slash == std::string::npos || slash == 0
                      ? Check(H5Gopen2(file, "/", H5P_DEFAULT), H5Gclose, "open group /")
                      : OpenOrCreateGroup(file, dataset_path.substr(0, slash));
  if (H5Lexists(parent.get(), name.c_str(), H5P_DEFAULT) > 0)
    Check(H5Ldelete(parent.get(), name.c_str(), H5P_DEFAULT), "delete dataset " + dataset_path);
  return {std::move(parent), name};
}

}  // namespace

void AddTableToResultsFile(const std::string& path, const std::string& dataset_path, int cols,
                           const std::vector<double>& values, const std::vector<std::string>& columns) {
  if (cols < 1 || values.size() % static_cast<size_t>(cols) != 0 || columns.size() != static_cast<size_t>(cols))
    throw std::runtime_error("results file: table " + dataset_path + " has " + std::to_string(values.size()) +
                             " values for " + std::to_string(cols) + " columns and " +
                             std::to_string(columns.size()) + " column names");
  QuietErrors quiet;
  Handle file = Check(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose, "open " + path);
  {
    auto [parent, name] = PrepareDataset(file.get(), dataset_path);
    hsize_t dims[2] = {values.size() / static_cast<size_t>(cols), static_cast<hsize_t>(cols)};
    Handle space = Check(H5Screate_simple(2, dims, nullptr), H5Sclose, "create a dataspace");
    Handle ds = Check(H5Dcreate2(parent.get(), name.c_str(), H5T_IEEE_F64LE, space.get(), H5P_DEFAULT,
                                 H5P_DEFAULT, H5P_DEFAULT),
                      H5Dclose, "create dataset " + dataset_path);
    if (!values.empty())
      Check(H5Dwrite(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()),
            "write dataset " + dataset_path);
    WriteStringsAttribute(ds.get(), "columns", columns, dataset_path + "/columns");
  }
  Check(H5Fflush(file.get(), H5F_SCOPE_LOCAL), "flush " + path);
}

void AddStringsToResultsFile(const std::string& path, const std::string& dataset_path,
                             const std::vector<std::string>& values) {
  QuietErrors quiet;
  Handle file = Check(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose, "open " + path);
  {
    auto [parent, name] = PrepareDataset(file.get(), dataset_path);
    Handle type = VariableStringType();
    hsize_t n = values.size();
    Handle space = Check(H5Screate_simple(1, &n, nullptr), H5Sclose, "create a dataspace");
    Handle ds = Check(H5Dcreate2(parent.get(), name.c_str(), type.get(), space.get(), H5P_DEFAULT,
                                 H5P_DEFAULT, H5P_DEFAULT),
                      H5Dclose, "create dataset " + dataset_path);
    std::vector<const char*> ptrs;
    for (const auto& s : values) ptrs.push_back(s.c_str());
    if (!values.empty())
      Check(H5Dwrite(ds.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()),
            "write dataset " + dataset_path);
  }
  Check(H5Fflush(file.get(), H5F_SCOPE_LOCAL), "flush " + path);
}

void ResultsFile::SetAttribute(const std::string& name, long value) {
  QuietErrors quiet;
  impl_->DeleteAttributeIfPresent(name);
  const long long v = value;
  Handle space = Check(H5Screate(H5S_SCALAR), H5Sclose, "create a dataspace");
  Handle attr = Check(H5Acreate2(impl_->file.get(), name.c_str(), H5T_STD_I64LE, space.get(),
                                 H5P_DEFAULT, H5P_DEFAULT),
                      H5Aclose, "create attribute " + name);
  Check(H5Awrite(attr.get(), H5T_NATIVE_LLONG, &v), "write attribute " + name);
}

void ResultsFile::SetAttribute(const std::string& name, const std::string& value) {
  QuietErrors quiet;
  impl_->DeleteAttributeIfPresent(name);
  Handle type = VariableStringType();
  Handle space = Check(H5Screate(H5S_SCALAR), H5Sclose, "create a dataspace");
  Handle attr = Check(H5Acreate2(impl_->file.get(), name.c_str(), type.get(), space.get(),
                                 H5P_DEFAULT, H5P_DEFAULT),
                      H5Aclose, "create attribute " + name);
  const char* p = value.c_str();
  Check(H5Awrite(attr.get(), type.get(), &p), "write attribute " + name);
}

void ResultsFile::SetAttribute(const std::string& name, const std::vector<std::string>& values) {
  QuietErrors quiet;
  impl_->DeleteAttributeIfPresent(name);
  Handle type = VariableStringType();
  hsize_t n = values.size();
  Handle space = Check(H5Screate_simple(1, &n, nullptr), H5Sclose, "create a dataspace");
  Handle attr = Check(H5Acreate2(impl_->file.get(), name.c_str(), type.get(), space.get(),
                                 H5P_DEFAULT, H5P_DEFAULT),
                      H5Aclose, "create attribute " + name);
  if (values.empty()) return;
  std::vector<const char*> ptrs;
  for (const auto& s : values) ptrs.push_back(s.c_str());
  Check(H5Awrite(attr.get(), type.get(), ptrs.data()), "write attribute " + name);
}

namespace {

void WriteFixedTable(hid_t file, const std::string& dataset_path, int cols, size_t count, hid_t file_type,
                     hid_t memory_type, const void* data) {
  if (cols < 0 || (cols > 0 && count % static_cast<size_t>(cols) != 0))
    throw std::runtime_error("results file: table " + dataset_path + " has " + std::to_string(count) +
                             " values for " + std::to_string(cols) + " columns");
  auto [parent, name] = PrepareDataset(file, dataset_path);
  hsize_t dims[2] = {cols == 0 ? count : count / static_cast<size_t>(cols), static_cast<hsize_t>(cols)};
  Handle space = Check(H5Screate_simple(cols == 0 ? 1 : 2, dims, nullptr), H5Sclose, "create a dataspace");
  Handle ds = Check(H5Dcreate2(parent.get(), name.c_str(), file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT,
                               H5P_DEFAULT),
                    H5Dclose, "create dataset " + dataset_path);
  if (count > 0)
    Check(H5Dwrite(ds.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), "write dataset " + dataset_path);
}

}  // namespace

void ResultsFile::WriteTable(const std::string& dataset_path, int cols, const std::vector<double>& values) {
  QuietErrors quiet;
  WriteFixedTable(impl_->file.get(), dataset_path, cols, values.size(), H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE,
                  values.data());
}

void ResultsFile::WriteIntegerTable(const std::string& dataset_path, int cols, const std::vector<long>& values) {
  QuietErrors quiet;
  std::vector<long long> v(values.begin(), values.end());
  WriteFixedTable(impl_->file.get(), dataset_path, cols, v.size(), H5T_STD_I64LE, H5T_NATIVE_LLONG, v.data());
}

void ResultsFile::WriteStringDataset(const std::string& dataset_path, const std::vector<std::string>& values) {
  QuietErrors quiet;
  auto [parent, name] = PrepareDataset(impl_->file.get(), dataset_path);
  ::mbdae::io::WriteStrings(parent.get(), name, values);
}

void ResultsFile::Flush() {
  QuietErrors quiet;
  const auto start = std::chrono::steady_clock::now();
  impl_->WriteAllPending();
  Check(H5Fflush(impl_->file.get(), H5F_SCOPE_GLOBAL), "flush " + impl_->path);
  impl_->last_flush = std::chrono::steady_clock::now();
  impl_->last_flush_seconds = std::chrono::duration<double>(impl_->last_flush - start).count();
}

long ResultsFile::rows() const { return impl_->rows; }
const std::string& ResultsFile::path() const { return impl_->path; }

}  // namespace mbdae::io
