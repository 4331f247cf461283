// Executor overhead: 1000 trivial nodes (a chain and a wide fan-out), YAML parse + validate + run,
// against the floor of calling the same module's run() directly through run_module.
#include <cstdio>
#include <string>

#include "common/bench_util.hpp"
#include "skel/executor.hpp"
#include "skel/mask.hpp"
#include "skel/pipeline.hpp"
#include "skel/run_module.hpp"
#include "skel/volume.hpp"

using namespace skel;

namespace {
class Tiny final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("bench.tiny", "Adds a constant to a 1-voxel volume")
        .optional_input<VolumeF32>("volume", "input")
        .output<VolumeF32>("volume", "output")
        .param<double>("add", 1.0, "constant");
  }
  void run(RunContext& ctx) override {
    VolumeF32 v(Dims{1, 1, 1});
    if (auto in = ctx.optional_input<VolumeF32>("volume")) v[0] = (*in)[0];
    v[0] += static_cast<float>(ctx.param<double>("add"));
    ctx.output("volume", std::move(v));
  }
};
SKEL_REGISTER_MODULE(Tiny);

std::string make_yaml(int n, bool chain) {
  std::string y = "skelflow: 1\nnodes:\n  n0: {module: bench.tiny}\n";
  for (int i = 1; i < n; ++i) {
    const int src = chain ? i - 1 : 0;
    y += "  n" + std::to_string(i) + ": {module: bench.tiny, inputs: {volume: n" + std::to_string(src) +
         ".volume}, params: {add: " + std::to_string(i) + ".5}}\n";
  }
  return y;
}
}  // namespace

int main() {
  const int n = 1000;
  std::printf("## Engine: executor overhead (%d trivial nodes)\n\n", n);
  std::printf("Peer: the same module called %d times directly through `run_module` (no graph, no scheduling) — "
              "the floor. Overhead per node = (pipeline time − direct time) / %d.\n\n", n, n);
  std::printf("| graph | threads | parse+validate (ms) | run (ms) | cached re-run (ms) | direct calls (ms) | overhead per node (µs) |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  const double direct = bench::best_of(3, [&] {
    DataPtr prev;
    for (int i = 0; i < n; ++i) {
      std::map<std::string, DataPtr> in;
      if (prev) in["volume"] = prev;
      prev = run_module("bench.tiny", in, {{"add", 1.5}}, {.threads = 1}).data("volume");
    }
  });
  for (bool chain : {true, false}) {
    const std::string yaml = make_yaml(n, chain);
    for (int threads : {1, 2}) {
      Pipeline p;
      const double parse = bench::best_of(3, [&] {
        p = Pipeline::parse(yaml, "bench.yaml");
        validate_or_throw(p);
      });
      const double run = bench::best_of(3, [&] {
        Executor ex;
        ExecOptions o;
        o.threads = threads;
        ex.run(p, o);
      });
      Executor ex;
      ExecOptions o;
      o.threads = threads;
      o.keep_outputs = true;
      ex.run(p, o);
      const double cached = bench::best_of(3, [&] { ex.run(p, o); });
      std::printf("| %s | %d | %.1f | %.1f | %.1f | %.1f | %.1f |\n", chain ? "chain" : "fan-out", threads,
                  parse * 1e3, run * 1e3, cached * 1e3, direct * 1e3, (run - direct) / n * 1e6);
    }
  }

  // The value check of mask inputs (0/1, else a warning) rides on the conversion pass; the floor is the
  // conversion without the check.
  {
    VolumeU16 v({256, 256, 256}, 0);
    for (int64_t i = 0; i < v.size(); i += 3) v[i] = 1;
    auto u8 = std::make_shared<VolumeU8>(v.grid(), uint8_t{0});
    std::string w;
    volatile uint8_t sink = 0;  // keeps the conversions from being optimised away
    const double plain = bench::best_of(3, [&] { sink = sink + to_mask(v, "m")[v.size() / 2]; });
    const double checked = bench::best_of(3, [&] { sink = sink + to_mask(v, "m", &w)[v.size() / 2]; });
    const double u8_check = bench::best_of(3, [&] { sink = sink + (*shared_mask(u8, "m", &w))[v.size() / 2]; });
    std::printf("\n## Engine: mask value check (%lld voxels)\n\n", static_cast<long long>(v.size()));
    std::printf("| conversion | ms | ratio to plain uint16 → mask |\n|---|---|---|\n");
    std::printf("| uint16 → mask, no check | %.1f | 1.00 |\n", plain * 1e3);
    std::printf("| uint16 → mask, with the 0/1 check | %.1f | %.2f |\n", checked * 1e3, checked / plain);
    std::printf("| uint8 mask, check only (no copy) | %.1f | %.2f |\n", u8_check * 1e3, u8_check / plain);
  }
  std::printf("\nPeak RSS %.0f MiB.\n", bench::peak_rss_mib());
  return 0;
}
