// HDF5 as a VolumeFormat (the reader and writer themselves are in hdf5_volume.cpp).
#include "io/hdf5_volume.hpp"
#include "io/volume_format.hpp"

namespace skel::io {

VolumeFormat hdf5_volume_format() {
  VolumeFormat f;
  f.name = "HDF5";
  f.extensions = {".h5", ".hdf5", ".he5"};
  f.sniff = [](std::string_view head) { return head.substr(0, 8) == std::string_view("\x89HDF\r\n\x1a\n", 8); };
  f.read_header = [](const std::filesystem::path& p, const VolumeReadOptions& o) {
    const VolumeInfo i = read_volume_info(p, o.dataset.empty() ? "/volume" : o.dataset);
    VolumeHeader h;
    h.grid = Grid(i.dims, i.spacing, i.origin, i.unit);
    h.dtype = i.dtype;
    h.has_spacing = i.has_spacing;
    h.has_origin = i.has_origin;
    h.has_unit = i.has_unit;
    if (i.chunks[0])
      h.details.push_back("chunks: " + std::to_string(i.chunks[0]) + "x" + std::to_string(i.chunks[1]) + "x" +
                          std::to_string(i.chunks[2]));
    for (const auto& fl : i.filters) h.details.push_back("filter: " + fl);
    return h;
  };
  f.read = [](const std::filesystem::path& p, const VolumeReadOptions& o) {
    return read_volume(p, o.dataset.empty() ? "/volume" : o.dataset, o.threads);
  };
  f.read_box = [](const std::filesystem::path& p, const VolumeReadOptions& o, Dims begin, Dims size) -> DataPtr {
    const std::string ds = o.dataset.empty() ? "/volume" : o.dataset;
    const std::string t = read_volume_info(p, ds).dtype;
    if (t == "uint8") return std::make_shared<VolumeU8>(read_box<uint8_t>(p, ds, begin, size));
    if (t == "uint16") return std::make_shared<VolumeU16>(read_box<uint16_t>(p, ds, begin, size));
    if (t == "uint32") return std::make_shared<VolumeU32>(read_box<uint32_t>(p, ds, begin, size));
    if (t == "uint64") return std::make_shared<VolumeU64>(read_box<uint64_t>(p, ds, begin, size));
    if (t == "int8" || t == "int16" || t == "int32") return std::make_shared<VolumeI32>(read_box<int32_t>(p, ds, begin, size));
    if (t == "float32") return std::make_shared<VolumeF32>(read_box<float>(p, ds, begin, size));
    return std::make_shared<VolumeF64>(read_box<double>(p, ds, begin, size));
  };
  f.write = [](const std::filesystem::path& p, const DataObject& v, const VolumeWriteOptions& o) {
    WriteOptions w;
    w.compression = o.compression;
    w.threads = o.threads;
    write_volume(p, v, o.dataset.empty() ? "/volume" : o.dataset, w);
  };
  f.write_boxes = [](const std::filesystem::path& p, const VolumeBoxSource& v, const VolumeWriteOptions& o) {
    WriteOptions w;
    w.compression = o.compression;
    w.threads = o.threads;
    write_volume_boxes(p, v, o.dataset.empty() ? "/volume" : o.dataset, w);
  };
  f.describe = [](const std::filesystem::path& p) { return describe_file(p); };
  return f;
}

}  // namespace skel::io
