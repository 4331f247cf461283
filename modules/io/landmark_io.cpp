#include "io/landmark_io.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>

#include "registration/registration.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"
#include "skel/text.hpp"

namespace skel::io {
namespace {

using text::split;
using text::split_lines;
using text::trim;

std::string where(const std::string& name, size_t line) { return name + ":" + std::to_string(line + 1); }

double parse_number(const std::string& text, const std::string& context) {
  const std::string t = trim(text);
  double v = 0.0;
  if (!text::parse_double(t, v)) {
    // A number too large for a double (1e400) is a number, but not a finite one.
    char* end = nullptr;
    (void)std::strtod(t.c_str(), &end);
    const bool overflow = !t.empty() && end == t.c_str() + t.size();
    throw InputError(context + ": '" + t + (overflow ? "' is not a finite number" : "' is not a number"));
  }
  // inf, nan and overflowing numbers (1e400) would poison every distance computed from them.
  if (!std::isfinite(v)) throw InputError(context + ": '" + t + "' is not a finite number");
  return v;
}

std::vector<double> parse_numbers(const std::string& text, const std::string& context) {
  std::vector<double> out;
  std::istringstream in(text);
  std::string tok;
  while (in >> tok) out.push_back(parse_number(tok, context));
  return out;
}

std::string format_double(double v) { return text::format_double(v, 17); }

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    std::error_code ec;
    throw InputError(path.string() + (std::filesystem::exists(path, ec) ? ": cannot open the file for reading" : ": file not found"));
  }
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_file(const std::filesystem::path& path, const std::string& text) { write_file_atomically(path, text); }

void check_name_for_csv(const std::string& n, const char* format) {
  if (n.find_first_of(",\"\r\n") != std::string::npos) {
    throw InputError(std::string(format) + ": landmark name '" + n +
                     "' contains a comma, quote or line break, which this format cannot store");
  }
}

// ---------------------------------------------------------------- Amira
LandmarkSet parse_amira(const std::string& text, const std::string& name) {
  const auto lines = split_lines(text);
  if (lines.empty() || (lines[0].rfind("# AmiraMesh", 0) != 0 && lines[0].rfind("# Avizo", 0) != 0 &&
                        lines[0].rfind("# HyperMesh", 0) != 0)) {
    throw InputError(where(name, 0) + ": not an AmiraMesh file (expected '# AmiraMesh 3D ASCII 2.0')");
  }
  if (lines[0].find("BINARY") != std::string::npos) {
    throw InputError(where(name, 0) + ": binary AmiraMesh landmarks are not supported; save as landmarkAscii");
  }
  int64_t count = -1, num_sets = -1;
  std::map<int64_t, int64_t> block_of_set;  // data block number @K → set index (declaration order)
  size_t i = 1;
  for (; i < lines.size(); ++i) {
    const std::string l = trim(lines[i]);
    if (l.empty()) continue;
    if (l[0] == '@') break;  // first data block
    if (l[0] == '#') continue;
    if (l.rfind("define Markers", 0) == 0 || l.rfind("nMarkers", 0) == 0) {
      // "define Markers N", possibly followed by more header on the same line (old files).
      std::istringstream in(l.substr(l.find("Markers") + 7));
      std::string tok;
      in >> tok;
      const double v = parse_number(tok, where(name, i) + ": 'define Markers N'");
      if (v < 0 || v != std::floor(v)) throw InputError(where(name, i) + ": expected 'define Markers N'");
      // Each marker is 3 ASCII values of >= 2 bytes: refuse a count the file cannot hold.
      if (v * 6.0 > static_cast<double>(text.size()))
        throw InputError(where(name, i) + ": 'define Markers " + tok + "' declares more markers than a file of " +
                         std::to_string(text.size()) + " bytes can hold");
      count = static_cast<int64_t>(v);
    } else if (auto p = l.find("NumSets"); p != std::string::npos) {
      std::string rest = l.substr(p + 7);
      rest.erase(std::remove(rest.begin(), rest.end(), ','), rest.end());
      const auto nums = parse_numbers(rest, where(name, i));
      // k ≥ 1, an integer, and at most one set per declaration line the file can hold.
      if (nums.size() != 1 || !(nums[0] >= 1 && nums[0] <= static_cast<double>(text.size())) ||
          nums[0] != std::floor(nums[0]))
        throw InputError(where(name, i) + ": expected 'NumSets k'");
      num_sets = static_cast<int64_t>(nums[0]);
    } else if (l.rfind("Markers", 0) == 0 && l.find('{') != std::string::npos) {
      const auto at = l.rfind('@');
      if (at == std::string::npos) throw InputError(where(name, i) + ": data declaration without '@K'");
      if (l.find("Coordinates") == std::string::npos) continue;  // other per-marker data: ignored
      const auto nums = parse_numbers(l.substr(at + 1), where(name, i));
      if (nums.size() != 1) throw InputError(where(name, i) + ": expected '@K' at the end of the declaration");
      if (!(nums[0] >= 0 && nums[0] <= 1e9) || nums[0] != std::floor(nums[0]))
        throw InputError(where(name, i) + ": expected a block number '@K' (K >= 0)");
      const auto block = static_cast<int64_t>(nums[0]);
      const auto set_index = static_cast<int64_t>(block_of_set.size());
      if (!block_of_set.emplace(block, set_index).second)
        throw InputError(where(name, i) + ": data block @" + std::to_string(block) + " is declared twice");
    }
  }
  if (count < 0) throw InputError(name + ": missing 'define Markers N'");
  if (block_of_set.empty()) throw InputError(name + ": no 'Markers { float[3] Coordinates } @K' declaration");
  if (num_sets < 0) num_sets = static_cast<int64_t>(block_of_set.size());
  if (num_sets != static_cast<int64_t>(block_of_set.size())) {
    throw InputError(name + ": NumSets " + std::to_string(num_sets) + " but " + std::to_string(block_of_set.size()) +
                     " coordinate declarations");
  }
  std::vector<std::vector<Vec3>> sets(static_cast<size_t>(num_sets));
  std::vector<bool> seen(static_cast<size_t>(num_sets), false);
  while (i < lines.size()) {
    const std::string l = trim(lines[i]);
    if (l.empty() || l[0] == '#') {
      ++i;
      continue;
    }
    if (l[0] != '@') throw InputError(where(name, i) + ": expected a data block '@K'");
    const auto nums = parse_numbers(l.substr(1), where(name, i));
    if (nums.size() != 1) throw InputError(where(name, i) + ": expected '@K'");
    // As in the declarations: a whole K in [0, 1e9] (a larger one made the cast to int64 undefined).
    if (!(nums[0] >= 0 && nums[0] <= 1e9) || nums[0] != std::floor(nums[0]))
      throw InputError(where(name, i) + ": expected a block number '@K' (K >= 0)");
    const auto it = block_of_set.find(static_cast<int64_t>(nums[0]));
    const size_t header = i++;
    std::vector<Vec3> pts;
    // Values may be spread over lines; read 3·count numbers.
    std::vector<double> values;
    while (i < lines.size() && static_cast<int64_t>(values.size()) < 3 * count) {
      const std::string d = trim(lines[i]);
      if (!d.empty() && d[0] == '@') break;
      if (!d.empty() && d[0] != '#') {
        const auto v = parse_numbers(d, where(name, i));
        values.insert(values.end(), v.begin(), v.end());
      }
      ++i;
    }
    if (it == block_of_set.end()) continue;  // a block of other data
    if (static_cast<int64_t>(values.size()) != 3 * count) {
      throw InputError(where(name, header) + ": block " + l + " has " + std::to_string(values.size()) +
                       " numbers; expected " + std::to_string(3 * count) + " (define Markers " + std::to_string(count) + ")");
    }
    for (int64_t k = 0; k < count; ++k) {
      pts.push_back({values[static_cast<size_t>(3 * k)], values[static_cast<size_t>(3 * k + 1)],
                     values[static_cast<size_t>(3 * k + 2)]});
    }
    sets[static_cast<size_t>(it->second)] = std::move(pts);
    seen[static_cast<size_t>(it->second)] = true;
  }
  for (size_t s = 0; s < seen.size(); ++s) {
    if (!seen[s] && count > 0) throw InputError(name + ": data block of set " + std::to_string(s + 1) + " is missing");
    if (!seen[s]) sets[s].clear();
  }
  return LandmarkSet(std::move(sets));
}

std::string format_amira(const LandmarkSet& lm) {
  if (lm.set_count() < 1) throw InputError("landmarkAscii: the landmark object has no set");
  std::ostringstream o;
  o << "# AmiraMesh 3D ASCII 2.0\n\n\n";
  o << "define Markers " << lm.point_count() << "\n\n";
  o << "Parameters {\n    NumSets " << lm.set_count() << ",\n    ContentType \"LandmarkSet\"\n}\n\n";
  for (int64_t s = 0; s < lm.set_count(); ++s) {
    o << "Markers { float[3] Coordinates";
    if (s > 0) o << (s + 1);
    o << " } @" << (s + 1) << "\n";
  }
  o << "\n# Data section follows\n";
  for (int64_t s = 0; s < lm.set_count(); ++s) {
    o << "@" << (s + 1) << "\n";
    for (const auto& p : lm.set(s)) o << format_double(p[0]) << " " << format_double(p[1]) << " " << format_double(p[2]) << "\n";
    o << "\n";
  }
  return o.str();
}

// ---------------------------------------------------------------- Slicer fcsv
LandmarkSet parse_fcsv(const std::string& text, const std::string& name) {
  const auto lines = split_lines(text);
  bool ras = false;
  std::vector<std::string> columns = {"id", "x", "y", "z", "ow", "ox", "oy", "oz", "vis", "sel", "lock", "label", "desc", "associatedNodeID"};
  std::vector<Vec3> pts;
  std::vector<std::string> names;
  bool header_seen = false;
  for (size_t i = 0; i < lines.size(); ++i) {
    const std::string l = trim(lines[i]);
    if (l.empty()) continue;
    if (l[0] == '#') {
      const std::string body = trim(l.substr(1));
      if (body.rfind("Markups fiducial file version", 0) == 0) header_seen = true;
      if (body.rfind("CoordinateSystem", 0) == 0) {
        const auto eq = body.find('=');
        const std::string v = eq == std::string::npos ? "" : trim(body.substr(eq + 1));
        if (v == "RAS" || v == "0") ras = true;
        else if (v == "LPS" || v == "1") ras = false;
        else throw InputError(where(name, i) + ": unsupported CoordinateSystem '" + v + "'; expected LPS or RAS");
      }
      if (body.rfind("columns", 0) == 0) {
        const auto eq = body.find('=');
        if (eq != std::string::npos) {
          columns = split(trim(body.substr(eq + 1)), ',');
          for (auto& c : columns) c = trim(c);
        }
      }
      continue;
    }
    const auto find_col = [&](const std::string& c) -> size_t {
      const auto it = std::find(columns.begin(), columns.end(), c);
      if (it == columns.end()) throw InputError(where(name, i) + ": the columns line has no '" + c + "' column");
      return static_cast<size_t>(it - columns.begin());
    };
    const size_t cx = find_col("x"), cy = find_col("y"), cz = find_col("z");
    const auto label_it = std::find(columns.begin(), columns.end(), "label");
    const auto fields = split(l, ',');
    if (fields.size() <= std::max({cx, cy, cz})) {
      throw InputError(where(name, i) + ": expected at least " + std::to_string(std::max({cx, cy, cz}) + 1) + " fields");
    }
    Vec3 p{parse_number(fields[cx], where(name, i)), parse_number(fields[cy], where(name, i)),
           parse_number(fields[cz], where(name, i))};
    if (ras) {
      p[0] = -p[0];
      p[1] = -p[1];
    }
    pts.push_back(p);
    std::string label;
    if (label_it != columns.end()) {
      const auto li = static_cast<size_t>(label_it - columns.begin());
      if (li < fields.size()) label = trim(fields[li]);
    }
    names.push_back(label.empty() ? LandmarkSet::default_name(static_cast<int64_t>(names.size())) : label);
  }
  if (!header_seen) throw InputError(name + ": not a Slicer markups file (no '# Markups fiducial file version' line)");
  std::vector<std::vector<Vec3>> sets;
  sets.push_back(std::move(pts));
  return LandmarkSet(std::move(sets), std::move(names));
}

std::string format_fcsv(const LandmarkSet& lm) {
  if (lm.set_count() != 1) {
    throw InputError(".fcsv holds one landmark set, but the object has " + std::to_string(lm.set_count()) +
                     "; write one file per set (io.write_landmarks parameter 'set')");
  }
  std::ostringstream o;
  o << "# Markups fiducial file version = 4.11\n# CoordinateSystem = LPS\n"
       "# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n";
  const auto& pts = lm.set(0);
  for (size_t i = 0; i < pts.size(); ++i) {
    check_name_for_csv(lm.names[i], ".fcsv");
    o << "vtkMRMLMarkupsFiducialNode_" << i << "," << format_double(pts[i][0]) << "," << format_double(pts[i][1])
      << "," << format_double(pts[i][2]) << ",0,0,0,1,1,1,0," << lm.names[i] << ",,\n";
  }
  return o.str();
}

// ---------------------------------------------------------------- CSV
LandmarkSet parse_csv(const std::string& text, const std::string& name) {
  const auto lines = split_lines(text);
  size_t i = 0;
  while (i < lines.size() && trim(lines[i]).empty()) ++i;
  if (i == lines.size()) throw InputError(name + ": empty file; expected a header 'set,name,x,y,z'");
  auto header = split(trim(lines[i]), ',');
  std::string unit;  // from "x [mm]"
  for (auto& h : header) {
    h = trim(h);
    if (auto b = h.find('['); b != std::string::npos && h.back() == ']') {
      if (unit.empty()) unit = trim(h.substr(b + 1, h.size() - b - 2));
      h = trim(h.substr(0, b));
    }
    h = text::to_lower(h);
  }
  const auto col = [&](const std::string& c) -> size_t {
    const auto it = std::find(header.begin(), header.end(), c);
    if (it == header.end()) throw InputError(where(name, i) + ": header has no '" + c + "' column; expected set,name,x,y,z");
    return static_cast<size_t>(it - header.begin());
  };
  const size_t cs = col("set"), cn = col("name"), cx = col("x"), cy = col("y"), cz = col("z");
  const size_t need = std::max({cs, cn, cx, cy, cz}) + 1;
  std::vector<std::string> set_labels;                          // order of first appearance
  std::map<std::string, std::vector<std::pair<std::string, Vec3>>> rows;  // set → (name, point)
  for (++i; i < lines.size(); ++i) {
    const std::string l = trim(lines[i]);
    if (l.empty() || l[0] == '#') continue;
    const auto f = split(l, ',');
    if (f.size() < need)
      throw InputError(where(name, i) + ": expected " + std::to_string(need) + " fields, got " + std::to_string(f.size()));
    const std::string s = trim(f[cs]);
    if (!rows.count(s)) set_labels.push_back(s);
    rows[s].push_back({trim(f[cn]), {parse_number(f[cx], where(name, i)), parse_number(f[cy], where(name, i)),
                                     parse_number(f[cz], where(name, i))}});
  }
  // Sets ordered numerically when all labels are digit strings (of any length), else by first
  // appearance.
  const bool numeric = std::all_of(set_labels.begin(), set_labels.end(), [](const std::string& s) {
    return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); });
  });
  if (numeric) {
    std::sort(set_labels.begin(), set_labels.end(),
              [](const std::string& a, const std::string& b) {
                // Numeric order of digit strings of any length (no std::stoll: it throws past int64).
                const auto sa = a.substr(std::min(a.find_first_not_of('0'), a.size()));
                const auto sb = b.substr(std::min(b.find_first_not_of('0'), b.size()));
                return sa.size() != sb.size() ? sa.size() < sb.size() : sa < sb;
              });
  }
  std::vector<std::string> names;
  std::vector<std::vector<Vec3>> sets;
  for (size_t s = 0; s < set_labels.size(); ++s) {
    const auto& r = rows[set_labels[s]];
    std::vector<Vec3> pts;
    if (s == 0) {
      for (const auto& [n, p] : r) {
        if (std::find(names.begin(), names.end(), n) != names.end()) {
          throw InputError(name + ": landmark name '" + n + "' appears twice in set " + set_labels[s]);
        }
        names.push_back(n);
        pts.push_back(p);
      }
    } else {
      if (r.size() != names.size()) {
        throw InputError(name + ": set " + set_labels[s] + " has " + std::to_string(r.size()) + " points; set " +
                         set_labels[0] + " has " + std::to_string(names.size()));
      }
      pts.resize(names.size());
      std::vector<bool> got(names.size(), false);
      for (const auto& [n, p] : r) {
        const auto it = std::find(names.begin(), names.end(), n);
        if (it == names.end()) throw InputError(name + ": landmark '" + n + "' of set " + set_labels[s] + " is not in set " + set_labels[0]);
        const auto k = static_cast<size_t>(it - names.begin());
        if (got[k]) throw InputError(name + ": landmark name '" + n + "' appears twice in set " + set_labels[s]);
        got[k] = true;
        pts[k] = p;
      }
    }
    sets.push_back(std::move(pts));
  }
  for (size_t k = 0; k < names.size(); ++k)
    if (names[k].empty()) names[k] = LandmarkSet::default_name(static_cast<int64_t>(k));
  LandmarkSet lm(std::move(sets), std::move(names));
  if (!unit.empty()) lm.unit = unit;
  return lm;
}

std::string format_csv(const LandmarkSet& lm) {
  std::ostringstream o;
  o << "set,name,x [" << lm.unit << "],y [" << lm.unit << "],z [" << lm.unit << "]\n";
  for (int64_t s = 0; s < lm.set_count(); ++s) {
    const auto& pts = lm.set(s);
    for (size_t i = 0; i < pts.size(); ++i) {
      check_name_for_csv(lm.names[i], "CSV");
      o << s << "," << lm.names[i] << "," << format_double(pts[i][0]) << "," << format_double(pts[i][1]) << ","
        << format_double(pts[i][2]) << "\n";
    }
  }
  return o.str();
}

// ---------------------------------------------------------------- transforms
Transform parse_matrix(const std::string& text, const std::string& name) {
  const auto lines = split_lines(text);
  std::vector<double> v;
  std::string kind_text;
  for (size_t i = 0; i < lines.size(); ++i) {
    const std::string l = trim(lines[i]);
    if (l.empty()) continue;
    if (l[0] == '#') {
      if (auto p = l.find("kind="); p != std::string::npos) {
        std::istringstream in(l.substr(p + 5));
        in >> kind_text;
      }
      continue;
    }
    std::string cleaned = l;
    std::replace(cleaned.begin(), cleaned.end(), ',', ' ');
    const auto nums = parse_numbers(cleaned, where(name, i));
    v.insert(v.end(), nums.begin(), nums.end());
  }
  if (v.size() != 16 && v.size() != 12) {
    throw InputError(name + ": expected a 4x4 matrix (16 numbers, or 12 for the top 3 rows), found " +
                     std::to_string(v.size()) + " numbers");
  }
  Matrix4 m{{{0, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 0, 1}}};
  for (size_t k = 0; k < v.size(); ++k) m[k / 4][k % 4] = v[k];
  const TransformKind kind = kind_text.empty() ? registration::classify_transform(m) : parse_transform_kind(kind_text, name + ": kind");
  try {
    return Transform(m, kind);
  } catch (const InputError& e) {
    throw InputError(name + ": " + e.what());
  }
}

std::string format_matrix(const Transform& t) {
  std::ostringstream o;
  o << "# skelflow transform kind=" << to_string(t.kind()) << " maps moving -> fixed, physical units\n";
  for (const auto& row : t.matrix()) {
    o << format_double(row[0]) << " " << format_double(row[1]) << " " << format_double(row[2]) << " "
      << format_double(row[3]) << "\n";
  }
  return o.str();
}

Transform parse_itk(const std::string& text, const std::string& name) {
  const auto lines = split_lines(text);
  if (lines.empty() || trim(lines[0]).rfind("#Insight Transform File", 0) != 0) {
    throw InputError(where(name, 0) + ": not an ITK transform file (expected '#Insight Transform File V1.0')");
  }
  std::string type;
  std::vector<double> params, fixed_params;
  size_t params_line = 0, fixed_line = 0;  // for messages
  int transforms = 0;
  for (size_t i = 1; i < lines.size(); ++i) {
    const std::string l = trim(lines[i]);
    if (l.empty() || l[0] == '#') continue;
    const auto colon = l.find(':');
    if (colon == std::string::npos) throw InputError(where(name, i) + ": expected 'Key: value'");
    const std::string key = trim(l.substr(0, colon)), value = trim(l.substr(colon + 1));
    if (key == "Transform") {
      if (++transforms > 1) throw InputError(where(name, i) + ": composite files with several transforms are not supported");
      type = value;
    } else if (key == "Parameters") {
      params = parse_numbers(value, where(name, i));
      params_line = i;
    } else if (key == "FixedParameters") {
      fixed_params = parse_numbers(value, where(name, i));
      fixed_line = i;
    }
  }
  const bool affine_type = type == "AffineTransform_double_3_3" || type == "AffineTransform_float_3_3" ||
                           type == "MatrixOffsetTransformBase_double_3_3" || type == "MatrixOffsetTransformBase_float_3_3";
  if (!affine_type) {
    throw InputError(name + ": ITK transform type '" + type +
                     "' is not supported; expected AffineTransform_double_3_3 (or _float_, or MatrixOffsetTransformBase)");
  }
  if (params.size() != 12)
    throw InputError((params_line ? where(name, params_line) : name) + ": 'Parameters' has " +
                     std::to_string(params.size()) + " numbers; expected 12");
  if (fixed_params.empty()) fixed_params = {0, 0, 0};
  if (fixed_params.size() != 3) {
    throw InputError(where(name, fixed_line) + ": 'FixedParameters' has " + std::to_string(fixed_params.size()) +
                     " numbers; expected 3 (the centre)");
  }
  // ITK: T(x) = A (x - c) + c + t, mapping fixed → moving (LPS).
  Matrix3 a{};
  Vec3 offset{};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) a[r][c] = params[static_cast<size_t>(3 * r + c)];
  }
  for (int r = 0; r < 3; ++r) {
    offset[r] = params[static_cast<size_t>(9 + r)] + fixed_params[static_cast<size_t>(r)];
    for (int c = 0; c < 3; ++c) offset[r] -= a[r][c] * fixed_params[static_cast<size_t>(c)];
  }
  try {
    const Transform fixed_to_moving(a, offset);
    Transform t = fixed_to_moving.inverse();
    t.set_kind(registration::classify_transform(t.matrix()));
    return t;
  } catch (const InputError& e) {
    throw InputError(name + ": " + e.what());
  }
}

std::string format_itk(const Transform& t) {
  const Transform inv = t.inverse();  // ITK stores fixed → moving
  const auto& m = inv.matrix();
  std::ostringstream o;
  o << "#Insight Transform File V1.0\n#Transform 0\nTransform: AffineTransform_double_3_3\nParameters:";
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) o << " " << format_double(m[r][c]);
  for (int r = 0; r < 3; ++r) o << " " << format_double(m[r][3]);
  o << "\nFixedParameters: 0 0 0\n";
  return o.str();
}

}  // namespace

LandmarkFormat parse_landmark_format(const std::string& text) {
  if (text == "auto") return LandmarkFormat::Auto;
  if (text == "amira") return LandmarkFormat::Amira;
  if (text == "fcsv") return LandmarkFormat::Fcsv;
  if (text == "csv") return LandmarkFormat::Csv;
  throw InputError("format: '" + text + "' is not a landmark format; expected auto, amira, fcsv or csv");
}

TransformFormat parse_transform_format(const std::string& text) {
  if (text == "auto") return TransformFormat::Auto;
  if (text == "matrix") return TransformFormat::Matrix;
  if (text == "itk") return TransformFormat::Itk;
  throw InputError("format: '" + text + "' is not a transform format; expected auto, matrix or itk");
}

LandmarkFormat resolve_landmark_format(LandmarkFormat format, const std::filesystem::path& path) {
  if (format != LandmarkFormat::Auto) return format;
  const std::string ext = text::to_lower(path.extension().string());
  if (ext == ".landmarkascii" || ext == ".am") return LandmarkFormat::Amira;
  if (ext == ".fcsv") return LandmarkFormat::Fcsv;
  if (ext == ".csv") return LandmarkFormat::Csv;
  throw InputError("'" + path.string() +
                   "': cannot tell the landmark format from the extension; use .landmarkAscii, .fcsv or .csv, or set 'format'");
}

TransformFormat resolve_transform_format(TransformFormat format, const std::filesystem::path& path) {
  if (format != TransformFormat::Auto) return format;
  return text::to_lower(path.extension().string()) == ".tfm" ? TransformFormat::Itk : TransformFormat::Matrix;
}

LandmarkSet parse_landmarks(const std::string& text, LandmarkFormat format, const std::string& name) {
  switch (format) {
    case LandmarkFormat::Amira: return parse_amira(text, name);
    case LandmarkFormat::Fcsv: return parse_fcsv(text, name);
    case LandmarkFormat::Csv: return parse_csv(text, name);
    case LandmarkFormat::Auto: break;
  }
  throw InputError(name + ": landmark format not resolved");
}

std::string format_landmarks(const LandmarkSet& landmarks, LandmarkFormat format) {
  if (auto problems = landmarks.check_invariants(); !problems.empty()) throw InputError("landmarks: " + problems.front());
  switch (format) {
    case LandmarkFormat::Amira: return format_amira(landmarks);
    case LandmarkFormat::Fcsv: return format_fcsv(landmarks);
    case LandmarkFormat::Csv: return format_csv(landmarks);
    case LandmarkFormat::Auto: break;
  }
  throw InputError("landmark format not resolved");
}

Transform parse_transform(const std::string& text, TransformFormat format, const std::string& name) {
  return format == TransformFormat::Itk ? parse_itk(text, name) : parse_matrix(text, name);
}

std::string format_transform(const Transform& transform, TransformFormat format) {
  return format == TransformFormat::Itk ? format_itk(transform) : format_matrix(transform);
}

LandmarkSet read_landmarks(const std::filesystem::path& path, LandmarkFormat format) {
  const LandmarkFormat f = resolve_landmark_format(format, path);
  return parse_landmarks(read_file(path), f, path.string());
}

void write_landmarks(const std::filesystem::path& path, const LandmarkSet& landmarks, LandmarkFormat format) {
  write_file(path, format_landmarks(landmarks, resolve_landmark_format(format, path)));
}

Transform read_transform(const std::filesystem::path& path, TransformFormat format) {
  return parse_transform(read_file(path), resolve_transform_format(format, path), path.string());
}

void write_transform(const std::filesystem::path& path, const Transform& transform, TransformFormat format) {
  write_file(path, format_transform(transform, resolve_transform_format(format, path)));
}

}  // namespace skel::io
