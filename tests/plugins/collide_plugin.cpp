// A plugin whose module name is SKEL_COLLIDE_NAME: another plugin's module (plugin_test.invert) or a
// built-in one (test.mask); it must be refused as a whole, naming both files.
#include "skel/module.hpp"
#include "skel/plugin.hpp"
#include "skel/volume.hpp"

namespace {
class Other final : public skel::Module {
public:
  static skel::ModuleSpec spec() {
    return skel::ModuleSpec(SKEL_COLLIDE_NAME, "collides").output<skel::VolumeU8>("mask", "nothing");
  }
  void run(skel::RunContext&) override {}
};
class Fine final : public skel::Module {
public:
  static skel::ModuleSpec spec() { return skel::ModuleSpec(SKEL_COLLIDE_NAME "_not", "would not collide"); }
  void run(skel::RunContext&) override {}
};
}  // namespace

SKELFLOW_PLUGIN(Fine, Other);
