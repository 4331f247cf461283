#pragma once
// Out-of-core execution (issue 16, thesis ch. 5): volumes that live on disk (ChunkedVolume), the
// block layout a block-wise stage walks, and memory sizes ("2GiB"). See docs/architecture.md,
// "Out-of-core execution".
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "skel/data.hpp"
#include "skel/error.hpp"
#include "skel/interrupter.hpp"
#include "skel/volume.hpp"

namespace skel {

// Parses a memory size: a non-negative number with an optional unit B, KB, MB, GB, TB (powers of
// 1000) or KiB, MiB, GiB, TiB (powers of 1024), case-insensitive, optional space before the unit:
// "512MiB", "2GiB", "1.5GB", "1048576". Throws InputError "WHAT: ..." on anything else, on 0 and on
// sizes above 2^62 bytes.
uint64_t parse_byte_size(const std::string& text, const std::string& what);
// "1.5 GiB", "512 MiB", "300 B".
std::string format_byte_size(uint64_t bytes);

// Bytes per voxel of a volume type id ("volume.u8" -> 1); 0 for a type id that is no volume.
int64_t voxel_bytes(const std::string& type_id);

// Where the voxels of a ChunkedVolume live: boxes are read and written by position (x, y, z).
// Buffers are x-fastest, `size` voxels of the store's type. Implementations serialise themselves.
class VolumeStore {
public:
  virtual ~VolumeStore() = default;
  virtual void read(const Dims& begin, const Dims& size, void* out) const = 0;
  virtual void write(const Dims& begin, const Dims& size, const void* in) = 0;
  [[nodiscard]] virtual const std::filesystem::path& file() const = 0;
};

// Creates an empty store (every voxel 0) of `type_id` and `grid` at `file`, chunked by `chunk`
// (x, y, z). The store removes `file` when it is destroyed (scratch data).
using VolumeStoreFactory = std::function<std::shared_ptr<VolumeStore>(
    const std::filesystem::path& file, const std::string& type_id, const Grid& grid, const Dims& chunk)>;
// io registers the HDF5 scratch store; framework names no file format.
void register_volume_store_factory(VolumeStoreFactory factory);
// Throws Error when no factory is registered (a program that links no io family).
std::shared_ptr<VolumeStore> create_volume_store(const std::filesystem::path& file, const std::string& type_id,
                                                 const Grid& grid, const Dims& chunk);

// A volume on disk: the grid and voxel type of the Volume<T> it stands for (its type_id is that
// volume's, so ports and validation see no difference) and the store holding the voxels.
class ChunkedVolume final : public DataObject {
public:
  ChunkedVolume(Grid grid, std::string type_id, std::shared_ptr<VolumeStore> store);

  [[nodiscard]] const Grid& grid() const { return grid_; }
  [[nodiscard]] const Dims& dims() const { return grid_.dims; }
  [[nodiscard]] const std::shared_ptr<VolumeStore>& store() const { return store_; }
  // Bytes the voxels would take in memory.
  [[nodiscard]] uint64_t voxel_data_bytes() const {
    return static_cast<uint64_t>(grid_.voxel_count()) * static_cast<uint64_t>(voxel_bytes(type_));
  }

  // The box [begin, begin + size) as Volume<T> (T must be the voxel type); its grid has this
  // volume's spacing and the box's origin.
  template <class T>
  [[nodiscard]] Volume<T> read(const Dims& begin, const Dims& size) const {
    check_type<T>();
    check_box(begin, size);
    Volume<T> v = Volume<T>::uninitialized(box_grid(begin, size));
    if (v.size() > 0) store_->read(begin, size, v.data());
    return v;
  }
  // Writes `block` with its voxel (0,0,0) at `begin`.
  template <class T>
  void write(const Volume<T>& block, const Dims& begin) const {
    check_type<T>();
    check_box(begin, block.dims());
    if (block.size() > 0) store_->write(begin, block.dims(), block.data());
  }
  // Grid of the box [begin, begin + size).
  [[nodiscard]] Grid box_grid(const Dims& begin, const Dims& size) const;

  // DataObject: bytes() is what it holds in memory (nothing: the voxels are on disk).
  [[nodiscard]] std::string type_id() const override { return type_; }
  [[nodiscard]] uint64_t bytes() const override { return 0; }
  [[nodiscard]] std::string describe() const override;

private:
  template <class T>
  void check_type() const {
    if (type_ != VoxelTraits<T>::id)
      throw Error("volume on disk " + store_->file().string() + " holds " + type_ + ", not " + VoxelTraits<T>::id);
  }
  void check_box(const Dims& begin, const Dims& size) const;
  Grid grid_;
  std::string type_;
  std::shared_ptr<VolumeStore> store_;
};

// True when `data` is a volume on disk.
inline bool is_on_disk(const DataObject& data) { return dynamic_cast<const ChunkedVolume*>(&data) != nullptr; }
// Grid of an in-memory or on-disk volume; throws InputError naming `what` otherwise.
const Grid& any_volume_grid(const DataObject& data, const std::string& what);
// A ChunkedVolume loaded into memory as the Volume<T> of its type; any other object as it is.
DataPtr materialize(const DataPtr& data);

// The box [begin, begin + size) of an in-memory or on-disk volume of voxel type T (the box's grid
// has the volume's spacing and the box's origin). Throws InputError naming `what` when `data` is no
// volume of type T.
template <class T>
Volume<T> read_block(const DataObject& data, const Dims& begin, const Dims& size, const std::string& what) {
  if (auto* c = dynamic_cast<const ChunkedVolume*>(&data)) return c->read<T>(begin, size);
  auto* v = dynamic_cast<const Volume<T>*>(&data);
  if (!v) throw InputError(what + ": expected " + VoxelTraits<T>::id + ", got " + data.type_id());
  Grid g = v->grid();
  g.dims = size;
  g.origin = g.position(static_cast<double>(begin[0]), static_cast<double>(begin[1]), static_cast<double>(begin[2]));
  Volume<T> out = Volume<T>::uninitialized(g);
  for (int64_t z = 0; z < size[2]; ++z)
    for (int64_t y = 0; y < size[1]; ++y)
      if (size[0] > 0)
        std::memcpy(&out(0, y, z), &(*v)(begin[0], begin[1] + y, begin[2] + z), static_cast<size_t>(size[0]) * sizeof(T));
  return out;
}

// One block of a block layout: its interior box and the box with the halo (clipped to the grid).
struct Block {
  Dims index{0, 0, 0};                // block coordinates
  Dims begin{0, 0, 0}, size{0, 0, 0};  // interior
  Dims outer_begin{0, 0, 0}, outer_size{0, 0, 0};  // interior plus halo, inside the grid
};

// A grid cut into blocks of `block` voxels (the last block along an axis may be smaller).
struct BlockLayout {
  BlockLayout() = default;
  BlockLayout(const Dims& grid_dims, const Dims& block_dims, int64_t halo = 0);
  Dims dims{0, 0, 0}, block{1, 1, 1};
  int64_t halo = 0;
  [[nodiscard]] Dims count() const;  // blocks along x, y, z
  [[nodiscard]] int64_t total() const { const Dims c = count(); return c[0] * c[1] * c[2]; }
  [[nodiscard]] Block at(int64_t bx, int64_t by, int64_t bz) const;
};

// What a block-wise module gets from the executor under a memory budget (RunContext::blocks()).
struct BlockPlan {
  uint64_t memory_budget = 0;  // bytes
  Dims block{64, 64, 64};      // interior block shape (x, y, z)
  bool block_from_user = false;  // `block` was given (execution: block); else chosen from the budget
  Dims chunk{32, 32, 32};      // chunk shape of the scratch volumes (scratch_chunk(block))
  // Makes an empty on-disk volume for output port `port` (every voxel 0), removed when the run ends.
  std::function<std::shared_ptr<ChunkedVolume>(const std::string& port, const std::string& type_id, const Grid& grid)>
      scratch;
};

// The largest cube block (edge a multiple of 8, at least 16, at most the grid's largest side) whose
// blocks with halo, at `bytes_per_voxel`, take at most a quarter of `budget`.
Dims block_for_budget(uint64_t budget, int64_t halo, int64_t bytes_per_voxel, const Dims& grid_dims);

// The chunk shape of the scratch volumes of a stage with blocks of `block` voxels: per axis the
// largest divisor of the block's edge that is at most 32, or min(edge, 32) when that divisor is
// below 16 (edges such as 376 = 8 · 47 or 37: chunks of 8³ made a 1024³ EDT 5× slower). A block
// interior is then whole chunks (but at the grid's end), so skelflow-mpi's shared scratch volumes are
// written a chunk at a time (mpi/parallel_store.cpp).
Dims scratch_chunk(const Dims& block);

// Calls f(T{}) with the voxel type T of volume type id `type_id` ("volume.u8" -> uint8_t); throws
// InputError naming `what` for a type id that is no volume.
template <class F>
decltype(auto) visit_voxel_type(const std::string& type_id, const std::string& what, F&& f) {
  if (type_id == type_ids::volume_u8) return f(uint8_t{});
  if (type_id == type_ids::volume_u16) return f(uint16_t{});
  if (type_id == type_ids::volume_u32) return f(uint32_t{});
  if (type_id == type_ids::volume_u64) return f(uint64_t{});
  if (type_id == type_ids::volume_i32) return f(int32_t{});
  if (type_id == type_ids::volume_f32) return f(float{});
  if (type_id == type_ids::volume_f64) return f(double{});
  throw InputError(what + ": expected a volume, got " + type_id);
}

// Progress of a block-wise stage: "LABEL DONE/TOTAL blocks" through the interrupter, cancellation
// checked.
void report_blocks(const Interrupter& interrupter, const std::string& label, int64_t done, int64_t total);

// Calls f(block) for every block of `layout` in z, y, x order, reporting "LABEL k/n blocks" and
// checking cancellation between blocks.
template <class F>
void for_each_block(const BlockLayout& layout, const Interrupter& interrupter, const std::string& label, F&& f) {
  const Dims c = layout.count();
  const int64_t total = layout.total();
  int64_t done = 0;
  report_blocks(interrupter, label, 0, total);
  for (int64_t bz = 0; bz < c[2]; ++bz)
    for (int64_t by = 0; by < c[1]; ++by)
      for (int64_t bx = 0; bx < c[0]; ++bx) {
        f(layout.at(bx, by, bz));
        report_blocks(interrupter, label, ++done, total);
      }
}

}  // namespace skel
