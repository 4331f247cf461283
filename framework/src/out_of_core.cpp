#include "skel/out_of_core.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <mutex>
#include <sstream>
#include <thread>

#include "skel/resume_io.hpp"
#include "skel/text.hpp"

namespace skel {

// ---------------------------------------------------------------- sizes
uint64_t parse_byte_size(const std::string& text, const std::string& what) {
  const std::string t = text::trim(text);
  size_t i = 0;
  while (i < t.size() && (std::isdigit(static_cast<unsigned char>(t[i])) || t[i] == '.')) ++i;
  const std::string number = t.substr(0, i);
  std::string unit = text::trim(t.substr(i));
  const std::string help = " (expected a size such as 512MiB, 2GiB or 1.5GB)";
  double value = 0;
  if (number.empty() || !text::parse_double(number, value) || !std::isfinite(value) || value < 0)
    throw InputError(what + ": '" + text + "' is not a memory size" + help);
  unit = text::to_lower(unit);
  double scale = 0;
  if (unit.empty() || unit == "b") scale = 1;
  else if (unit == "kb") scale = 1e3;
  else if (unit == "mb") scale = 1e6;
  else if (unit == "gb") scale = 1e9;
  else if (unit == "tb") scale = 1e12;
  else if (unit == "kib") scale = 1024.0;
  else if (unit == "mib") scale = 1024.0 * 1024.0;
  else if (unit == "gib") scale = 1024.0 * 1024.0 * 1024.0;
  else if (unit == "tib") scale = 1024.0 * 1024.0 * 1024.0 * 1024.0;
  else throw InputError(what + ": unknown unit '" + text::trim(t.substr(i)) + "' in '" + text + "'" + help);
  const double bytes = std::floor(value * scale);
  if (bytes < 1) throw InputError(what + ": '" + text + "' is no memory at all" + help);
  if (bytes > 4.6e18) throw InputError(what + ": '" + text + "' is larger than any machine's memory");
  return static_cast<uint64_t>(bytes);
}

std::string format_byte_size(uint64_t bytes) {
  static const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double v = static_cast<double>(bytes);
  int u = 0;
  while (v >= 1024.0 && u < 4) {
    v /= 1024.0;
    ++u;
  }
  std::ostringstream s;
  if (u == 0) s << bytes << " B";
  else s << text::format_double(std::round(v * 10.0) / 10.0, 6) << " " << units[u];
  return s.str();
}

int64_t voxel_bytes(const std::string& t) {
  if (t == type_ids::volume_u8) return 1;
  if (t == type_ids::volume_u16) return 2;
  if (t == type_ids::volume_u32 || t == type_ids::volume_i32 || t == type_ids::volume_f32) return 4;
  if (t == type_ids::volume_u64 || t == type_ids::volume_f64) return 8;
  return 0;
}

// ---------------------------------------------------------------- stores
namespace {
std::mutex& factory_mutex() {
  static std::mutex m;
  return m;
}
VolumeStoreFactory& factory() {
  static VolumeStoreFactory f;
  return f;
}
}  // namespace

void register_volume_store_factory(VolumeStoreFactory f) {
  std::lock_guard lock(factory_mutex());
  factory() = std::move(f);
}

std::shared_ptr<VolumeStore> create_volume_store(const std::filesystem::path& file, const std::string& type_id,
                                                 const Grid& grid, const Dims& chunk) {
  VolumeStoreFactory f;
  {
    std::lock_guard lock(factory_mutex());
    f = factory();
  }
  if (!f) throw Error("no on-disk volume store is linked into this program (the io family registers it)");
  return f(file, type_id, grid, chunk);
}

// ---------------------------------------------------------------- ChunkedVolume
ChunkedVolume::ChunkedVolume(Grid grid, std::string type_id, std::shared_ptr<VolumeStore> store)
    : grid_(std::move(grid)), type_(std::move(type_id)), store_(std::move(store)) {
  if (voxel_bytes(type_) == 0) throw Error("ChunkedVolume: '" + type_ + "' is not a volume type");
  if (!store_) throw Error("ChunkedVolume: no store");
}

Grid ChunkedVolume::box_grid(const Dims& begin, const Dims& size) const {
  Grid g = grid_;
  g.dims = size;
  g.origin = grid_.position(static_cast<double>(begin[0]), static_cast<double>(begin[1]), static_cast<double>(begin[2]));
  return g;
}

void ChunkedVolume::check_box(const Dims& begin, const Dims& size) const {
  for (int k = 0; k < 3; ++k)
    if (begin[k] < 0 || size[k] < 0 || begin[k] + size[k] > grid_.dims[k])
      throw Error("box at (" + std::to_string(begin[0]) + ", " + std::to_string(begin[1]) + ", " +
                  std::to_string(begin[2]) + ") of " + std::to_string(size[0]) + "x" + std::to_string(size[1]) + "x" +
                  std::to_string(size[2]) + " voxels is outside the volume on disk " + store_->file().string());
}

std::string ChunkedVolume::describe() const {
  std::ostringstream s;
  s << type_ << " " << grid_.dims[0] << "x" << grid_.dims[1] << "x" << grid_.dims[2] << " (x,y,z) on disk ("
    << store_->file().string() << "), spacing " << grid_.spacing[0] << " " << grid_.spacing[1] << " "
    << grid_.spacing[2] << ", origin " << grid_.origin[0] << " " << grid_.origin[1] << " " << grid_.origin[2];
  return s.str();
}

const Grid& any_volume_grid(const DataObject& data, const std::string& what) {
  if (auto* c = dynamic_cast<const ChunkedVolume*>(&data)) return c->grid();
  return volume_grid(data, what);
}

namespace {
template <class T>
DataPtr load(const ChunkedVolume& c) {
  return std::make_shared<Volume<T>>(c.read<T>({0, 0, 0}, c.dims()));
}
}  // namespace

DataPtr materialize(const DataPtr& data) {
  auto* c = dynamic_cast<const ChunkedVolume*>(data.get());
  if (!c) return data;
  const std::string t = c->type_id();
  DataPtr v;
  if (t == type_ids::volume_u8) v = load<uint8_t>(*c);
  else if (t == type_ids::volume_u16) v = load<uint16_t>(*c);
  else if (t == type_ids::volume_u32) v = load<uint32_t>(*c);
  else if (t == type_ids::volume_u64) v = load<uint64_t>(*c);
  else if (t == type_ids::volume_i32) v = load<int32_t>(*c);
  else if (t == type_ids::volume_f32) v = load<float>(*c);
  else v = load<double>(*c);
  // The loaded volume has the whole grid (its origin included).
  return v;
}

// ---------------------------------------------------------------- blocks
BlockLayout::BlockLayout(const Dims& grid_dims, const Dims& block_dims, int64_t h)
    : dims(grid_dims), block(block_dims), halo(h) {
  for (int k = 0; k < 3; ++k)
    if (block[k] < 1) throw InputError("block: every side must be at least 1 voxel");
  if (halo < 0) throw Error("BlockLayout: negative halo");
}

Dims BlockLayout::count() const {
  Dims c{};
  for (int k = 0; k < 3; ++k) c[k] = dims[k] == 0 ? 0 : (dims[k] + block[k] - 1) / block[k];
  return c;
}

Block BlockLayout::at(int64_t bx, int64_t by, int64_t bz) const {
  Block b;
  b.index = {bx, by, bz};
  const int64_t idx[3] = {bx, by, bz};
  for (int k = 0; k < 3; ++k) {
    b.begin[k] = idx[k] * block[k];
    b.size[k] = std::min(block[k], dims[k] - b.begin[k]);
    b.outer_begin[k] = std::max<int64_t>(0, b.begin[k] - halo);
    b.outer_size[k] = std::min(dims[k], b.begin[k] + b.size[k] + halo) - b.outer_begin[k];
  }
  return b;
}

Dims block_for_budget(uint64_t budget, int64_t halo, int64_t bytes_per_voxel, const Dims& grid_dims) {
  const double quarter = static_cast<double>(budget) / 4.0;
  const int64_t bpv = std::max<int64_t>(1, bytes_per_voxel);
  const int64_t largest = std::max<int64_t>({grid_dims[0], grid_dims[1], grid_dims[2], 16});
  int64_t edge = 16;
  for (int64_t e = 16; e <= largest + 7; e += 8) {
    const double side = static_cast<double>(e + 2 * halo);
    if (side * side * side * static_cast<double>(bpv) > quarter) break;
    edge = e;
  }
  return {edge, edge, edge};
}

Dims scratch_chunk(const Dims& block) {
  Dims c{1, 1, 1};
  for (int k = 0; k < 3; ++k) {
    const int64_t edge = std::max<int64_t>(1, block[k]);
    int64_t d = std::min<int64_t>(edge, 32);
    while (edge % d != 0) --d;
    c[k] = d >= 16 || d == edge ? d : std::min<int64_t>(edge, 32);
  }
  return c;
}

void report_blocks(const Interrupter& interrupter, const std::string& label, int64_t done, int64_t total) {
  if (done > 0 && test_block_delay_ms() > 0) std::this_thread::sleep_for(std::chrono::milliseconds(test_block_delay_ms()));
  interrupter.check(total > 0 ? static_cast<double>(done) / static_cast<double>(total) : 1.0);
  interrupter.note(label + " " + std::to_string(done) + "/" + std::to_string(total) + " blocks");
}

}  // namespace skel
