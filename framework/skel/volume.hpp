#pragma once
// Volume<T>: a 3D image stored x-fastest (C-order [z][y][x], index = x + nx*(y + ny*z)), 64-bit
// dims, spacing and origin in the grid's physical unit (µm when the file names none), reported as
// (x, y, z).
// No virtual call per voxel: voxel access is inline on a contiguous buffer.
#include <array>
#include <cstdint>
#include <cstring>
#include <memory>
#include <sstream>
#include <string>
#include <type_traits>

#include "skel/data.hpp"
#include "skel/error.hpp"

namespace skel {

// Asks the kernel for transparent huge pages on a large fresh buffer (>= 8 MiB; the 2 MiB-aligned
// interior) before its first touch: otherwise the first write to every 4 KiB page costs a page
// fault, a large part of any memory-bound pass over a new volume (worse in virtual machines).
void advise_huge_pages(void* data, size_t bytes);
// Gives the whole 4 KiB pages inside [data, data + bytes) back to the kernel: their contents are
// lost, the range stays owned and reads as zeros when touched again. Returns the bytes released.
size_t release_pages(void* data, size_t bytes);

using Dims = std::array<int64_t, 3>;   // (nx, ny, nz)
using Vec3 = std::array<double, 3>;    // (x, y, z) in physical units

template <class T> struct VoxelTraits;
template <> struct VoxelTraits<uint8_t> { static constexpr const char* id = "volume.u8"; static constexpr const char* name = "uint8"; };
template <> struct VoxelTraits<uint16_t> { static constexpr const char* id = "volume.u16"; static constexpr const char* name = "uint16"; };
template <> struct VoxelTraits<uint32_t> { static constexpr const char* id = "volume.u32"; static constexpr const char* name = "uint32"; };
template <> struct VoxelTraits<uint64_t> { static constexpr const char* id = "volume.u64"; static constexpr const char* name = "uint64"; };
template <> struct VoxelTraits<int32_t> { static constexpr const char* id = "volume.i32"; static constexpr const char* name = "int32"; };
template <> struct VoxelTraits<float> { static constexpr const char* id = "volume.f32"; static constexpr const char* name = "float32"; };
template <> struct VoxelTraits<double> { static constexpr const char* id = "volume.f64"; static constexpr const char* name = "float64"; };

// The unit of a volume or graph whose file names none.
inline constexpr const char* kDefaultUnit = "µm";
// 3x3 direction cosines, row-major: column k is the physical direction of voxel axis k (x, y, z),
// as in ITK/MetaImage/NRRD/NIfTI. Identity for axis-aligned data.
using Direction = std::array<double, 9>;
inline constexpr Direction kIdentityDirection{1, 0, 0, 0, 1, 0, 0, 0, 1};

// Geometry shared by every volume: dims, spacing, origin, the physical unit of spacing and origin,
// and the direction cosines (physical position of voxel i = origin + direction * (i .* spacing);
// the algorithms work in the axis-aligned frame, the direction travels to the outputs).
struct Grid {
  Grid() = default;
  explicit Grid(Dims d, Vec3 s = {1.0, 1.0, 1.0}, Vec3 o = {0.0, 0.0, 0.0}, std::string u = kDefaultUnit)
      : dims(d), spacing(s), origin(o), unit(std::move(u)) {}
  Dims dims{0, 0, 0};
  Vec3 spacing{1.0, 1.0, 1.0};
  Vec3 origin{0.0, 0.0, 0.0};
  std::string unit{kDefaultUnit};        // physical unit of spacing and origin ("µm", "mm", "nm", ...)
  Direction direction{kIdentityDirection};

  [[nodiscard]] int64_t voxel_count() const { return dims[0] * dims[1] * dims[2]; }
  [[nodiscard]] int64_t index(int64_t x, int64_t y, int64_t z) const {
    return x + dims[0] * (y + dims[1] * z);
  }
  [[nodiscard]] bool contains(int64_t x, int64_t y, int64_t z) const {
    return x >= 0 && y >= 0 && z >= 0 && x < dims[0] && y < dims[1] && z < dims[2];
  }
  // Physical position of a voxel centre.
  [[nodiscard]] Vec3 position(double x, double y, double z) const {
    return {origin[0] + x * spacing[0], origin[1] + y * spacing[1], origin[2] + z * spacing[2]};
  }
  // Throws InputError unless dims >= 0 and spacing > 0 (names the offending axis).
  void validate() const;
  bool operator==(const Grid&) const = default;
};

// A non-owning view of a block of a (possibly larger) volume: pointer to voxel (0,0,0) of the
// block, block dims, strides in elements, and the block's offset in the global grid. Block-wise and
// out-of-core algorithms take views, so the whole-volume case is just one block.
template <class T>
struct VolumeView {
  T* data = nullptr;
  Dims dims{0, 0, 0};
  std::array<int64_t, 3> strides{1, 0, 0};  // elements between x, y, z neighbours
  Dims offset{0, 0, 0};                     // position of this block in the global grid

  [[nodiscard]] T& operator()(int64_t x, int64_t y, int64_t z) const {
    return data[x * strides[0] + y * strides[1] + z * strides[2]];
  }
  [[nodiscard]] int64_t voxel_count() const { return dims[0] * dims[1] * dims[2]; }
};

template <class T>
class Volume final : public DataObject {
  static_assert(std::is_arithmetic_v<T>, "Volume voxel type must be arithmetic");

public:
  using value_type = T;

  Volume() = default;
  // Allocates dims voxels, all set to `fill`.
  explicit Volume(Dims dims, T fill = T{}, Vec3 spacing = {1, 1, 1}, Vec3 origin = {0, 0, 0})
      : Volume(Grid{dims, spacing, origin}, fill) {}
  explicit Volume(const Grid& grid, T fill = T{}) : grid_(grid) {
    allocate();
    std::fill_n(data_.get(), size(), fill);
  }
  // A volume on memory that someone else owns (a NumPy array in the Python module): `data` holds
  // grid.voxel_count() voxels, x fastest, and stays valid while `owner` lives; the volume keeps
  // `owner` alive and never frees `data` itself. Copies of it own a fresh buffer as usual.
  static Volume wrap(const Grid& grid, T* data, std::shared_ptr<const void> owner) {
    grid.validate();
    if (grid.voxel_count() > 0 && data == nullptr) throw Error("Volume::wrap: no memory for a non-empty grid");
    Volume v;
    v.grid_ = grid;
    v.data_ = Buffer(data, BufferDeleter{std::move(owner)});
    return v;
  }
  // Whether the voxels live in memory owned by someone else (see wrap()).
  [[nodiscard]] bool wraps_external_memory() const { return data_.get_deleter().owner != nullptr; }
  // Allocates without initialising the voxels (for outputs every voxel of which is written).
  static Volume uninitialized(const Grid& grid) {
    Volume v;
    v.grid_ = grid;
    v.allocate();
    return v;
  }
  Volume(const Volume& o) : grid_(o.grid_) {
    allocate();
    if (size() > 0) std::memcpy(data_.get(), o.data_.get(), size() * sizeof(T));
  }
  Volume& operator=(const Volume& o) {
    if (this != &o) { Volume tmp(o); *this = std::move(tmp); }
    return *this;
  }
  Volume(Volume&&) noexcept = default;
  Volume& operator=(Volume&&) noexcept = default;

  [[nodiscard]] const Grid& grid() const { return grid_; }
  [[nodiscard]] const Dims& dims() const { return grid_.dims; }
  [[nodiscard]] const Vec3& spacing() const { return grid_.spacing; }
  [[nodiscard]] const Vec3& origin() const { return grid_.origin; }
  void set_spacing(const Vec3& s) { grid_.spacing = s; }
  void set_origin(const Vec3& o) { grid_.origin = o; }
  [[nodiscard]] const std::string& unit() const { return grid_.unit; }
  void set_unit(std::string u) { grid_.unit = std::move(u); }
  void set_direction(const Direction& d) { grid_.direction = d; }
  // Takes spacing, origin, unit and direction from `g`; the dims stay.
  void copy_geometry(const Grid& g) {
    const Dims d = grid_.dims;
    grid_ = g;
    grid_.dims = d;
  }
  [[nodiscard]] int64_t nx() const { return grid_.dims[0]; }
  [[nodiscard]] int64_t ny() const { return grid_.dims[1]; }
  [[nodiscard]] int64_t nz() const { return grid_.dims[2]; }
  [[nodiscard]] int64_t size() const { return grid_.voxel_count(); }

  [[nodiscard]] T* data() { return data_.get(); }
  [[nodiscard]] const T* data() const { return data_.get(); }
  [[nodiscard]] T* begin() { return data_.get(); }
  [[nodiscard]] T* end() { return data_.get() + size(); }
  [[nodiscard]] const T* begin() const { return data_.get(); }
  [[nodiscard]] const T* end() const { return data_.get() + size(); }
  [[nodiscard]] T& operator[](int64_t i) { return data_[i]; }
  [[nodiscard]] const T& operator[](int64_t i) const { return data_[i]; }
  [[nodiscard]] int64_t index(int64_t x, int64_t y, int64_t z) const { return grid_.index(x, y, z); }
  [[nodiscard]] T& operator()(int64_t x, int64_t y, int64_t z) { return data_[index(x, y, z)]; }
  [[nodiscard]] const T& operator()(int64_t x, int64_t y, int64_t z) const { return data_[index(x, y, z)]; }
  // Value at (x, y, z), or `outside` when the position is not in the grid.
  [[nodiscard]] T at_or(int64_t x, int64_t y, int64_t z, T outside) const {
    return grid_.contains(x, y, z) ? data_[index(x, y, z)] : outside;
  }

  [[nodiscard]] VolumeView<T> view() { return {data(), dims(), {1, nx(), nx() * ny()}, {0, 0, 0}}; }
  [[nodiscard]] VolumeView<const T> view() const {
    return {data(), dims(), {1, nx(), nx() * ny()}, {0, 0, 0}};
  }

  bool operator==(const Volume& o) const {
    return grid_ == o.grid_ && (size() == 0 || std::memcmp(data(), o.data(), size() * sizeof(T)) == 0);
  }

  // DataObject
  [[nodiscard]] std::string type_id() const override { return VoxelTraits<T>::id; }
  [[nodiscard]] uint64_t bytes() const override { return static_cast<uint64_t>(size()) * sizeof(T); }
  [[nodiscard]] std::string physical_unit() const override { return grid_.unit; }
  [[nodiscard]] std::string describe() const override {
    std::ostringstream s;
    s << type_id() << " " << nx() << "x" << ny() << "x" << nz() << " (x,y,z), spacing "
      << grid_.spacing[0] << " " << grid_.spacing[1] << " " << grid_.spacing[2] << ", origin "
      << grid_.origin[0] << " " << grid_.origin[1] << " " << grid_.origin[2] << " " << grid_.unit;
    return s.str();
  }

private:
  // Frees a buffer the volume allocated, or only drops the reference to the owner of wrapped memory.
  struct BufferDeleter {
    std::shared_ptr<const void> owner;
    void operator()(T* p) const {
      if (!owner) delete[] p;
    }
  };
  using Buffer = std::unique_ptr<T[], BufferDeleter>;
  void allocate() {
    grid_.validate();
    data_ = Buffer(size() > 0 ? new T[static_cast<size_t>(size())] : nullptr, BufferDeleter{});
    if (size() > 0) advise_huge_pages(data_.get(), static_cast<size_t>(size()) * sizeof(T));
  }
  Grid grid_;
  Buffer data_;
};

using VolumeU8 = Volume<uint8_t>;
using VolumeU16 = Volume<uint16_t>;
using VolumeU32 = Volume<uint32_t>;
using VolumeU64 = Volume<uint64_t>;  // voxel indices (feature transforms) on grids > 2^32 voxels
using VolumeI32 = Volume<int32_t>;
using VolumeF32 = Volume<float>;
using VolumeF64 = Volume<double>;

// Calls f(const Volume<T>&) with the concrete volume type behind `data`; throws InputError naming
// `what` if `data` is not a volume.
template <class F>
decltype(auto) visit_volume(const DataObject& data, const std::string& what, F&& f) {
  if (auto* v = dynamic_cast<const VolumeU8*>(&data)) return f(*v);
  if (auto* v = dynamic_cast<const VolumeU16*>(&data)) return f(*v);
  if (auto* v = dynamic_cast<const VolumeU32*>(&data)) return f(*v);
  if (auto* v = dynamic_cast<const VolumeU64*>(&data)) return f(*v);
  if (auto* v = dynamic_cast<const VolumeI32*>(&data)) return f(*v);
  if (auto* v = dynamic_cast<const VolumeF32*>(&data)) return f(*v);
  if (auto* v = dynamic_cast<const VolumeF64*>(&data)) return f(*v);
  throw InputError(what + ": expected a volume, got " + data.type_id());
}

// Grid of any volume behind `data` (throws InputError naming `what` if it is not a volume).
const Grid& volume_grid(const DataObject& data, const std::string& what);

// Converts any volume to Volume<U> by static_cast per voxel (no rescaling); same grid.
template <class U>
Volume<U> convert_volume(const DataObject& data, const std::string& what) {
  return visit_volume(data, what, [](const auto& v) {
    Volume<U> out = Volume<U>::uninitialized(v.grid());
    const auto* s = v.data();
    U* d = out.data();
    for (int64_t i = 0, n = v.size(); i < n; ++i) d[i] = static_cast<U>(s[i]);
    return out;
  });
}

}  // namespace skel
