// example.voxel_count: an out-of-tree Skelflow module, loaded as a plugin (see README.md).
#include "voxel_count.hpp"

#include <cstdint>

#include "skel/module.hpp"
#include "skel/plugin.hpp"
#include "skel/table.hpp"
#include "skel/units.hpp"
#include "skel/volume.hpp"

namespace example {

VoxelCount count_voxels(const skel::DataObject& volume, const VoxelCountOptions& options) {
  return skel::visit_volume(volume, "input 'volume'", [&](const auto& v) {
    VoxelCount c;
    c.voxels = v.size();
    for (int64_t i = 0; i < c.voxels; ++i) c.object += static_cast<double>(v[i]) >= options.min_value ? 1 : 0;
    const auto& s = v.spacing();
    c.object_volume = static_cast<double>(c.object) * s[0] * s[1] * s[2];
    c.unit = v.unit();
    return c;
  });
}

namespace {

class VoxelCountModule final : public skel::Module {
public:
  static skel::ModuleSpec spec() {
    return skel::ModuleSpec("example.voxel_count", "Counts the voxels of an object and its physical volume")
        .add_input("volume", skel::all_volume_types(), "any volume; object voxels are those >= min_value", true)
        .output<skel::Table>("counts",
                             "one row: voxels, object_voxels, object_fraction, object_volume (input unit³)")
        .param("min_value", &VoxelCountOptions::min_value, "smallest value of an object voxel")
        .details("Counts the voxels whose value is at least `min_value` and their physical volume "
                 "(count × voxel volume, in the input's unit cubed). Memory: the input only, and "
                 "0 bytes per voxel besides (one pass, no copy).");
  }
  void run(skel::RunContext& ctx) override {
    const VoxelCount c = count_voxels(*ctx.input_data("volume"), ctx.options<VoxelCountOptions>());
    skel::Table t;
    t.add("voxels", std::vector<int64_t>{c.voxels});
    t.add("object_voxels", std::vector<int64_t>{c.object});
    t.add("object_fraction", std::vector<double>{c.voxels ? static_cast<double>(c.object) / static_cast<double>(c.voxels) : 0.0});
    t.add("object_volume", std::vector<double>{c.object_volume}, skel::units::power(c.unit, 3));
    ctx.output("counts", std::move(t));
  }
};

}  // namespace
}  // namespace example

// The plugin's entry points: its ABI tag and the list of its modules.
SKELFLOW_PLUGIN(example::VoxelCountModule);
