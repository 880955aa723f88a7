// Round trip of the results file: written with ResultsFile, read back with the HDF5 C API.
#include "io/results_file.h"

#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

namespace mbdae::io {
namespace {

std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "/mbdae_io_" + name + "_" + std::to_string(getpid()) + ".h5";
}

// Reads a double dataset; dims returned in `dims`.
std::vector<double> ReadDoubles(hid_t file, const std::string& name, std::vector<hsize_t>* dims) {
  hid_t ds = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  EXPECT_GE(ds, 0) << name;
  if (ds < 0) return {};
  hid_t space = H5Dget_space(ds);
  const int rank = H5Sget_simple_extent_ndims(space);
  dims->assign(rank, 0);
  H5Sget_simple_extent_dims(space, dims->data(), nullptr);
  hsize_t n = 1;
  for (hsize_t d : *dims) n *= d;
  std::vector<double> out(n);
  if (n > 0) EXPECT_GE(H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()), 0);
  H5Sclose(space);
  H5Dclose(ds);
  return out;
}

std::vector<std::string> ReadStrings(hid_t file, const std::string& name) {
  hid_t ds = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  EXPECT_GE(ds, 0) << name;
  hid_t space = H5Dget_space(ds);
  hsize_t n = 0;
  H5Sget_simple_extent_dims(space, &n, nullptr);
  hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, H5T_VARIABLE);
  H5Tset_cset(type, H5T_CSET_UTF8);
  std::vector<char*> raw(n, nullptr);
  std::vector<std::string> out;
  if (n > 0) {
    EXPECT_GE(H5Dread(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, raw.data()), 0);
    for (char* s : raw) out.emplace_back(s ? s : "");
    H5Dvlen_reclaim(type, space, H5P_DEFAULT, raw.data());
  }
  H5Tclose(type);
  H5Sclose(space);
  H5Dclose(ds);
  return out;
}

double ReadDoubleAttribute(hid_t file, const std::string& name) {
  double v = -12345;
  hid_t a = H5Aopen(file, name.c_str(), H5P_DEFAULT);
  EXPECT_GE(a, 0) << name;
  EXPECT_GE(H5Aread(a, H5T_NATIVE_DOUBLE, &v), 0);
  H5Aclose(a);
  return v;
}

long long ReadIntAttribute(hid_t file, const std::string& name) {
  long long v = -12345;
  hid_t a = H5Aopen(file, name.c_str(), H5P_DEFAULT);
  EXPECT_GE(a, 0) << name;
  hid_t type = H5Aget_type(a);
  EXPECT_EQ(H5Tget_class(type), H5T_INTEGER) << name;
  H5Tclose(type);
  EXPECT_GE(H5Aread(a, H5T_NATIVE_LLONG, &v), 0);
  H5Aclose(a);
  return v;
}

std::string ReadStringAttribute(hid_t file, const std::string& name) {
  hid_t a = H5Aopen(file, name.c_str(), H5P_DEFAULT);
  EXPECT_GE(a, 0) << name;
  hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, H5T_VARIABLE);
  H5Tset_cset(type, H5T_CSET_UTF8);
  char* s = nullptr;
  EXPECT_GE(H5Aread(a, type, &s), 0);
  std::string out = s ? s : "";
  H5free_memory(s);
  H5Tclose(type);
  H5Aclose(a);
  return out;
}

ResultsLayout SmallLayout() {
  ResultsLayout layout;
  layout.q_names = {"b.x", "b.y", "b.z", "b.e0", "b.e1", "b.e2", "b.e3"};
  layout.lambda_names = {"hinge.x", "b.euler_norm"};
  layout.bodies = {"b"};
  layout.measures = {"angle", "height"};
  layout.joints = {"hinge"};
  layout.forces = {"spring"};
  return layout;
}

// Row k: every value is 1000 * k + its index, so the read-back can be checked entry by entry.
struct RowData {
  std::vector<double> q, v, a, lambda, body, measures, joints, forces;
  explicit RowData(int k) {
    auto fill = [k](int n, double base) {
      std::vector<double> x(n);
      for (int i = 0; i < n; ++i) x[i] = 1000.0 * k + base + i;
      return x;
    };
    q = fill(7, 0);
    v = fill(7, 100);
    a = fill(7, 200);
    lambda = fill(2, 300);
    body = fill(13, 400);
    measures = fill(2, 500);
    joints = fill(6, 600);
    forces = fill(6, 700);
  }
  ResultsRow Row(double t) const {
    ResultsRow r;
    r.t = t;
    r.q = q.data();
    r.v = v.data();
    r.a = a.data();
    r.lambda = lambda.data();
    r.body_data = body.data();
    r.measures = measures.data();
    r.joint_data = joints.data();
    r.force_data = forces.data();
    r.kinetic_energy = 10 + t;
    r.potential_energy = -20 - t;
    r.position_violation = 1e-12 * (1 + t);
    r.velocity_violation = 1e-11 * (1 + t);
    return r;
  }
};

TEST(ResultsFile, RoundTripOfEveryDatasetAndAttribute) {
  const std::string path = TempPath("roundtrip");
  const int kRows = 5;
  {
    ResultsFile file(path, SmallLayout());
    for (int k = 0; k < kRows; ++k) {
      RowData d(k);
      file.AppendRow(d.Row(0.1 * k));
    }
    EXPECT_EQ(file.rows(), kRows);
    file.SetAttribute("model", std::string("models/pendulum.yaml"));
    file.SetAttribute("hht_alpha", -0.1);
    file.SetAttribute("steps_accepted", 42L);
    file.SetAttribute("status", "running");
    file.SetAttribute("status", "done");  // replaced
    file.SetAttribute("redundant_constraint_names", std::vector<std::string>{"j.rx", "j.ry"});
  }
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  std::vector<hsize_t> dims;
  auto time = ReadDoubles(f, "/time", &dims);
  ASSERT_EQ(dims, std::vector<hsize_t>({kRows}));
  for (int k = 0; k < kRows; ++k) EXPECT_DOUBLE_EQ(time[k], 0.1 * k);

  struct Expect { const char* name; int cols; double base; int offset; };
  const Expect expects[] = {
      {"/q", 7, 0, 0},           {"/v", 7, 100, 0},
      {"/a", 7, 200, 0},         {"/lambda", 2, 300, 0},
      {"/bodies/b/position", 3, 400, 0},  {"/bodies/b/orientation", 4, 400, 3},
      {"/bodies/b/velocity", 3, 400, 7},  {"/bodies/b/angular_velocity", 3, 400, 10},
      {"/joints/hinge/force", 3, 600, 0}, {"/joints/hinge/torque", 3, 600, 3},
      {"/forces/spring/force", 3, 700, 0}, {"/forces/spring/torque", 3, 700, 3},
  };
  for (const auto& e : expects) {
    auto x = ReadDoubles(f, e.name, &dims);
    ASSERT_EQ(dims, std::vector<hsize_t>({kRows, static_cast<hsize_t>(e.cols)})) << e.name;
    for (int k = 0; k < kRows; ++k)
      for (int c = 0; c < e.cols; ++c)
        EXPECT_EQ(x[k * e.cols + c], 1000.0 * k + e.base + e.offset + c) << e.name;
  }
  for (int m = 0; m < 2; ++m) {
    const std::string name = m == 0 ? "/measures/angle" : "/measures/height";
    auto x = ReadDoubles(f, name, &dims);
    ASSERT_EQ(dims, std::vector<hsize_t>({kRows})) << name;
    for (int k = 0; k < kRows; ++k) EXPECT_EQ(x[k], 1000.0 * k + 500 + m);
  }
  auto ke = ReadDoubles(f, "/energy/kinetic", &dims);
  auto pe = ReadDoubles(f, "/energy/potential", &dims);
  auto pv = ReadDoubles(f, "/violation/position", &dims);
  auto vv = ReadDoubles(f, "/violation/velocity", &dims);
  ASSERT_EQ(dims, std::vector<hsize_t>({kRows}));
  for (int k = 0; k < kRows; ++k) {
    EXPECT_DOUBLE_EQ(ke[k], 10 + 0.1 * k);
    EXPECT_DOUBLE_EQ(pe[k], -20 - 0.1 * k);
    EXPECT_DOUBLE_EQ(pv[k], 1e-12 * (1 + 0.1 * k));
    EXPECT_DOUBLE_EQ(vv[k], 1e-11 * (1 + 0.1 * k));
  }
  EXPECT_EQ(ReadStrings(f, "/q_names"), SmallLayout().q_names);
  EXPECT_EQ(ReadStrings(f, "/lambda_names"), SmallLayout().lambda_names);
  EXPECT_EQ(ReadIntAttribute(f, "format"), 1);
  EXPECT_EQ(ReadIntAttribute(f, "steps_accepted"), 42);
  EXPECT_DOUBLE_EQ(ReadDoubleAttribute(f, "hht_alpha"), -0.1);
  EXPECT_EQ(ReadStringAttribute(f, "model"), "models/pendulum.yaml");
  EXPECT_EQ(ReadStringAttribute(f, "status"), "done");
  H5Fclose(f);
  std::remove(path.c_str());
}

// A writer killed after three rows (no destructor, no close) leaves a readable file
// with those rows: every row is flushed.
TEST(ResultsFile, RowsSurviveAKilledWriter) {
  const std::string path = TempPath("killed");
  pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    try {
      auto* file = new ResultsFile(path, SmallLayout());  // deliberately never deleted
      for (int k = 0; k < 3; ++k) {
        RowData d(k);
        file->AppendRow(d.Row(0.5 * k));
      }
    } catch (...) {
      _exit(1);
    }
    _exit(0);
  }
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0);
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  std::vector<hsize_t> dims;
  auto time = ReadDoubles(f, "/time", &dims);
  ASSERT_EQ(dims, std::vector<hsize_t>({3}));
  EXPECT_DOUBLE_EQ(time[2], 1.0);
  auto q = ReadDoubles(f, "/q", &dims);
  ASSERT_EQ(dims, std::vector<hsize_t>({3, 7}));
  EXPECT_EQ(q[2 * 7 + 6], 2006.0);
  H5Fclose(f);
  std::remove(path.c_str());
}

// With a flush interval, rows wait in memory until the next flush (or the end), and
// then land in order.
// The time and the hinge torque of rows k = 0..6 written from RowData(k) at t = 0.25 k.
void ExpectSevenRows(hid_t f) {
  std::vector<hsize_t> dims;
  auto time = ReadDoubles(f, "/time", &dims);
  ASSERT_EQ(dims, std::vector<hsize_t>({7}));
  auto jt = ReadDoubles(f, "/joints/hinge/torque", &dims);
  ASSERT_EQ(dims, std::vector<hsize_t>({7, 3}));
  for (int k = 0; k < 7; ++k) {
    EXPECT_DOUBLE_EQ(time[k], 0.25 * k);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(jt[3 * k + c], 1000.0 * k + 603 + c);
  }
}

TEST(ResultsFile, BufferedRowsAreWrittenInOrderAtFlush) {
  const std::string path = TempPath("buffered");
  {
    ResultsFile file(path, SmallLayout());
    file.set_flush_interval(1e9);
    for (int k = 0; k < 4; ++k) {
      RowData d(k);
      file.AppendRow(d.Row(0.25 * k));
    }
    file.Flush();
    for (int k = 4; k < 7; ++k) {
      RowData d(k);
      file.AppendRow(d.Row(0.25 * k));
    }
    EXPECT_EQ(file.rows(), 7);
  }  // the destructor writes the last three
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  ExpectSevenRows(f);
  H5Fclose(f);
  std::remove(path.c_str());
}

// The chunks hold at most the expected rows (a short run of a large model does not
// allocate 8 KiB per dataset); more rows than expected are still written and read back.
TEST(ResultsFile, ChunksFollowTheExpectedRows) {
  auto chunk_rows = [](hid_t file, const std::string& name) {
    hid_t ds = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
    hid_t plist = H5Dget_create_plist(ds);
    hsize_t chunk[2] = {0, 0};
    EXPECT_GE(H5Pget_chunk(plist, 2, chunk), 1) << name;
    H5Pclose(plist);
    H5Dclose(ds);
    return chunk[0];
  };
  for (long expected : {0L, 3L}) {
    const std::string path = TempPath("chunks" + std::to_string(expected));
    ResultsLayout layout = SmallLayout();
    layout.expected_rows = expected;
    {
      ResultsFile file(path, layout);
      for (int k = 0; k < 7; ++k) {
        RowData d(k);
        file.AppendRow(d.Row(0.25 * k));
      }
    }
    hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    // Unknown: about 8 KiB, at least 16 rows (1-D: 1024 rows, 3 columns: 341).
    EXPECT_EQ(chunk_rows(f, "/time"), expected == 0 ? 1024u : 3u);
    EXPECT_EQ(chunk_rows(f, "/joints/hinge/torque"), expected == 0 ? 341u : 3u);
    ExpectSevenRows(f);
    H5Fclose(f);
    std::remove(path.c_str());
  }
}

// No constraints, no measures: zero-width datasets are still well formed.
TEST(ResultsFile, EmptyLayoutParts) {
  const std::string path = TempPath("empty");
  ResultsLayout layout;
  layout.q_names = {"b.x"};
  {
    ResultsFile file(path, layout);
    const double q = 3.5;
    ResultsRow row;
    row.t = 0.25;
    row.q = &q;
    file.AppendRow(row);  // v, a null: zeros
    file.AppendRow(row);
  }
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  std::vector<hsize_t> dims;
  ReadDoubles(f, "/lambda", &dims);
  EXPECT_EQ(dims, std::vector<hsize_t>({2, 0}));
  auto q = ReadDoubles(f, "/q", &dims);
  EXPECT_EQ(dims, std::vector<hsize_t>({2, 1}));
  EXPECT_EQ(q[1], 3.5);
  auto v = ReadDoubles(f, "/v", &dims);
  EXPECT_EQ(v[0], 0.0);
  EXPECT_TRUE(ReadStrings(f, "/lambda_names").empty());
  H5Fclose(f);
  std::remove(path.c_str());
}

// write_* flags: only the chosen elements get datasets, each with its own entries of the
// row (which still carries every element); a joint left out loses its effort and
// joint-coordinate datasets too; /q and the rest stay whole.
TEST(ResultsFile, WritesTheChosenElementsOnly) {
  const std::string path = TempPath("selection");
  ResultsLayout layout;
  layout.q_names = {"b0.x", "b1.x", "b2.x"};
  layout.bodies = {"b0", "b1", "b2"};
  layout.measures = {"m0", "m1", "m2"};
  layout.joints = {"j0", "j1", "j2"};
  layout.efforts = {"j0", "j2"};
  layout.joint_coordinates = {"j1", "j2"};
  layout.forces = {"f0", "f1"};
  layout.write_bodies = {false, false, true};
  layout.write_measures = {false, true, false};
  layout.write_joints = {false, false, true};
  layout.write_forces = {false, false};
  const int kRows = 3;
  auto value = [](int k, double base, int i) { return 1000.0 * k + base + i; };
  {
    ResultsFile file(path, layout);
    for (int k = 0; k < kRows; ++k) {
      std::vector<double> q(3), body(39), measures(3), joints(18), efforts(2), coords(8), forces(12);
      for (auto [x, base] : {std::pair{&q, 0.0}, {&body, 100.0}, {&measures, 200.0}, {&joints, 300.0},
                             {&efforts, 400.0}, {&coords, 500.0}, {&forces, 600.0}})
        for (size_t i = 0; i < x->size(); ++i) (*x)[i] = value(k, base, static_cast<int>(i));
      ResultsRow row;
      row.t = k;
      row.q = q.data();
      row.body_data = body.data();
      row.measures = measures.data();
      row.joint_data = joints.data();
      row.effort_data = efforts.data();
      row.joint_coordinate_data = coords.data();
      row.force_data = forces.data();
      file.AppendRow(row);
    }
  }
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  for (const char* absent : {"/bodies/b0", "/bodies/b1", "/measures/m0", "/measures/m2", "/joints/j0",
                             "/joints/j1", "/forces/f0", "/forces/f1"})
    EXPECT_EQ(H5Lexists(f, absent, H5P_DEFAULT), 0) << absent;
  std::vector<hsize_t> dims;
  // (dataset, columns, first entry of the element's values in the row)
  struct Expect { const char* name; int cols; double first; };
  const Expect expects[] = {
      {"/q", 3, 0},
      {"/bodies/b2/position", 3, 100 + 26},     {"/bodies/b2/orientation", 4, 100 + 29},
      {"/bodies/b2/velocity", 3, 100 + 33},     {"/bodies/b2/angular_velocity", 3, 100 + 36},
      {"/measures/m1", 0, 200 + 1},
      {"/joints/j2/force", 3, 300 + 12},        {"/joints/j2/torque", 3, 300 + 15},
      {"/joints/j2/effort", 0, 400 + 1},
      {"/joints/j2/position", 0, 500 + 4},      {"/joints/j2/rate", 0, 500 + 5},
      {"/joints/j2/acceleration", 0, 500 + 6},  {"/joints/j2/generalized_force", 0, 500 + 7},
  };
  for (const auto& e : expects) {
    auto x = ReadDoubles(f, e.name, &dims);
    const int width = std::max(1, e.cols);
    ASSERT_EQ(x.size(), static_cast<size_t>(kRows * width)) << e.name;
    for (int k = 0; k < kRows; ++k)
      for (int c = 0; c < width; ++c) EXPECT_EQ(x[k * width + c], value(k, e.first, c)) << e.name;
  }
  H5Fclose(f);
  std::remove(path.c_str());

  layout.write_bodies = {true};  // not one flag per body
  try {
    ResultsFile file(path, layout);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("1 flags for 3 bodies"), std::string::npos) << e.what();
  }
}

TEST(ResultsFile, ErrorsNameThePath) {
  try {
    ResultsFile file("no_such_directory_xyz/out.h5", SmallLayout());
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_directory_xyz/out.h5"), std::string::npos)
        << e.what();
  }
  ResultsLayout bad = SmallLayout();
  bad.bodies = {"a/b"};
  EXPECT_THROW(ResultsFile(TempPath("bad"), bad), std::runtime_error);
}

}  // namespace
}  // namespace mbdae::io
