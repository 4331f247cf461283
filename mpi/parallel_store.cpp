// Scratch volumes shared by every rank: one HDF5 file per volume, opened by all ranks through MPI-IO
// (parallel HDF5, libhdf5_openmpi), chunked (chunks that divide the stage's blocks, skel::scratch_chunk),
// uncompressed, allocated at creation (H5D_ALLOC_TIME_EARLY, not filled: a new file reads 0); ranks
// read and write their blocks independently, chunk by chunk (see read/write below: one contiguous
// access per chunk instead of one per row). HDF5 bypasses its chunk cache for files open for writing
// over MPI-IO, so two ranks writing disjoint voxels of one chunk do not overwrite each other's.
// Creating and closing the file are collective: they happen in the same order on every rank because
// every rank runs the same stages.
#include <hdf5.h>
#include <mpi.h>

#include <chrono>
#include <filesystem>
#include <cstring>
#include <mutex>
#include <vector>

#include "io/hdf5_volume.hpp"
#include "mpi_communicator.hpp"
#include "skel/distributed.hpp"
#include "skel/out_of_core.hpp"
#include "skel/resume_io.hpp"

namespace skel::mpi {

namespace fs = std::filesystem;

namespace {

std::mutex& store_mutex() {
  static std::mutex m;
  return m;
}

hid_t native_type(const std::string& type_id) {
  if (type_id == type_ids::volume_u8) return H5T_NATIVE_UINT8;
  if (type_id == type_ids::volume_u16) return H5T_NATIVE_UINT16;
  if (type_id == type_ids::volume_u32) return H5T_NATIVE_UINT32;
  if (type_id == type_ids::volume_u64) return H5T_NATIVE_UINT64;
  if (type_id == type_ids::volume_i32) return H5T_NATIVE_INT32;
  if (type_id == type_ids::volume_f32) return H5T_NATIVE_FLOAT;
  if (type_id == type_ids::volume_f64) return H5T_NATIVE_DOUBLE;
  throw Error("parallel scratch volume: '" + type_id + "' is not a volume type");
}

class ParallelScratchStore final : public VolumeStore {
public:
  ParallelScratchStore(const fs::path& file, const std::string& type_id, const Grid& grid, const Dims& chunk)
      : file_(file), type_(native_type(type_id)), dims_(grid.dims), elem_(H5Tget_size(type_)) {
    grid.validate();
    std::lock_guard lock(store_mutex());
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
    H5Pset_fapl_mpio(fapl, MPI_COMM_WORLD, MPI_INFO_NULL);
    file_id_ = H5Fcreate(file_.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
    H5Pclose(fapl);
    if (file_id_ < 0) throw Error("cannot create the shared scratch file " + file_.string() + " (parallel HDF5)");
    const hsize_t dims[3] = {static_cast<hsize_t>(grid.dims[2]), static_cast<hsize_t>(grid.dims[1]),
                             static_cast<hsize_t>(grid.dims[0])};
    hsize_t chunks[3];
    for (int k = 0; k < 3; ++k) {
      chunk_[k] = std::max<int64_t>(1, std::min(chunk[k], std::max<int64_t>(1, grid.dims[k])));
      chunks[2 - k] = static_cast<hsize_t>(chunk_[k]);
    }
    const hid_t space = H5Screate_simple(3, dims, nullptr);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, 3, chunks);
    H5Pset_alloc_time(dcpl, H5D_ALLOC_TIME_EARLY);
    // No fill pass (it wrote every byte once more, collectively): the file is new, so the chunks
    // allocated at creation are read as 0 until written (holes of a new file; the MPI-IO driver
    // reads 0 past the end of the file).
    H5Pset_fill_time(dcpl, H5D_FILL_TIME_NEVER);
    dset_ = H5Dcreate2(file_id_, "/volume", type_, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    H5Pclose(dcpl);
    H5Sclose(space);
    if (dset_ < 0) {
      H5Fclose(file_id_);
      if (communicator().rank() == 0) fs::remove(file_);
      throw Error("cannot create the dataset of the shared scratch file " + file_.string() + " (parallel HDF5)");
    }
  }
  ~ParallelScratchStore() override {
    // Closing is collective: every rank closes its stores in the same order. When a rank has failed
    // out of step (it waits in agree_outcome), the handles are left to the process's end instead.
    bool in_step = true;
    try {
      sync_ranks();
    } catch (...) {
      in_step = false;
    }
    std::lock_guard lock(store_mutex());
    if (in_step) {
      H5Dclose(dset_);
      H5Fclose(file_id_);
    }
    if (communicator().rank() == 0) {
      std::error_code ec;
      fs::remove(file_, ec);
    }
  }
  // Both go chunk by chunk, each chunk's part as one contiguous run of the file where it can be:
  // independent parallel HDF5 I/O turns a selection into one MPI-IO access per run that is
  // contiguous both in the file and in the memory buffer, so a box read straight into a block
  // buffer costs one pread per row of 32 voxels (2 million system calls per rank for the stages of a
  // 256³ volume). A read takes the chunk's whole rows and columns for the box's planes (contiguous in
  // the chunk) into a buffer of that shape and copies the box's part out. A write that covers the
  // chunk's whole rows and columns packs its planes and writes them in one run; a write covering
  // part of a chunk's rows cannot be widened (the rest of the chunk may be another rank's) and goes
  // row by row: block-wise stages write their blocks' interiors, which are whole chunks when the
  // block is a multiple of the chunk.
  void read(const Dims& begin, const Dims& size, void* out) const override {
    std::lock_guard lock(store_mutex());
    const IoTimer timer(*this);
    for_each_chunk(begin, size, [&](const Dims& ib, const Dims& is, const Dims& cb, const Dims& cs) {
      const Dims rb{cb[0], cb[1], ib[2]}, rs{cs[0], cs[1], is[2]};
      buffer_.resize(static_cast<size_t>(rs[0] * rs[1] * rs[2]) * elem_);
      transfer(rb, rs, rs, {0, 0, 0}, buffer_.data(), false);
      copy_box(buffer_.data(), rs, {ib[0] - rb[0], ib[1] - rb[1], 0}, static_cast<char*>(out), size,
               {ib[0] - begin[0], ib[1] - begin[1], ib[2] - begin[2]}, is);
    });
  }
  void write(const Dims& begin, const Dims& size, const void* in) override {
    std::lock_guard lock(store_mutex());
    const IoTimer timer(*this);
    for_each_chunk(begin, size, [&](const Dims& ib, const Dims& is, const Dims& /*cb*/, const Dims& cs) {
      const Dims off{ib[0] - begin[0], ib[1] - begin[1], ib[2] - begin[2]};
      if (is[0] == cs[0] && is[1] == cs[1] && (is[0] != size[0] || is[1] != size[1])) {
        buffer_.resize(static_cast<size_t>(is[0] * is[1] * is[2]) * elem_);
        copy_box(static_cast<const char*>(in), size, off, buffer_.data(), is, {0, 0, 0}, is);
        transfer(ib, is, is, {0, 0, 0}, buffer_.data(), true);
      } else {
        // Whole planes of the chunk already contiguous in `in`, or part of the chunk's rows.
        transfer(ib, is, size, off, const_cast<void*>(in), true);
      }
    });
  }
  [[nodiscard]] const fs::path& file() const override { return file_; }
  // Data and metadata to disk (collective: every rank flushes the volume at the same point, the
  // executor's checkpoint of the stage that made it), so that the file is readable after kill -9.
  void flush() const {
    std::lock_guard lock(store_mutex());
    if (H5Fflush(file_id_, H5F_SCOPE_GLOBAL) < 0) throw Error("cannot flush the shared scratch file " + file_.string());
  }

private:
  // f(box begin, box size, chunk begin, chunk size) for every chunk the box [begin, begin + size)
  // meets, the box clipped to the chunk and the chunk clipped to the grid.
  template <class F>
  void for_each_chunk(const Dims& begin, const Dims& size, F&& f) const {
    if (size[0] <= 0 || size[1] <= 0 || size[2] <= 0) return;
    Dims lo, hi;
    for (int k = 0; k < 3; ++k) {
      lo[k] = begin[k] / chunk_[k];
      hi[k] = (begin[k] + size[k] - 1) / chunk_[k];
    }
    for (int64_t cz = lo[2]; cz <= hi[2]; ++cz)
      for (int64_t cy = lo[1]; cy <= hi[1]; ++cy)
        for (int64_t cx = lo[0]; cx <= hi[0]; ++cx) {
          const Dims c{cx, cy, cz};
          Dims cb, cs, ib, is;
          for (int k = 0; k < 3; ++k) {
            cb[k] = c[k] * chunk_[k];
            cs[k] = std::min(chunk_[k], dims_[k] - cb[k]);
            ib[k] = std::max(begin[k], cb[k]);
            is[k] = std::min(begin[k] + size[k], cb[k] + cs[k]) - ib[k];
          }
          f(ib, is, cb, cs);
        }
  }
  // Copies the box `n` at `from_off` in `from` (dims `from_dims`) to `to_off` in `to` (`to_dims`).
  void copy_box(const char* from, const Dims& from_dims, const Dims& from_off, char* to, const Dims& to_dims,
                const Dims& to_off, const Dims& n) const {
    const auto row = static_cast<size_t>(n[0]) * elem_;
    for (int64_t z = 0; z < n[2]; ++z)
      for (int64_t y = 0; y < n[1]; ++y)
        std::memcpy(to + static_cast<size_t>(((to_off[2] + z) * to_dims[1] + to_off[1] + y) * to_dims[0] + to_off[0]) * elem_,
                    from + static_cast<size_t>(((from_off[2] + z) * from_dims[1] + from_off[1] + y) * from_dims[0] + from_off[0]) * elem_,
                    row);
  }
  // Reads or writes the file box [fb, fb + n) from or to the box at `mo` of the buffer `mem` (dims `md`).
  void transfer(const Dims& fb, const Dims& n, const Dims& md, const Dims& mo, void* mem, bool write) const {
    const hsize_t fstart[3] = {static_cast<hsize_t>(fb[2]), static_cast<hsize_t>(fb[1]), static_cast<hsize_t>(fb[0])};
    const hsize_t count[3] = {static_cast<hsize_t>(n[2]), static_cast<hsize_t>(n[1]), static_cast<hsize_t>(n[0])};
    const hsize_t mdims[3] = {static_cast<hsize_t>(md[2]), static_cast<hsize_t>(md[1]), static_cast<hsize_t>(md[0])};
    const hsize_t mstart[3] = {static_cast<hsize_t>(mo[2]), static_cast<hsize_t>(mo[1]), static_cast<hsize_t>(mo[0])};
    const Space file(H5Dget_space(dset_)), memory(H5Screate_simple(3, mdims, nullptr));
    if (file.id < 0 || memory.id < 0 || H5Sselect_hyperslab(file.id, H5S_SELECT_SET, fstart, nullptr, count, nullptr) < 0 ||
        H5Sselect_hyperslab(memory.id, H5S_SELECT_SET, mstart, nullptr, count, nullptr) < 0)
      throw Error("shared scratch file " + file_.string() + ": invalid box");
    (write ? bytes_written_ : bytes_read_) += static_cast<uint64_t>(n[0] * n[1] * n[2]) * elem_;
    if (write) {
      if (H5Dwrite(dset_, type_, memory.id, file.id, H5P_DEFAULT, mem) < 0)
        throw Error("cannot write the shared scratch file " + file_.string() + " (disk full?)");
    } else if (H5Dread(dset_, type_, memory.id, file.id, H5P_DEFAULT, mem) < 0) {
      throw Error("cannot read the shared scratch file " + file_.string());
    }
  }
  // Adds the time and bytes of one read or write to the rank's statistics (run report).
  struct IoTimer {
    const ParallelScratchStore& store;
    std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
    explicit IoTimer(const ParallelScratchStore& s) : store(s) { store.bytes_read_ = store.bytes_written_ = 0; }
    ~IoTimer() {
      detail::add_io(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), store.bytes_read_,
                     store.bytes_written_);
    }
    IoTimer(const IoTimer&) = delete;
    IoTimer& operator=(const IoTimer&) = delete;
  };
  struct Space {
    hid_t id;
    explicit Space(hid_t i) : id(i) {}
    ~Space() {
      if (id >= 0) H5Sclose(id);
    }
    Space(const Space&) = delete;
    Space& operator=(const Space&) = delete;
  };
  fs::path file_;
  hid_t type_;
  Dims dims_, chunk_;
  size_t elem_;
  mutable std::vector<char> buffer_;
  mutable uint64_t bytes_read_ = 0, bytes_written_ = 0;  // of the read or write in progress
  hid_t file_id_ = -1, dset_ = -1;
};

}  // namespace

void register_parallel_scratch_store() {
  // --resume: the executor flushes the volumes of a finished stage; a shared one flushes collectively.
  // Kept volumes are opened again by io's (serial, read-only) open on every rank.
  if (const ResumeVolumeIo* serial = resume_volume_io()) {
    ResumeVolumeIo io = *serial;
    io.flush = [serial_flush = serial->flush](const VolumeStore& store) {
      if (const auto* p = dynamic_cast<const ParallelScratchStore*>(&store)) p->flush();
      else serial_flush(store);
    };
    register_resume_volume_io(std::move(io));
  }
  register_volume_store_factory([](const fs::path& file, const std::string& type_id, const Grid& grid,
                                   const Dims& chunk) -> std::shared_ptr<VolumeStore> {
    if (!distributing()) return io::create_scratch_store(file, type_id, grid, chunk);
    // One file for all ranks: rank 0's name (each rank's executor names its temporaries after its pid).
    const fs::path shared = broadcast_from_root(file.string());
    return std::make_shared<ParallelScratchStore>(shared, type_id, grid, chunk);
  });
}

}  // namespace skel::mpi
