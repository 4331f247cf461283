// Test-only modules (family "test"): sources, arithmetic with run counters, slow and failing nodes,
// and a file writer, to exercise the engine without the real modules.
#include <atomic>
#include <chrono>
#include <sstream>
#include <thread>

#include "skel/fs.hpp"
#include "skel/module.hpp"
#include "skel/table.hpp"
#include "skel/volume.hpp"
#include "test_modules.hpp"

namespace skel::test_counters {

std::atomic<int> g_source_runs{0}, g_scale_runs{0}, g_sum_runs{0};

namespace {

class Source final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test.source", "A volume filled with a ramp")
        .output<VolumeF32>("volume", "ramp volume")
        .param<std::vector<int64_t>>("size", {8, 8, 8}, "size [x, y, z]").length(3).range(1, 4096)
        .param<double>("offset", 0.0, "added to every voxel");
  }
  void run(RunContext& ctx) override {
    ++g_source_runs;
    auto s = ctx.param<std::vector<int64_t>>("size");
    VolumeF32 v(Dims{s[0], s[1], s[2]});
    const float off = static_cast<float>(ctx.param<double>("offset"));
    for (int64_t i = 0; i < v.size(); ++i) v[i] = static_cast<float>(i % 97) + off;
    ctx.output("volume", std::move(v));
  }
};

class Scale final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test.scale", "Multiplies a float volume by a factor")
        .input<VolumeF32>("volume", "input")
        .output<VolumeF32>("volume", "scaled")
        .param<double>("factor", 2.0, "factor").range(-100, 100)
        .param<int64_t>("sleep_ms", 0, "sleep before finishing (tests)").min(0);
  }
  void run(RunContext& ctx) override {
    ++g_scale_runs;
    auto in = ctx.input<VolumeF32>("volume");
    VolumeF32 out(*in);
    const float f = static_cast<float>(ctx.param<double>("factor"));
    for (auto& x : out) x *= f;
    std::this_thread::sleep_for(std::chrono::milliseconds(ctx.param<int64_t>("sleep_ms")));
    ctx.output("volume", std::move(out));
  }
};

class Sum final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test.sum", "Adds two volumes")
        .input<VolumeF32>("a", "first")
        .optional_input<VolumeF32>("b", "second (optional)")
        .output<VolumeF32>("volume", "a + b")
        .output<Table>("table", "the total");
  }
  void run(RunContext& ctx) override {
    ++g_sum_runs;
    auto a = ctx.input<VolumeF32>("a");
    auto b = ctx.optional_input<VolumeF32>("b");
    VolumeF32 out(*a);
    double total = 0;
    for (int64_t i = 0; i < out.size(); ++i) {
      if (b) out[i] += (*b)[i];
      total += out[i];
    }
    Table t;
    t.add("total", std::vector<double>{total});
    ctx.output("volume", std::move(out));
    ctx.output("table", std::move(t));
  }
};

class Slow final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test.slow", "Busy for `seconds`, checking for cancellation")
        .optional_input<VolumeF32>("volume", "passed through")
        .output<VolumeF32>("volume", "the input or a 1-voxel volume")
        .param<double>("seconds", 10.0, "how long").min(0);
  }
  void run(RunContext& ctx) override {
    const double secs = ctx.param<double>("seconds");
    auto t0 = std::chrono::steady_clock::now();
    for (;;) {
      double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (el >= secs) break;
      ctx.progress().check(el / secs);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    if (auto v = ctx.optional_input<VolumeF32>("volume")) ctx.output("volume", VolumeF32(*v));
    else ctx.output("volume", VolumeF32(Dims{1, 1, 1}));
  }
};

class Fail final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test.fail", "Always fails")
        .optional_input<VolumeF32>("volume", "ignored")
        .output<VolumeF32>("volume", "never produced")
        .param<bool>("input_error", false, "throw an InputError instead of an Error");
  }
  void run(RunContext& ctx) override {
    if (ctx.param<bool>("input_error")) throw InputError("the input is bad on purpose");
    throw Error("failed on purpose");
  }
};

class Write final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test.write", "Writes a volume's sum to a text file")
        .input<VolumeF32>("volume", "volume")
        .path("path", "", PathRole::Output, "output file");
  }
  void run(RunContext& ctx) override {
    auto v = ctx.input<VolumeF32>("volume");
    double s = 0;
    for (float x : *v) s += x;
    std::ostringstream o;
    o << s << "\n";
    write_file_atomically(ctx.output_path("path"), o.str());
  }
};

class U8Source final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test.mask", "A uint8 volume").output<VolumeU8>("mask", "all ones");
  }
  void run(RunContext& ctx) override { ctx.output("mask", VolumeU8(Dims{2, 2, 2}, 1)); }
};

SKEL_REGISTER_MODULE(Source);
SKEL_REGISTER_MODULE(Scale);
SKEL_REGISTER_MODULE(Sum);
SKEL_REGISTER_MODULE(Slow);
SKEL_REGISTER_MODULE(Fail);
SKEL_REGISTER_MODULE(Write);
SKEL_REGISTER_MODULE(U8Source);

}  // namespace
}  // namespace skel::test_counters
