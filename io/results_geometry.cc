#include "io/results_geometry.h"

#include <hdf5.h>

#include <cstdio>
#include <stdexcept>

#include "mbs/kinematics.h"
#include "mbs/mesh.h"
#include "mbs/visual.h"

namespace mbdae::io {

namespace {

void AppendVec(std::vector<double>* out, const mbs::Vec3& v) { out->insert(out->end(), {v[0], v[1], v[2]}); }
void AppendQuat(std::vector<double>* out, const mbs::Mat3& R) {
  mbs::Quat q = mbs::QuaternionFromMatrix(R);
  q.normalize();
  if (q[0] < 0) q = -q;
  out->insert(out->end(), {q[0], q[1], q[2], q[3]});
}

}  // namespace

void WriteModelGeometry(ResultsFile& file, const mbs::Model& model) {
  const std::vector<mbs::DrawnShape> shapes = mbs::DrawnShapes(model);
  std::vector<std::string> body_names, kinds, sources;
  for (const mbs::Body& b : model.bodies) body_names.push_back(b.name);
  std::vector<long> shape_body, shape_mesh;
  std::vector<double> size, position, orientation, color;
  int meshes = 0;
  for (const mbs::DrawnShape& s : shapes) {
    kinds.push_back(s.kind);
    sources.push_back(s.source);
    shape_body.push_back(s.body);
    AppendVec(&size, s.size);
    AppendVec(&position, s.position);
    AppendQuat(&orientation, s.orientation);
    color.insert(color.end(), s.color.begin(), s.color.end());
    if (s.kind != "mesh") {
      shape_mesh.push_back(-1);
      continue;
    }
    // Vertices scaled, in the shape's axes; triangles 0-based.
    const mbs::TriangleMesh mesh = mbs::ReadMesh(s.mesh_file);
    std::vector<double> vertices;
    for (const mbs::Vec3& v : mesh.vertices) AppendVec(&vertices, s.size[0] * v);
    std::vector<long> triangles;
    for (const auto& t : mesh.triangles) triangles.insert(triangles.end(), {t[0], t[1], t[2]});
    const std::string group = "geometry/meshes/" + std::to_string(meshes);
    file.WriteTable(group + "/vertices", 3, vertices);
    file.WriteIntegerTable(group + "/triangles", 3, triangles);
    shape_mesh.push_back(meshes++);
  }
  file.WriteStringDataset("geometry/body_names", body_names);
  file.WriteStringDataset("geometry/shape_kind", kinds);
  file.WriteStringDataset("geometry/shape_source", sources);
  file.WriteIntegerTable("geometry/shape_body", 0, shape_body);
  file.WriteIntegerTable("geometry/shape_mesh", 0, shape_mesh);
  file.WriteTable("geometry/shape_size", 3, size);
  file.WriteTable("geometry/shape_position", 3, position);
  file.WriteTable("geometry/shape_orientation", 4, orientation);
  file.WriteTable("geometry/shape_color", 4, color);

  std::vector<std::string> marker_names;
  std::vector<long> marker_body;
  std::vector<double> marker_position, marker_orientation;
  for (const mbs::Marker& m : model.markers) {
    marker_names.push_back(m.name);
    marker_body.push_back(m.body);
    AppendVec(&marker_position, m.position);
    AppendQuat(&marker_orientation, m.orientation);
  }
  file.WriteStringDataset("geometry/marker_names", marker_names);
  file.WriteIntegerTable("geometry/marker_body", 0, marker_body);
  file.WriteTable("geometry/marker_position", 3, marker_position);
  file.WriteTable("geometry/marker_orientation", 4, marker_orientation);

  std::vector<std::string> joint_names;
  std::vector<long> joint_markers;
  for (const mbs::Joint& j : model.joints) {
    joint_names.push_back(j.name);
    joint_markers.insert(joint_markers.end(), {j.i, j.j});
  }
  file.WriteStringDataset("geometry/joint_names", joint_names);
  file.WriteIntegerTable("geometry/joint_markers", 2, joint_markers);
  file.WriteTable("geometry/gravity", 0, {model.gravity[0], model.gravity[1], model.gravity[2]});
  file.SetGroupAttributes("geometry", {{"format", 1.0}, {"length_scale", mbs::ModelLengthScale(model)}});
}

// ---- reading -------------------------------------------------------------------------

namespace {

class Quiet {
 public:
  Quiet() {
    H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~Quiet() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }

 private:
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

struct Id {
  hid_t id;
  herr_t (*close)(hid_t);
  ~Id() {
    if (id >= 0) close(id);
  }
};

}  // namespace

ResultsReader::ResultsReader(const std::string& path) : path_(path) {
  Quiet quiet;
  if (H5Fis_hdf5(path.c_str()) <= 0) {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) throw std::runtime_error(path + ": cannot open the file");
    std::fclose(f);
    throw NotAResultsFile(path + ": not a results file (not an HDF5 file)");
  }
  file_ = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (file_ < 0) throw std::runtime_error(path + ": cannot open the HDF5 file");
  if (!Has("time")) {
    H5Fclose(file_);
    file_ = -1;
    throw NotAResultsFile(path + ": not a results file of mbdae (an HDF5 file without the dataset /time)");
  }
}

ResultsReader::~ResultsReader() {
  if (file_ >= 0) H5Fclose(file_);
}

bool ResultsReader::Has(const std::string& object_path) const {
  Quiet quiet;
  // Each component must exist in turn (H5Lexists fails on a missing parent).
  std::string prefix;
  size_t start = 0;
  while (start <= object_path.size()) {
    const size_t slash = object_path.find('/', start);
    const std::string part = object_path.substr(start, slash == std::string::npos ? std::string::npos : slash - start);
    prefix += (prefix.empty() ? "" : "/") + part;
    if (H5Lexists(file_, prefix.c_str(), H5P_DEFAULT) <= 0) return false;
    if (slash == std::string::npos) break;
    start = slash + 1;
  }
  return true;
}

std::vector<double> ResultsReader::Doubles(const std::string& dataset_path, std::vector<size_t>* dims) const {
  Quiet quiet;
  if (!Has(dataset_path)) throw std::runtime_error(path_ + ": no dataset /" + dataset_path);
  Id ds{H5Dopen2(file_, dataset_path.c_str(), H5P_DEFAULT), H5Dclose};
  if (ds.id < 0) throw std::runtime_error(path_ + ": cannot open /" + dataset_path);
  Id space{H5Dget_space(ds.id), H5Sclose};
  const int rank = H5Sget_simple_extent_ndims(space.id);
  std::vector<hsize_t> d(rank > 0 ? rank : 0);
  if (rank > 0) H5Sget_simple_extent_dims(space.id, d.data(), nullptr);
  size_t n = 1;
  for (hsize_t x : d) n *= x;
  if (dims) dims->assign(d.begin(), d.end());
  std::vector<double> out(n);
  if (n > 0 && H5Dread(ds.id, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
    throw std::runtime_error(path_ + ": cannot read /" + dataset_path + " as numbers");
  return out;
}

std::vector<std::string> ResultsReader::Strings(const std::string& dataset_path) const {
  Quiet quiet;
  if (!Has(dataset_path)) throw std::runtime_error(path_ + ": no dataset /" + dataset_path);
  Id ds{H5Dopen2(file_, dataset_path.c_str(), H5P_DEFAULT), H5Dclose};
  Id space{H5Dget_space(ds.id), H5Sclose};
  const hssize_t n = H5Sget_simple_extent_npoints(space.id);
  Id type{H5Tcopy(H5T_C_S1), H5Tclose};
  H5Tset_size(type.id, H5T_VARIABLE);
  H5Tset_cset(type.id, H5T_CSET_UTF8);
  std::vector<char*> ptrs(n > 0 ? n : 0, nullptr);
  if (n > 0 && H5Dread(ds.id, type.id, H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()) < 0)
    throw std::runtime_error(path_ + ": cannot read /" + dataset_path + " as strings");
  std::vector<std::string> out;
  for (char* p : ptrs) out.emplace_back(p ? p : "");
  if (n > 0) H5Dvlen_reclaim(type.id, space.id, H5P_DEFAULT, ptrs.data());
  return out;
}

namespace {
herr_t CollectName(hid_t, const char* name, const H5L_info_t*, void* data) {
  static_cast<std::vector<std::string>*>(data)->emplace_back(name);
  return 0;
}
}  // namespace

std::vector<std::string> ResultsReader::Children(const std::string& group_path) const {
  Quiet quiet;
  std::vector<std::string> out;
  if (!Has(group_path)) return out;
  Id g{H5Gopen2(file_, group_path.c_str(), H5P_DEFAULT), H5Gclose};
  if (g.id < 0) return out;
  hsize_t idx = 0;
  H5Literate(g.id, H5_INDEX_NAME, H5_ITER_INC, &idx, CollectName, &out);
  return out;
}

std::string ResultsReader::StringAttribute(const std::string& name, const std::string& fallback) const {
  Quiet quiet;
  if (H5Aexists(file_, name.c_str()) <= 0) return fallback;
  Id attr{H5Aopen(file_, name.c_str(), H5P_DEFAULT), H5Aclose};
  Id ftype{H5Aget_type(attr.id), H5Tclose};
  if (H5Tget_class(ftype.id) != H5T_STRING) return fallback;
  if (H5Tis_variable_str(ftype.id) > 0) {
    Id type{H5Tcopy(H5T_C_S1), H5Tclose};
    H5Tset_size(type.id, H5T_VARIABLE);
    H5Tset_cset(type.id, H5Tget_cset(ftype.id));
    char* p = nullptr;
    if (H5Aread(attr.id, type.id, &p) < 0) return fallback;
    std::string out = p ? p : "";
    H5free_memory(p);
    return out;
  }
  const size_t size = H5Tget_size(ftype.id);
  std::string out(size, '\0');
  if (H5Aread(attr.id, ftype.id, out.data()) < 0) return fallback;
  return out.substr(0, out.find('\0'));
}

double ResultsReader::NumberAttribute(const std::string& name, double fallback) const {
  Quiet quiet;
  if (H5Aexists(file_, name.c_str()) <= 0) return fallback;
  Id attr{H5Aopen(file_, name.c_str(), H5P_DEFAULT), H5Aclose};
  Id ftype{H5Aget_type(attr.id), H5Tclose};
  const H5T_class_t c = H5Tget_class(ftype.id);
  if (c != H5T_FLOAT && c != H5T_INTEGER) return fallback;
  double v = fallback;
  if (H5Aread(attr.id, H5T_NATIVE_DOUBLE, &v) < 0) return fallback;
  return v;
}

}  // namespace mbdae::io
