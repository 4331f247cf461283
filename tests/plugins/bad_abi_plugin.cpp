// A plugin built "for another Skelflow": its ABI tag differs, so its register function must never
// run (it would add plugin_test.bad_abi).
#include "skel/module.hpp"

namespace {
class Bad final : public skel::Module {
public:
  static skel::ModuleSpec spec() { return skel::ModuleSpec("plugin_test.bad_abi", "must never be registered"); }
  void run(skel::RunContext&) override {}
};
}  // namespace

extern "C" __attribute__((visibility("default"))) const char* skelflow_plugin_abi() {
  return "skelflow 0.0.1 plugin-api 0; layout ModuleSpec=1/1";
}
extern "C" __attribute__((visibility("default"))) void skelflow_plugin_register(skel::Registry& r) {
  r.add(Bad::spec(), [] { return std::unique_ptr<skel::Module>(std::make_unique<Bad>()); });
}
