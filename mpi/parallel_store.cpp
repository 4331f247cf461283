// Scratch volumes shared by every rank: one HDF5 file per volume, opened by all ranks through MPI-IO
// (parallel HDF5, libhdf5_openmpi), chunked, uncompressed, allocated at creation
// (H5D_ALLOC_TIME_EARLY, filled with 0); ranks read and write their blocks independently. HDF5
// bypasses its chunk cache for files open for writing over MPI-IO, so two ranks writing disjoint
// voxels of one chunk do not overwrite each other's. Creating and closing the file are collective:
// they happen in the same order on every rank because every rank runs the same stages.
#include <hdf5.h>
#include <mpi.h>

#include <filesystem>
#include <mutex>

#include "io/hdf5_volume.hpp"
#include "mpi_communicator.hpp"
#include "skel/distributed.hpp"
#include "skel/out_of_core.hpp"

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
      : file_(file), type_(native_type(type_id)) {
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
    for (int k = 0; k < 3; ++k)
      chunks[k] = static_cast<hsize_t>(std::max<int64_t>(1, std::min(chunk[2 - k], std::max<int64_t>(1, grid.dims[2 - k]))));
    const hid_t space = H5Screate_simple(3, dims, nullptr);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, 3, chunks);
    H5Pset_alloc_time(dcpl, H5D_ALLOC_TIME_EARLY);
    H5Pset_fill_time(dcpl, H5D_FILL_TIME_ALLOC);
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
  void read(const Dims& begin, const Dims& size, void* out) const override {
    std::lock_guard lock(store_mutex());
    const Selection s(dset_, begin, size);
    if (H5Dread(dset_, type_, s.mem, s.file, H5P_DEFAULT, out) < 0)
      throw Error("cannot read the shared scratch file " + file_.string());
  }
  void write(const Dims& begin, const Dims& size, const void* in) override {
    std::lock_guard lock(store_mutex());
    const Selection s(dset_, begin, size);
    if (H5Dwrite(dset_, type_, s.mem, s.file, H5P_DEFAULT, in) < 0)
      throw Error("cannot write the shared scratch file " + file_.string() + " (disk full?)");
  }
  [[nodiscard]] const fs::path& file() const override { return file_; }

private:
  struct Selection {
    hid_t mem = -1, file = -1;
    Selection(hid_t dset, const Dims& begin, const Dims& size) {
      const hsize_t start[3] = {static_cast<hsize_t>(begin[2]), static_cast<hsize_t>(begin[1]), static_cast<hsize_t>(begin[0])};
      const hsize_t count[3] = {static_cast<hsize_t>(size[2]), static_cast<hsize_t>(size[1]), static_cast<hsize_t>(size[0])};
      file = H5Dget_space(dset);
      if (file < 0 || H5Sselect_hyperslab(file, H5S_SELECT_SET, start, nullptr, count, nullptr) < 0) {
        if (file >= 0) H5Sclose(file);
        throw Error("shared scratch file: invalid box");
      }
      mem = H5Screate_simple(3, count, nullptr);
    }
    ~Selection() {
      if (mem >= 0) H5Sclose(mem);
      if (file >= 0) H5Sclose(file);
    }
    Selection(const Selection&) = delete;
    Selection& operator=(const Selection&) = delete;
  };
  fs::path file_;
  hid_t type_;
  hid_t file_id_ = -1, dset_ = -1;
};

}  // namespace

void register_parallel_scratch_store() {
  register_volume_store_factory([](const fs::path& file, const std::string& type_id, const Grid& grid,
                                   const Dims& chunk) -> std::shared_ptr<VolumeStore> {
    if (!distributing()) return io::create_scratch_store(file, type_id, grid, chunk);
    // One file for all ranks: rank 0's name (each rank's executor names its temporaries after its pid).
    const fs::path shared = broadcast_from_root(file.string());
    return std::make_shared<ParallelScratchStore>(shared, type_id, grid, chunk);
  });
}

}  // namespace skel::mpi
