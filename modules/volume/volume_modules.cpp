// Modules of the `volume` family: generic volume utilities.
#include "skel/module.hpp"
#include "volume/convert.hpp"
#include "volume/names.hpp"

namespace skel::volume {
namespace {

class ConvertModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::convert, "Convert a volume to another voxel type")
        .input<AnyVolume>("input", "volume of any voxel type")
        .add_output("output", all_volume_types(), "converted volume, same grid")
        .choice("dtype", {"uint8", "uint16", "uint32", "int32", "float32", "float64"}, "float32",
                "target voxel type")
        .param("mode", &ConvertOptions::mode,
                "clamp: cast and clamp to the target range; rescale: map [min, max] of the input "
                "onto the target range ([0, 1] for float types)")
        .details("Memory: input plus output (1–8 bytes per voxel each). Floating-point values "
                 "are rounded to the nearest integer when the target is an integer type; NaN "
                 "becomes 0.");
  }
  void run(RunContext& ctx) override {
    auto o = ctx.options<ConvertOptions>();
    o.dtype = ctx.param<std::string>("dtype");
    ctx.output("output", convert_volume_type(*ctx.input_data("input"), o));
  }
};
SKEL_REGISTER_MODULE(ConvertModule);

class CropModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::crop, "Cut a box out of a volume, keeping physical positions")
        .input<AnyVolume>("input", "volume of any voxel type")
        .add_output("output", all_volume_types(), "the cropped volume (same voxel type)")
        .param<std::vector<int64_t>>("begin", {0, 0, 0}, "first voxel of the box (x, y, z)")
        .length(3)
        .min(0)
        .unit("voxels")
        .param<std::vector<int64_t>>("size", {64, 64, 64}, "box size (x, y, z), clipped to the volume")
        .length(3)
        .min(1)
        .unit("voxels")
        .details("The output origin is moved so that every voxel keeps its physical position. The box is "
                 "clipped to the volume; a box entirely outside it is an error naming the parameter. "
                 "Memory: the output only (same bytes per voxel as the input).");
  }
  void run(RunContext& ctx) override {
    auto b = ctx.param<std::vector<int64_t>>("begin");
    auto s = ctx.param<std::vector<int64_t>>("size");
    ctx.output("output", crop_volume(*ctx.input_data("input"), {b[0], b[1], b[2]}, {s[0], s[1], s[2]}));
  }
};
SKEL_REGISTER_MODULE(CropModule);

}  // namespace
}  // namespace skel::volume
