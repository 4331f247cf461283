// The example's test: the function against a hand-counted volume, and the plugin's entry points.
#include <cstdio>
#include <cstring>

#include "skel/plugin.hpp"
#include "skel/volume.hpp"
#include "voxel_count.hpp"

extern "C" const char* skelflow_plugin_abi();
extern "C" void skelflow_plugin_register(skel::Registry&);

namespace {
int failures = 0;
void check(bool ok, const char* what) {
  if (!ok) {
    std::fprintf(stderr, "FAILED: %s\n", what);
    ++failures;
  }
}
}  // namespace

int main() {
  skel::VolumeU8 v(skel::Dims{4, 3, 2}, 0, {0.5, 0.5, 2.0});
  v[0] = 1;
  v[5] = 3;
  v[23] = 200;
  const auto c = example::count_voxels(v);
  check(c.voxels == 24, "24 voxels");
  check(c.object == 3, "3 object voxels");
  check(c.object_volume == 3 * 0.5 * 0.5 * 2.0, "object volume = 3 voxels of 0.5 unit³");
  check(example::count_voxels(v, {4.0}).object == 1, "min_value 4 keeps the 200");
  // The entry points SKELFLOW_PLUGIN wrote: the tag of this build equals the framework's (same
  // headers, same compiler), and registering adds the module with its parameter.
  check(std::strcmp(skelflow_plugin_abi(), skel::plugin_abi_tag().c_str()) == 0, "ABI tag matches the installed Skelflow");
  skel::Registry r;
  skelflow_plugin_register(r);
  const skel::ModuleSpec* s = r.find("example.voxel_count");
  check(s && s->find_param("min_value"), "example.voxel_count registered with min_value");
  if (failures == 0) std::printf("voxel_count_test: all passed\n");
  return failures == 0 ? 0 : 1;
}
