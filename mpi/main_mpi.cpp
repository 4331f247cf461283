// skelflow-mpi: the skelflow command line on every rank of an MPI job (SPMD). Every rank parses and
// runs the same pipeline; block-wise stages that support it split their blocks over the ranks and
// share their scratch volumes (parallel HDF5); rank 0 prints, writes the outputs and the report.
// See docs/architecture.md, "Running on several processes", and README, "Running on a cluster".
#include <mpi.h>

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <memory>

#include "cli.hpp"
#include "mpi_communicator.hpp"

int main(int argc, char** argv) {
  // Serialized: the executor runs stages on worker threads, one stage at a time under a memory
  // budget, so MPI (and parallel HDF5) are called by one thread at a time, not always the main one.
  int provided = 0;
  if (MPI_Init_thread(&argc, &argv, MPI_THREAD_SERIALIZED, &provided) != MPI_SUCCESS) {
    std::fprintf(stderr, "skelflow-mpi: MPI_Init_thread failed\n");
    return 1;
  }
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (provided < MPI_THREAD_SERIALIZED) {
    if (rank == 0)
      std::fprintf(stderr, "skelflow-mpi: this MPI library does not allow calls from several threads one at a time "
                           "(MPI_THREAD_SERIALIZED); it provides level %d\n", provided);
    MPI_Finalize();
    return 1;
  }
  int rc = 1;
  {
    skel::set_communicator(std::make_shared<skel::mpi::MpiCommunicator>());
    skel::mpi::register_parallel_scratch_store();
    // Rank 0 reports; the others are silent (their errors reach rank 0 through agree_outcome) unless
    // SKELFLOW_MPI_ALL_OUTPUT=1.
    const char* all = std::getenv("SKELFLOW_MPI_ALL_OUTPUT");
    if (rank != 0 && !(all && *all == '1')) {
      const int null = ::open("/dev/null", O_WRONLY);
      if (null >= 0) {
        std::fflush(stdout);
        std::fflush(stderr);
        ::dup2(null, 1);
        ::dup2(null, 2);
        ::close(null);
      }
    }
    rc = skelflow_main(argc, argv);
    std::cout.flush();
    std::fflush(nullptr);
    skel::set_communicator(nullptr);
  }
  // The exit status of the job is the highest of the ranks' (they agree on success or failure).
  int worst = rc;
  MPI_Allreduce(&rc, &worst, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  MPI_Finalize();
  return worst;
}
