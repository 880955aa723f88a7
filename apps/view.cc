#include "apps/view.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <strings.h>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <vector>

#include "io/results_geometry.h"
#include "mbs/model_writer.h"

namespace mbdae::app {

// The template and the player (viewer/viewer.html, viewer/viewer.js), embedded at build
// time (apps/CMakeLists.txt).
extern const char* const kViewerHtml;
extern const char* const kViewerJs;

namespace {

#ifndef MBDAE_THREE_JS
#define MBDAE_THREE_JS "/usr/share/javascript/three/build/three.min.js"
#endif

const char* kViewUsage = "usage: mbdae view RESULTS.h5 [-o FILE.html]\n";

// ---- JSON ------------------------------------------------------------------------------

// A JSON string: mbs::DoubleQuoted's escapes are JSON's; "</" is written "<\\/" so that
// no "</script>" in a name ends the page's script early.
std::string JsonText(const std::string& s) {
  std::string out = mbs::DoubleQuoted(s);
  for (size_t k = out.find("</"); k != std::string::npos; k = out.find("</", k + 3)) out.replace(k, 2, "<\\/");
  return out;
}

void Number(std::string* out, double x) {
  if (!std::isfinite(x)) {
    *out += "null";
    return;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", x);
  *out += buf;
}

std::string Numbers(const std::vector<double>& v) {
  std::string out = "[";
  for (size_t k = 0; k < v.size(); ++k) {
    if (k) out += ',';
    Number(&out, v[k]);
  }
  return out + "]";
}

std::string Ints(const std::vector<double>& v) {
  std::string out = "[";
  for (size_t k = 0; k < v.size(); ++k) {
    if (k) out += ',';
    out += std::to_string(static_cast<long long>(std::llround(v[k])));
  }
  return out + "]";
}

// Rows `rows` of a rows x cols table (row-major).
std::vector<double> Take(const std::vector<double>& table, int cols, const std::vector<size_t>& rows) {
  std::vector<double> out;
  out.reserve(rows.size() * cols);
  for (size_t r : rows)
    for (int c = 0; c < cols; ++c) out.push_back(table[r * cols + c]);
  return out;
}

std::vector<double> Slice(const std::vector<double>& v, size_t from, size_t count) {
  return std::vector<double>(v.begin() + from, v.begin() + from + count);
}

std::string ReadFileText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::string();
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

struct Series {
  std::string name, unit;
  std::vector<double> values;  // the drawn rows
};

// The page's data: the drawn rows, bodies, shapes, markers, joints and series.
std::string DataJson(const io::ResultsReader& r, const ViewOptions& options) {
  std::vector<size_t> dims;
  const std::vector<double> time = r.Doubles("time", &dims);
  const size_t n = time.size();
  // Thinning: every stride-th row, and the last.
  const size_t max_frames = static_cast<size_t>(std::max(2, options.max_frames));
  const size_t stride = n <= max_frames ? 1 : (n + max_frames - 2) / (max_frames - 1);
  std::vector<size_t> rows;
  for (size_t k = 0; k < n; k += stride) rows.push_back(k);
  if (n > 0 && rows.back() != n - 1) rows.push_back(n - 1);

  const bool has_geometry = r.Has("geometry/body_names");
  const std::vector<std::string> bodies = has_geometry ? r.Strings("geometry/body_names") : r.Children("bodies");
  std::vector<std::vector<double>> positions, orientations;
  // A body the run left out of /bodies (simulation: {output: {bodies}}) is drawn from
  // its columns of /q (NAME.x, NAME.y, NAME.z, NAME.e0 .. NAME.e3), read once.
  std::vector<double> q_table;
  std::map<std::string, size_t> q_column;
  for (const std::string& b : bodies) {
    std::vector<double> p, q;
    if (r.Has("bodies/" + b + "/position")) {
      p = r.Doubles("bodies/" + b + "/position");
      q = r.Doubles("bodies/" + b + "/orientation");
    } else {
      if (q_column.empty()) {
        const std::vector<std::string> names = r.Strings("q_names");
        for (size_t c = 0; c < names.size(); ++c) q_column.emplace(names[c], c);
        q_table = r.Doubles("q");
      }
      const size_t nq = q_column.size();
      static const char* kCoord[7] = {"x", "y", "z", "e0", "e1", "e2", "e3"};
      size_t col[7];
      for (int k = 0; k < 7; ++k) {
        const auto it = q_column.find(b + "." + kCoord[k]);
        if (it == q_column.end())
          throw ViewInputError(r.path() + ": body " + b + " has neither /bodies/" + b + " nor a column " + b +
                               "." + kCoord[k] + " in /q_names");
        col[k] = it->second;
      }
      if (q_table.size() < nq * n) throw ViewInputError(r.path() + ": /q has fewer rows than /time");
      for (size_t row = 0; row < n; ++row) {
        for (int k = 0; k < 3; ++k) p.push_back(q_table[row * nq + col[k]]);
        for (int k = 3; k < 7; ++k) q.push_back(q_table[row * nq + col[k]]);
      }
    }
    if (p.size() < 3 * n || q.size() < 4 * n)
      throw ViewInputError(r.path() + ": /bodies/" + b + " has fewer rows than /time");
    positions.push_back(Take(p, 3, rows));
    orientations.push_back(Take(q, 4, rows));
  }

  std::string json = "{";
  const std::string model = r.StringAttribute("model_name", r.StringAttribute("model"));
  json += "\"title\":" + JsonText(model.empty() ? r.path() : model);
  json += ",\"file\":" + JsonText(r.path());
  json += ",\"status\":" + JsonText(r.StringAttribute("status", "unknown"));
  json += ",\"t_reached\":";
  Number(&json, r.NumberAttribute("t_reached", n ? time.back() : 0));
  json += ",\"failure\":" + JsonText(r.StringAttribute("failure_reason"));
  json += ",\"rows_total\":" + std::to_string(n);
  json += ",\"stride\":" + std::to_string(stride);
  json += ",\"max_frames\":" + std::to_string(max_frames);
  json += ",\"time\":" + Numbers(Take(time, 1, rows));

  json += ",\"bodies\":[";
  for (size_t b = 0; b < bodies.size(); ++b) {
    json += std::string(b ? "," : "") + "{\"name\":" + JsonText(bodies[b]) + ",\"p\":" + Numbers(positions[b]) +
            ",\"q\":" + Numbers(orientations[b]) + "}";
  }
  json += "]";

  double length_scale = 1;
  if (has_geometry) {
    const std::vector<double> kind_body = r.Doubles("geometry/shape_body");
    const std::vector<std::string> kinds = r.Strings("geometry/shape_kind");
    const std::vector<double> size = r.Doubles("geometry/shape_size"), pos = r.Doubles("geometry/shape_position"),
                              quat = r.Doubles("geometry/shape_orientation"), color = r.Doubles("geometry/shape_color"),
                              mesh = r.Doubles("geometry/shape_mesh");
    json += ",\"shapes\":[";
    for (size_t s = 0; s < kinds.size(); ++s) {
      json += std::string(s ? "," : "") + "{\"kind\":" + JsonText(kinds[s]) +
              ",\"body\":" + std::to_string(std::llround(kind_body[s])) + ",\"size\":" + Numbers(Slice(size, 3 * s, 3)) +
              ",\"pos\":" + Numbers(Slice(pos, 3 * s, 3)) + ",\"quat\":" + Numbers(Slice(quat, 4 * s, 4)) +
              ",\"color\":" + Numbers(Slice(color, 4 * s, 4)) + ",\"mesh\":" + std::to_string(std::llround(mesh[s])) + "}";
    }
    json += "],\"meshes\":[";
    for (int k = 0;; ++k) {
      const std::string g = "geometry/meshes/" + std::to_string(k);
      if (!r.Has(g + "/vertices")) break;
      json += std::string(k ? "," : "") + "{\"v\":" + Numbers(r.Doubles(g + "/vertices")) +
              ",\"f\":" + Ints(r.Doubles(g + "/triangles")) + "}";
    }
    const std::vector<std::string> marker_names = r.Strings("geometry/marker_names");
    const std::vector<double> marker_body = r.Doubles("geometry/marker_body"),
                              marker_pos = r.Doubles("geometry/marker_position"),
                              marker_quat = r.Doubles("geometry/marker_orientation");
    json += "],\"markers\":[";
    for (size_t m = 0; m < marker_names.size(); ++m) {
      json += std::string(m ? "," : "") + "{\"name\":" + JsonText(marker_names[m]) +
              ",\"body\":" + std::to_string(std::llround(marker_body[m])) + ",\"pos\":" + Numbers(Slice(marker_pos, 3 * m, 3)) +
              ",\"quat\":" + Numbers(Slice(marker_quat, 4 * m, 4)) + "}";
    }
    const std::vector<std::string> joint_names = r.Strings("geometry/joint_names");
    const std::vector<double> joint_markers = r.Doubles("geometry/joint_markers");
    json += "],\"joints\":[";
    for (size_t j = 0; j < joint_names.size(); ++j) {
      json += std::string(j ? "," : "") + "{\"name\":" + JsonText(joint_names[j]) +
              ",\"i\":" + std::to_string(std::llround(joint_markers[2 * j])) +
              ",\"j\":" + std::to_string(std::llround(joint_markers[2 * j + 1])) + "}";
    }
    json += "],\"gravity\":" + Numbers(r.Has("geometry/gravity") ? r.Doubles("geometry/gravity") : std::vector<double>{0, 0, 0});
    // The scene's size: the box around the drawn centres of mass and ground's markers.
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (const auto& p : positions)
      for (size_t k = 0; k + 2 < p.size(); k += 3)
        for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], p[k + c]), hi[c] = std::max(hi[c], p[k + c]);
    for (size_t m = 0; m < marker_names.size(); ++m)
      if (marker_body[m] < 0)
        for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], marker_pos[3 * m + c]), hi[c] = std::max(hi[c], marker_pos[3 * m + c]);
    double d = 0;
    for (int c = 0; c < 3; ++c) d += hi[c] > lo[c] ? (hi[c] - lo[c]) * (hi[c] - lo[c]) : 0;
    length_scale = d > 0 ? std::sqrt(d) : 1;
  } else {
    // A results file without /geometry (written before it existed): each body a sphere.
    json += ",\"shapes\":[";
    for (size_t b = 0; b < bodies.size(); ++b)
      json += std::string(b ? "," : "") + "{\"kind\":\"sphere\",\"body\":" + std::to_string(b) +
              ",\"size\":[0.05,0,0],\"pos\":[0,0,0],\"quat\":[1,0,0,0],\"color\":[0.85,0.33,0.1,1],\"mesh\":-1}";
    json += "],\"meshes\":[],\"markers\":[],\"joints\":[],\"gravity\":[0,0,0]";
  }
  json += ",\"length_scale\":";
  Number(&json, length_scale);

  // Series to plot: measures, joints' reactions and efforts, force elements, energy,
  // violations, centres of mass.
  std::vector<Series> series;
  auto add = [&](const std::string& name, const std::string& unit, const std::vector<double>& all, int cols, int col) {
    if (all.size() < n * static_cast<size_t>(cols)) return;
    Series s{name, unit, {}};
    for (size_t k : rows) s.values.push_back(all[k * cols + col]);
    series.push_back(std::move(s));
  };
  auto add_vector = [&](const std::string& name, const std::string& unit, const std::vector<double>& all) {
    if (all.size() < 3 * n) return;
    const char* axis[] = {"x", "y", "z"};
    for (int c = 0; c < 3; ++c) add(name + " " + axis[c], unit, all, 3, c);
    Series s{"|" + name + "|", unit, {}};
    for (size_t k : rows) s.values.push_back(std::sqrt(all[3 * k] * all[3 * k] + all[3 * k + 1] * all[3 * k + 1] +
                                                       all[3 * k + 2] * all[3 * k + 2]));
    series.push_back(std::move(s));
  };
  for (const std::string& m : r.Children("measures")) add("measure " + m, "", r.Doubles("measures/" + m), 1, 0);
  if (r.Has("energy/kinetic") && r.Has("energy/potential")) {
    const std::vector<double> kin = r.Doubles("energy/kinetic"), pot = r.Doubles("energy/potential");
    std::vector<double> total(kin.size());
    for (size_t k = 0; k < kin.size() && k < pot.size(); ++k) total[k] = kin[k] + pot[k];
    add("energy total", "J", total, 1, 0);
    add("energy kinetic", "J", kin, 1, 0);
    add("energy potential", "J", pot, 1, 0);
  }
  for (const std::string& j : r.Children("joints")) {
    add_vector("joint " + j + " force", "N", r.Doubles("joints/" + j + "/force"));
    add_vector("joint " + j + " torque", "N m", r.Doubles("joints/" + j + "/torque"));
    if (r.Has("joints/" + j + "/effort")) add("joint " + j + " effort", "", r.Doubles("joints/" + j + "/effort"), 1, 0);
  }
  for (const std::string& f : r.Children("forces")) {
    add_vector("force " + f + " force", "N", r.Doubles("forces/" + f + "/force"));
    add_vector("force " + f + " torque", "N m", r.Doubles("forces/" + f + "/torque"));
  }
  for (size_t b = 0; b < bodies.size(); ++b) {
    const char* axis[] = {"x", "y", "z"};
    for (int c = 0; c < 3; ++c) {
      Series s{"body " + bodies[b] + " " + axis[c], "m", {}};
      for (size_t k = 0; k < rows.size(); ++k) s.values.push_back(positions[b][3 * k + c]);
      series.push_back(std::move(s));
    }
  }
  for (const char* v : {"position", "velocity"})
    if (r.Has(std::string("violation/") + v))
      add(std::string("violation ") + v, "", r.Doubles(std::string("violation/") + v), 1, 0);
  json += ",\"series\":[";
  for (size_t s = 0; s < series.size(); ++s) {
    json += std::string(s ? "," : "") + "{\"name\":" + JsonText(series[s].name) + ",\"unit\":" + JsonText(series[s].unit) +
            ",\"v\":" + Numbers(series[s].values) + "}";
  }
  json += "]}";
  return json;
}

// `text` with no "</script" (so that it stays inside its <script> element).
std::string ScriptSafe(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (size_t k = 0; k < text.size(); ++k) {
    if (text[k] == '<' && k + 1 < text.size() && text[k + 1] == '/' &&
        strncasecmp(text.c_str() + k + 2, "script", 6) == 0) {
      out += "<\\/";
      ++k;
      continue;
    }
    out += text[k];
  }
  return out;
}

std::string HtmlText(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else if (c == '&') out += "&amp;";
    else out += c;
  }
  return out;
}

}  // namespace

std::string ViewerHtml(const ViewOptions& options) {
  std::unique_ptr<io::ResultsReader> reader;
  try {
    reader = std::make_unique<io::ResultsReader>(options.results);
  } catch (const io::NotAResultsFile& e) {
    throw ViewInputError(e.what());
  } catch (const std::runtime_error& e) {
    throw ViewInputError(e.what());
  }
  std::string data;
  try {
    data = DataJson(*reader, options);
  } catch (const ViewInputError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw ViewInputError(std::string(e.what()) + " (a results file of mbdae has /time and /bodies; docs/results-file.md)");
  }

  std::string three_path = options.three_js;
  if (three_path.empty()) {
    const char* env = std::getenv("MBDAE_THREE_JS");
    three_path = env && *env ? env : MBDAE_THREE_JS;
  }
  const std::string three = ReadFileText(three_path);
  if (three.empty())
    throw std::runtime_error("three.js not found at " + three_path +
                             " (install Debian's libjs-three, or name three.min.js in MBDAE_THREE_JS)");

  const std::string model = reader->StringAttribute("model_name", reader->StringAttribute("model"));
  const std::string page = kViewerHtml;
  const std::vector<std::pair<std::string, std::string>> parts = {
      {"@TITLE@", HtmlText(model.empty() ? options.results : model)},
      {"@THREE@", ScriptSafe(three)},
      {"@DATA@", data},
      {"@VIEWER@", ScriptSafe(kViewerJs)}};
  std::string out;
  size_t at = 0;
  for (const auto& [marker, text] : parts) {
    const size_t k = page.find(marker, at);
    if (k == std::string::npos) throw std::logic_error("viewer template without " + marker);
    out += page.substr(at, k - at) + text;
    at = k + marker.size();
  }
  out += page.substr(at);
  return out;
}

int RunView(int argc, char** argv) {
  ViewOptions options;
  for (int k = 2; k < argc; ++k) {
    const std::string a = argv[k];
    if (a == "-h" || a == "--help") {
      std::cout << kViewUsage
                << "Writes one self-contained HTML file (default: RESULTS with .html) that plays the run\n"
                   "in a browser: play/pause, time slider, speed, orbit camera (drag; right-drag or\n"
                   "shift-drag pans; wheel zooms), body names on hover, joint frames, and a plot of\n"
                   "any measure, joint reaction, force or energy against time. At most 2000 rows are\n"
                   "drawn (every k-th row and the last). docs/viewer.md\n";
      return 0;
    }
    if (a == "-o" || a == "--output") {
      if (k + 1 >= argc) {
        std::fprintf(stderr, "mbdae: error: %s needs a file name\n%s", a.c_str(), kViewUsage);
        return 2;
      }
      options.output = argv[++k];
    } else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "mbdae: error: view: unknown option '%s'\n%s", a.c_str(), kViewUsage);
      return 2;
    } else if (options.results.empty()) {
      options.results = a;
    } else {
      std::fprintf(stderr, "mbdae: error: view takes one results file, got a second: '%s'\n%s", a.c_str(), kViewUsage);
      return 2;
    }
  }
  if (options.results.empty()) {
    std::fprintf(stderr, "mbdae: error: view: no results file given\n%s", kViewUsage);
    return 2;
  }
  if (options.output.empty()) {
    const std::string& in = options.results;
    const size_t dot = in.find_last_of('.'), slash = in.find_last_of('/');
    const bool ext = dot != std::string::npos && (slash == std::string::npos || dot > slash);
    options.output = (ext ? in.substr(0, dot) : in) + ".html";
  }
  std::string html;
  try {
    html = ViewerHtml(options);
  } catch (const ViewInputError& e) {
    std::fprintf(stderr, "mbdae: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mbdae: error: %s\n", e.what());
    return 1;
  }
  std::ofstream out(options.output, std::ios::binary);
  if (!out || !(out << html) || !(out.flush())) {
    std::fprintf(stderr, "mbdae: error: cannot write %s: %s\n", options.output.c_str(), std::strerror(errno));
    return 2;
  }
  std::fprintf(stderr, "mbdae: wrote %s (%.1f MB); open it in a browser\n", options.output.c_str(), html.size() / 1e6);
  return 0;
}

}  // namespace mbdae::app
