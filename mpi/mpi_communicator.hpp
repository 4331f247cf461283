#pragma once
// The MPI transport of skel::Communicator (skel/distributed.hpp) for skelflow-mpi: MPI_COMM_WORLD.
// Only this folder includes mpi.h.
#include <string>
#include <vector>

#include "skel/distributed.hpp"

namespace skel::mpi {

class MpiCommunicator final : public Communicator {
public:
  MpiCommunicator();  // MPI must be initialised
  [[nodiscard]] int rank() const override { return rank_; }
  [[nodiscard]] int size() const override { return size_; }
  std::vector<std::string> allgather(const std::string& bytes) override;
  [[nodiscard]] bool reports_ranks() const override { return true; }

private:
  int rank_ = 0, size_ = 1;
};

// The store factory of skelflow-mpi (installed over io's): inside a DistributedStage with several
// ranks, one HDF5 file per volume opened by every rank through MPI-IO (parallel HDF5), its name
// chosen by rank 0; otherwise io's serial scratch store (private to the rank).
void register_parallel_scratch_store();

}  // namespace skel::mpi
