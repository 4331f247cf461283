#include "mpi_communicator.hpp"

#include <mpi.h>

#include <climits>
#include <cstdint>

namespace skel::mpi {

namespace {
void check(int rc, const char* what) {
  if (rc == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int len = 0;
  MPI_Error_string(rc, text, &len);
  throw Error(std::string("MPI ") + what + ": " + std::string(text, static_cast<size_t>(len)));
}
}  // namespace

MpiCommunicator::MpiCommunicator() {
  check(MPI_Comm_rank(MPI_COMM_WORLD, &rank_), "MPI_Comm_rank");
  check(MPI_Comm_size(MPI_COMM_WORLD, &size_), "MPI_Comm_size");
}

std::vector<std::string> MpiCommunicator::allgather(const std::string& bytes) {
  // Sizes first, then the bytes (MPI counts are int: a buffer of 2 GiB or more is refused; the
  // exchanges carry statuses, union lists and statistics, never voxels).
  if (bytes.size() > static_cast<size_t>(INT_MAX))
    throw Error("rank exchange: " + std::to_string(bytes.size()) + " bytes is more than one MPI message may carry");
  const auto n = static_cast<size_t>(size_);
  std::vector<int64_t> sizes(n);
  const int64_t mine = static_cast<int64_t>(bytes.size());
  check(MPI_Allgather(&mine, 1, MPI_INT64_T, sizes.data(), 1, MPI_INT64_T, MPI_COMM_WORLD), "MPI_Allgather");
  std::vector<int> counts(n), displs(n);
  int64_t total = 0;
  for (size_t r = 0; r < n; ++r) {
    if (total + sizes[r] > INT_MAX) throw Error("rank exchange: more than 2 GiB in one exchange");
    counts[r] = static_cast<int>(sizes[r]);
    displs[r] = static_cast<int>(total);
    total += sizes[r];
  }
  std::string all(static_cast<size_t>(total), '\0');
  check(MPI_Allgatherv(bytes.data(), static_cast<int>(bytes.size()), MPI_BYTE, all.data(), counts.data(), displs.data(),
                       MPI_BYTE, MPI_COMM_WORLD),
        "MPI_Allgatherv");
  std::vector<std::string> out(n);
  for (size_t r = 0; r < n; ++r) out[r] = all.substr(static_cast<size_t>(displs[r]), static_cast<size_t>(counts[r]));
  return out;
}

}  // namespace skel::mpi
