// A plugin whose second module's spec throws while it registers (range() before any parameter):
// refused as a whole, the first module is not registered either.
#include "skel/module.hpp"
#include "skel/plugin.hpp"

namespace {
class Good final : public skel::Module {
public:
  static skel::ModuleSpec spec() { return skel::ModuleSpec("plugin_test.good_half", "fine on its own"); }
  void run(skel::RunContext&) override {}
};
class Broken final : public skel::Module {
public:
  static skel::ModuleSpec spec() { return skel::ModuleSpec("plugin_test.broken", "broken spec").range(0, 1); }
  void run(skel::RunContext&) override {}
};
}  // namespace

SKELFLOW_PLUGIN(Good, Broken);
