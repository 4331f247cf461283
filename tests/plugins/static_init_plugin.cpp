// A plugin that registers its module from a static initialiser (SKEL_REGISTER_MODULE), which would
// run before the ABI check: the loader refuses it and the module never reaches the registry.
#include "skel/module.hpp"
#include "skel/plugin.hpp"

namespace {
class Early final : public skel::Module {
public:
  static skel::ModuleSpec spec() { return skel::ModuleSpec("plugin_test.early", "registers too early"); }
  void run(skel::RunContext&) override {}
};
SKEL_REGISTER_MODULE(Early);
}  // namespace

SKELFLOW_PLUGIN(Early);
