#pragma once
// Parallel loops with an explicit thread budget. Results of algorithms must not depend on the thread
// count: split work into independent ranges (z-slabs, lines) and combine deterministically.
#include <algorithm>
#include <cstdint>
#include <functional>

namespace skel {

// Number of hardware threads; `threads <= 0` in the functions below means "all of them".
int hardware_threads();
int effective_threads(int threads);

// Calls body(begin, end) on disjoint sub-ranges of [begin, end) covering it, on up to `threads`
// threads. `grain` is the minimum sub-range length. Blocks until all are done; exceptions thrown by
// the body are rethrown (the first one).
void parallel_for(int64_t begin, int64_t end, int threads,
                  const std::function<void(int64_t, int64_t)>& body, int64_t grain = 1);

// Like parallel_for, but splits [begin, end) into exactly `chunks` contiguous pieces (the last ones
// may be empty) and passes the chunk number: body(chunk, begin, end). For per-chunk partial results
// combined in chunk order, which keeps results identical for any thread count if `chunks` is fixed.
void parallel_chunks(int64_t begin, int64_t end, int64_t chunks, int threads,
                     const std::function<void(int64_t, int64_t, int64_t)>& body);

}  // namespace skel
