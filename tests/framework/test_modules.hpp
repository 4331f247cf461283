#pragma once
#include <atomic>

namespace skel::test_counters {
// How many times each test module ran (caching tests).
extern std::atomic<int> g_source_runs, g_scale_runs, g_sum_runs;
}  // namespace skel::test_counters
