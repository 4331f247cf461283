#pragma once
// An HDF5 file driver for files Skelflow writes: POSIX I/O like HDF5's "sec2" driver, except that
// after the first failed write (disk full, file size limit) the file is given up: later writes and
// the final truncation succeed without touching the disk. HDF5 1.10 cannot close a file whose
// close-time flush fails (the file stays half-open and H5_term_library crashes in H5F__close_cb at
// exit), so a write error must never reach H5Fclose; the file is a temporary that is removed anyway.
// The OS error of the first failed write is kept for the message.
#include <hdf5.h>

namespace skel::io::detail {

// A file access property list using the driver (caller closes it). Resets the recorded error.
hid_t safe_write_fapl();
// errno of the first write (or file creation) that failed since safe_write_fapl() was called, or 0. Caller holds the
// HDF5 mutex (one HDF5 call at a time), so one record is enough.
int first_write_errno();

}  // namespace skel::io::detail
