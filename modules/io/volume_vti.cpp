// VTK XML image data (`.vti`, what ParaView, VMTK and vtkXMLImageDataWriter write). Read: the
// point-data array named by PointData's `Scalars` (else its first one-component array), stored
// inline (base64 `binary` or `ascii`) or appended (`raw` or `base64`), uncompressed or
// vtkZLibDataCompressor blocks, header_type UInt32 or UInt64, either byte order; WholeExtent,
// Origin, Spacing, Direction (row-major, VTK 9) -> the grid (an extent starting at i0 moves the
// origin to voxel i0). One piece. VTK names no unit: Skelflow writes a FieldData string array `unit`
// and reads it back (absent: the default unit).
// Write: appended raw, header_type UInt64, zlib blocks of 1 MiB when compression > 0.
// The XML part is parsed by expat; appended raw data (not XML) is cut off before parsing.
#include <expat.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>

#include "io/volume_bytes.hpp"
#include "io/volume_format.hpp"
#include "io/vtk_xml_data.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"
#include "skel/text.hpp"

namespace skel::io {

namespace {

namespace fs = std::filesystem;

using Attrs = std::map<std::string, std::string>;

struct VtiDoc {
  std::string file;
  Attrs vtkfile, image, piece, array;  // array: the chosen point-data DataArray
  std::string array_text;              // its inline content
  std::string unit;                    // FieldData string array "unit" (as char codes)
  bool has_unit = false;
  int pieces = 0;
  int64_t array_line = 0;
  // Appended data: where it starts in the file (after '_') and its encoding.
  bool has_appended = false;
  uint64_t appended_begin = 0;
  std::string appended_encoding;
  // Derived:
  VolumeHeader header;
  std::string stored;
  bool big_endian = false;
  size_t header_bytes = 4;  // UInt32 or UInt64
  bool compressed = false;
};

std::string vtk_type(const std::string& t) {
  static const std::map<std::string, std::string> names{
      {"Int8", "int8"},   {"UInt8", "uint8"},   {"Int16", "int16"}, {"UInt16", "uint16"}, {"Int32", "int32"},
      {"UInt32", "uint32"}, {"Int64", "int64"}, {"UInt64", "uint64"}, {"Float32", "float32"}, {"Float64", "float64"},
      {"Char", "int8"}, {"UnsignedChar", "uint8"}, {"Short", "int16"}, {"UnsignedShort", "uint16"}, {"Int", "int32"},
      {"UnsignedInt", "uint32"}, {"Float", "float32"}, {"Double", "float64"}};
  auto it = names.find(t);
  return it == names.end() ? std::string() : it->second;
}

std::string vtk_name(const std::string& dtype) {
  static const std::map<std::string, std::string> names{
      {"uint8", "UInt8"}, {"uint16", "UInt16"}, {"uint32", "UInt32"}, {"uint64", "UInt64"},
      {"int32", "Int32"}, {"float32", "Float32"}, {"float64", "Float64"}};
  return names.at(dtype);
}

struct ParseState {
  VtiDoc* doc = nullptr;
  XML_Parser parser = nullptr;
  std::vector<std::string> stack;
  bool in_point_data = false, in_field_data = false;
  std::string scalars;          // PointData's Scalars attribute
  bool collecting = false;      // inside the chosen DataArray
  bool collecting_unit = false; // inside FieldData's "unit" array
  bool chosen = false;
};

Attrs to_attrs(const XML_Char** atts) {
  Attrs a;
  for (int i = 0; atts[i]; i += 2) a[atts[i]] = atts[i + 1];
  return a;
}

void on_start(void* ud, const XML_Char* name_c, const XML_Char** atts) {
  auto& st = *static_cast<ParseState*>(ud);
  const std::string name = name_c;
  Attrs a = to_attrs(atts);
  VtiDoc& d = *st.doc;
  if (st.stack.empty() && name == "VTKFile") d.vtkfile = a;
  else if (name == "ImageData" && st.stack.size() == 1) d.image = a;
  else if (name == "Piece" && st.stack.size() == 2 && st.stack.back() == "ImageData") {
    if (++d.pieces == 1) d.piece = a;
  } else if (name == "PointData" && d.pieces == 1) {
    st.in_point_data = true;
    st.scalars = a.count("Scalars") ? a["Scalars"] : "";
  } else if (name == "FieldData") {
    st.in_field_data = true;
  } else if ((name == "Array" || name == "DataArray") && st.in_field_data && a["Name"] == "unit" && a["type"] == "String" &&
             a["format"] == "ascii") {
    st.collecting_unit = true;
    d.has_unit = true;
  } else if (name == "DataArray" && st.in_point_data && !st.chosen) {
    const std::string comps = a.count("NumberOfComponents") ? a["NumberOfComponents"] : "1";
    if ((!st.scalars.empty() && a["Name"] == st.scalars) || (st.scalars.empty() && comps == "1")) {
      st.chosen = true;
      st.collecting = true;
      d.array = a;
      d.array_line = XML_GetCurrentLineNumber(st.parser);
    }
  }
  st.stack.push_back(name);
}

void on_end(void* ud, const XML_Char* name_c) {
  auto& st = *static_cast<ParseState*>(ud);
  const std::string name = name_c;
  if (name == "PointData") st.in_point_data = false;
  if (name == "FieldData") st.in_field_data = false;
  if (name == "DataArray") st.collecting = false;
  if (name == "Array" || name == "DataArray") st.collecting_unit = false;
  st.stack.pop_back();
}

void on_text(void* ud, const XML_Char* s, int len) {
  auto& st = *static_cast<ParseState*>(ud);
  if (st.collecting) st.doc->array_text.append(s, static_cast<size_t>(len));
  if (st.collecting_unit) st.doc->unit.append(s, static_cast<size_t>(len));
}

std::vector<double> numbers(const VtiDoc& d, const Attrs& a, const char* key, size_t count, const char* element) {
  auto it = a.find(key);
  std::vector<double> out;
  if (it == a.end()) return out;
  for (const auto& w : text::split(it->second, ' ')) {
    if (text::trim(w).empty()) continue;
    double v = 0;
    if (!text::parse_double(text::trim(w), v) || !std::isfinite(v))
      throw InputError(d.file + ": " + element + " " + key + ": '" + w.substr(0, 30) + "' is not a finite number");
    out.push_back(v);
  }
  if (out.size() != count)
    throw InputError(d.file + ": " + element + " " + key + " has " + std::to_string(out.size()) + " values; expected " +
                     std::to_string(count));
  return out;
}

VtiDoc parse(const fs::path& path, std::string* whole = nullptr) {
  VtiDoc d;
  d.file = path.string();
  std::string s;
  if (whole) {
    s = volbytes::read_file(path);
  } else {
    // The header only: the XML before the appended data, or the whole file when the data is inline.
    const uint64_t size = volbytes::file_size(path);
    s.resize(static_cast<size_t>(std::min<uint64_t>(size, 1 << 20)));
    volbytes::read_exact(path, 0, s.data(), s.size(), "header");
    if (s.size() < size && s.find("<AppendedData") == std::string::npos) s = volbytes::read_file(path);
  }
  std::string xml;
  const size_t app = s.find("<AppendedData");
  if (app != std::string::npos) {
    d.has_appended = true;
    const size_t close = s.find('>', app);
    if (close == std::string::npos) throw InputError(d.file + ": the <AppendedData> tag is not closed (truncated)");
    const std::string tag = s.substr(app, close - app);
    const size_t enc = tag.find("encoding=\"");
    d.appended_encoding = enc == std::string::npos ? "raw" : tag.substr(enc + 10, tag.find('"', enc + 10) - enc - 10);
    const size_t underscore = s.find('_', close);
    if (underscore == std::string::npos) throw InputError(d.file + ": the appended data has no '_' marker (truncated)");
    d.appended_begin = underscore + 1;
    xml = s.substr(0, app) + "</VTKFile>";
  } else {
    xml = s;
  }
  if (xml.find("<VTKFile") == std::string::npos) throw InputError(d.file + ": not a VTK XML file (no <VTKFile> element)");
  ParseState st;
  st.doc = &d;
  std::unique_ptr<std::remove_pointer_t<XML_Parser>, void (*)(XML_Parser)> parser(XML_ParserCreate(nullptr), XML_ParserFree);
  if (!parser) throw Error("XML parser: out of memory");
  st.parser = parser.get();
  XML_SetUserData(parser.get(), &st);
  XML_SetElementHandler(parser.get(), on_start, on_end);
  XML_SetCharacterDataHandler(parser.get(), on_text);
  if (XML_Parse(parser.get(), xml.data(), static_cast<int>(std::min<size_t>(xml.size(), 0x7fffffff)), 1) == XML_STATUS_ERROR)
    throw InputError(d.file + ":" + std::to_string(XML_GetCurrentLineNumber(parser.get())) + ": XML error: " +
                     XML_ErrorString(XML_GetErrorCode(parser.get())));
  if (whole) *whole = std::move(s);

  if (d.vtkfile.empty()) throw InputError(d.file + ": not a VTK XML file (the root element is not <VTKFile>)");
  if (d.vtkfile["type"] != "ImageData")
    throw InputError(d.file + ": a VTK XML file of type '" + d.vtkfile["type"] + "', not ImageData");
  if (d.image.empty()) throw InputError(d.file + ": no <ImageData> element");
  if (d.pieces != 1)
    throw InputError(d.file + ": " + std::to_string(d.pieces) + " pieces; Skelflow reads VTK image files of one piece");
  if (d.array.empty()) throw InputError(d.file + ": no point-data array with one component (the voxels)");
  const std::string bo = d.vtkfile.count("byte_order") ? d.vtkfile["byte_order"] : "LittleEndian";
  if (bo != "LittleEndian" && bo != "BigEndian") throw InputError(d.file + ": byte_order '" + bo + "' (LittleEndian or BigEndian)");
  d.big_endian = bo == "BigEndian";
  const std::string ht = d.vtkfile.count("header_type") ? d.vtkfile["header_type"] : "UInt32";
  if (ht != "UInt32" && ht != "UInt64") throw InputError(d.file + ": header_type '" + ht + "' (UInt32 or UInt64)");
  d.header_bytes = ht == "UInt64" ? 8 : 4;
  if (d.vtkfile.count("compressor") && !d.vtkfile["compressor"].empty()) {
    if (d.vtkfile["compressor"] != "vtkZLibDataCompressor")
      throw InputError(d.file + ": unsupported compressor '" + d.vtkfile["compressor"] + "' (vtkZLibDataCompressor)");
    d.compressed = true;
  }
  const std::string where = d.file + ":" + std::to_string(d.array_line);
  d.stored = vtk_type(d.array["type"]);
  if (d.stored.empty())
    throw InputError(where + ": unsupported DataArray type '" + d.array["type"] +
                     "' (Int8, UInt8, Int16, UInt16, Int32, UInt32, Int64, UInt64, Float32, Float64)");
  if (d.array.count("NumberOfComponents") && d.array["NumberOfComponents"] != "1")
    throw InputError(where + ": DataArray '" + d.array["Name"] + "' has " + d.array["NumberOfComponents"] +
                     " components; Skelflow reads one");

  auto ext = numbers(d, d.image, "WholeExtent", 6, "ImageData");
  if (ext.empty()) throw InputError(d.file + ": ImageData has no WholeExtent");
  Grid& g = d.header.grid;
  for (size_t i = 0; i < 3; ++i) {
    if (ext[2 * i] != std::floor(ext[2 * i]) || ext[2 * i + 1] != std::floor(ext[2 * i + 1]) || ext[2 * i + 1] < ext[2 * i] ||
        ext[2 * i + 1] - ext[2 * i] > 9e15)
      throw InputError(d.file + ": ImageData WholeExtent axis " + std::string(1, "xyz"[i]) + " is " +
                       text::format_double(ext[2 * i], 17) + " " + text::format_double(ext[2 * i + 1], 17) +
                       " (integers, min <= max)");
    g.dims[i] = static_cast<int64_t>(ext[2 * i + 1] - ext[2 * i]) + 1;
  }
  if (!d.piece.count("Extent") || numbers(d, d.piece, "Extent", 6, "Piece") != ext)
    throw InputError(d.file + ": the piece's Extent differs from the WholeExtent; Skelflow reads one whole piece");
  if (const auto sp = numbers(d, d.image, "Spacing", 3, "ImageData"); !sp.empty()) {
    for (size_t i = 0; i < 3; ++i) {
      if (!(sp[i] > 0))
        throw InputError(d.file + ": ImageData Spacing of axis " + std::string(1, "xyz"[i]) + " is " +
                         text::format_double(sp[i], 17) + " (must be > 0)");
      g.spacing[i] = sp[i];
    }
    d.header.has_spacing = true;
  }
  if (const auto dir = numbers(d, d.image, "Direction", 9, "ImageData"); !dir.empty())
    std::copy(dir.begin(), dir.end(), g.direction.begin());
  Vec3 origin{0, 0, 0};
  if (const auto o = numbers(d, d.image, "Origin", 3, "ImageData"); !o.empty()) {
    origin = {o[0], o[1], o[2]};
    d.header.has_origin = true;
  }
  // Voxel (0,0,0) of the volume is extent index (i0, j0, k0).
  for (size_t r = 0; r < 3; ++r) {
    g.origin[r] = origin[r];
    for (size_t k = 0; k < 3; ++k) g.origin[r] += g.direction[r * 3 + k] * ext[2 * k] * g.spacing[k];
  }
  if (d.has_unit) {
    std::string u;
    for (const auto& w : text::split(d.unit, ' ')) {
      int64_t c = 0;
      if (text::trim(w).empty()) continue;
      if (!text::parse_int(text::trim(w), c) || c < 0 || c > 255) throw InputError(d.file + ": FieldData 'unit' is not a string array");
      if (c == 0) break;
      u += static_cast<char>(c);
    }
    for (char& c : u)
      if (c == '\n' || c == '\t') c = ' ';
    g.unit = volbytes::normalize_unit(text::trim(u));
    if (g.unit.empty()) g.unit = kDefaultUnit, d.has_unit = false;
    d.header.has_unit = d.has_unit;
  }
  d.header.dtype = d.stored;
  const std::string format = d.array.count("format") ? d.array["format"] : "ascii";
  d.header.details.push_back("array: " + d.array["Name"] + " (" + format +
                             (format == "appended" ? ", " + d.appended_encoding : "") + (d.compressed ? ", zlib" : "") + ")");
  return d;
}

// The voxel bytes of a binary block (header + data or header + compressed blocks) at `b[off..]`,
// decoded by the one VTK block decoder (io/vtk_xml_data.hpp). With dst == nullptr: checks the
// block's header against `need` and the bytes present (before the volume is allocated), copies nothing.
void unpack_block(const VtiDoc& d, const std::string& b, uint64_t off, char* dst, uint64_t need) {
  const vtk::Encoding enc{d.header_bytes == 8, d.big_endian, d.compressed};
  const vtk::BlockMessages m{d.file, "the voxel data", "WholeExtent and type"};
  if (dst) vtk::decode_block(b, off, enc, m, dst, need);
  else vtk::check_block(b, off, enc, m, need);
}

DataPtr read_vti(const fs::path& path, const VolumeReadOptions&) {
  std::string whole;
  const VtiDoc d = parse(path, &whole);
  volbytes::checked_bytes(d.file, d.header.grid.dims, volbytes::dtype_bytes(d.stored));  // sizes in range
  const std::string format = d.array.count("format") ? d.array.at("format") : "ascii";
  std::string bytes;
  uint64_t off = 0;
  if (format == "appended") {
    if (!d.has_appended) throw InputError(d.file + ": the array is 'appended' but the file has no <AppendedData>");
    int64_t o = 0;
    if (!d.array.count("offset") || !text::parse_int(d.array.at("offset"), o) || o < 0)
      throw InputError(d.file + ": the appended array has no valid offset");
    if (d.appended_encoding == "raw") {
      off = d.appended_begin + static_cast<uint64_t>(o);
      bytes = std::move(whole);
    } else if (d.appended_encoding == "base64") {
      const uint64_t b = d.appended_begin + static_cast<uint64_t>(o);
      if (b > whole.size()) throw InputError(d.file + ": the appended array's offset is past the end of the file");
      size_t e = whole.find('<', b);
      bytes = text::base64_decode(std::string_view(whole).substr(b, e == std::string::npos ? std::string::npos : e - b),
                                  d.file + ": appended data");
    } else {
      throw InputError(d.file + ": unsupported AppendedData encoding '" + d.appended_encoding + "' (raw, base64)");
    }
  } else if (format == "binary") {
    bytes = text::base64_decode(d.array_text, d.file + ": inline binary data");
  } else if (format == "ascii") {
    const uint64_t count = static_cast<uint64_t>(d.header.grid.voxel_count());
    volbytes::check_available(d.file, d.array_text.size() + 1, 2 * count, "the ascii voxel data");
    const bool native_big = std::endian::native == std::endian::big;
    return volbytes::decode(d.header.grid, d.stored, native_big, [&](char* dst, uint64_t) {
      const char* p = d.array_text.data();
      const char* end = p + d.array_text.size();
      const size_t w = volbytes::dtype_bytes(d.stored);
      for (uint64_t i = 0; i < count; ++i) {
        while (p < end && std::isspace(static_cast<unsigned char>(*p))) ++p;
        const char* q = p;
        while (q < end && !std::isspace(static_cast<unsigned char>(*q))) ++q;
        if (p == q || !volbytes::store_text_value(std::string_view(p, static_cast<size_t>(q - p)), d.stored, dst + i * w))
          throw InputError(d.file + ": ascii data value " + std::to_string(i) + " is missing or not a " + d.stored + " value");
        p = q;
      }
    });
  } else {
    throw InputError(d.file + ":" + std::to_string(d.array_line) + ": unsupported DataArray format '" + format +
                     "' (ascii, binary, appended)");
  }
  const uint64_t need = volbytes::checked_bytes(d.file, d.header.grid.dims, volbytes::dtype_bytes(d.stored));
  unpack_block(d, bytes, off, nullptr, need);  // sizes checked before allocating
  return volbytes::decode(d.header.grid, d.stored, d.big_endian,
                          [&](char* dst, uint64_t n) { unpack_block(d, bytes, off, dst, n); });
}

void put_u64(std::string& s, uint64_t v) {
  char b[8];
  std::memcpy(b, &v, 8);
  s.append(b, 8);
}

void write_vti(const fs::path& path, const DataObject& volume, const VolumeWriteOptions& o) {
  if (std::endian::native == std::endian::big) throw Error("VTI writer: big-endian hosts are not supported");
  const std::string shown = display_path(path).string();
  const Grid& g = volume_grid(volume, shown);
  const std::string dtype = volbytes::volume_dtype(volume);
  const std::string raw = volbytes::encode(volume, false);
  std::string block;
  const bool compress = o.compression > 0;
  if (!compress) {
    put_u64(block, raw.size());
    block += raw;
  } else {
    constexpr uint64_t bs = 1 << 20;
    const uint64_t nb = (raw.size() + bs - 1) / bs;
    std::vector<std::string> blocks(static_cast<size_t>(nb));
    for (uint64_t i = 0; i < nb; ++i) {
      const uint64_t n = std::min<uint64_t>(bs, raw.size() - i * bs);
      blocks[i] = volbytes::deflate(raw.data() + i * bs, n, o.compression, false);
    }
    put_u64(block, nb);
    put_u64(block, bs);
    put_u64(block, nb ? raw.size() - (nb - 1) * bs : 0);
    for (const auto& b : blocks) put_u64(block, b.size());
    for (const auto& b : blocks) block += b;
  }
  std::string ext;
  for (size_t i = 0; i < 3; ++i) ext += (i ? " 0 " : "0 ") + std::to_string(g.dims[i] - 1);
  std::string unit_codes;
  for (unsigned char c : g.unit) unit_codes += std::to_string(c) + " ";
  std::string s = "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\"";
  if (compress) s += " compressor=\"vtkZLibDataCompressor\"";
  s += ">\n  <ImageData WholeExtent=\"" + ext + "\" Origin=\"" + volbytes::join_numbers(g.origin.data(), 3) + "\" Spacing=\"" +
       volbytes::join_numbers(g.spacing.data(), 3) + "\" Direction=\"" + volbytes::join_numbers(g.direction.data(), 9) + "\">\n";
  s += "    <FieldData>\n      <Array type=\"String\" Name=\"unit\" NumberOfTuples=\"1\" format=\"ascii\">\n        " + unit_codes +
       "0\n      </Array>\n    </FieldData>\n";
  s += "    <Piece Extent=\"" + ext + "\">\n      <PointData Scalars=\"volume\">\n";
  s += "        <DataArray type=\"" + vtk_name(dtype) + "\" Name=\"volume\" format=\"appended\" offset=\"0\"/>\n";
  s += "      </PointData>\n      <CellData>\n      </CellData>\n    </Piece>\n  </ImageData>\n";
  s += "  <AppendedData encoding=\"raw\">\n   _";
  s += block;
  s += "\n  </AppendedData>\n</VTKFile>\n";
  write_file_atomically(path, s);
}

}  // namespace

VolumeFormat vti_volume_format() {
  VolumeFormat f;
  f.name = "VTK image data";
  f.extensions = {".vti"};
  f.sniff = [](std::string_view head) {
    return head.find("<VTKFile") != std::string_view::npos && head.find("\"ImageData\"") != std::string_view::npos;
  };
  f.read_header = [](const fs::path& p, const VolumeReadOptions&) { return parse(p).header; };
  f.read = read_vti;
  f.write = write_vti;
  return f;
}

}  // namespace skel::io
