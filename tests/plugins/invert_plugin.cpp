// A test plugin (loaded from SKELFLOW_PLUGIN_PATH by plugin_test): one real module,
// plugin_test.invert, registered only through SKELFLOW_PLUGIN.
#include <cstdint>

#include "skel/module.hpp"
#include "skel/plugin.hpp"
#include "skel/volume.hpp"

namespace {

struct InvertOptions {
  int64_t value = 1;  // what background voxels become
};

class Invert final : public skel::Module {
public:
  static skel::ModuleSpec spec() {
    return skel::ModuleSpec("plugin_test.invert", "Swaps a mask's object and background (test plugin)")
        .input<skel::VolumeU8>("mask", "binary mask (0 = background)")
        .output<skel::VolumeU8>("mask", "`value` where the input is 0, else 0")
        .param("value", &InvertOptions::value, "value of the voxels that were background")
        .range(1, 255)
        .details("Test plugin module. Memory: 2 bytes per voxel (input and output uint8).");
  }
  void run(skel::RunContext& ctx) override {
    const auto in = ctx.input<skel::VolumeU8>("mask");
    const auto opt = ctx.options<InvertOptions>();
    skel::VolumeU8 out(in->grid());
    for (int64_t i = 0; i < in->size(); ++i) out[i] = (*in)[i] == 0 ? static_cast<uint8_t>(opt.value) : 0;
    ctx.output("mask", std::move(out));
  }
};

}  // namespace

SKELFLOW_PLUGIN(Invert);
