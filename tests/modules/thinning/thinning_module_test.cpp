// thinning.doht and analysis.topology through the module API (run_module).
#include <gtest/gtest.h>

#include <memory>

#include "shapes.hpp"
#include "skel/run_module.hpp"
#include "skel/table.hpp"
#include "thinning/thinning.hpp"
#include "analysis/topology.hpp"
#include "thinning/local_topology.hpp"

using namespace skel::thinning;
using namespace skel::analysis;

namespace skel {
namespace {

TEST(ThinningModule, MatchesLibraryAndReportsTable) {
  const VolumeU8 m = test::random_blobs(24, 4, 0.48, 2);
  const VolumeU32 d = test::chamfer345(m);
  auto mask = std::make_shared<VolumeU8>(m);
  auto prio = std::make_shared<VolumeU32>(d);
  for (const char* variant : {"basic", "smooth"}) {
    const ModuleRunResult r = run_module("thinning.doht", {{"mask", mask}, {"priority", prio}},
                                         {{"variant", ParamValue(std::string(variant))},
                                          {"end_point_length", ParamValue(int64_t{3})}},
                                         {.threads = 2});
    ThinningOptions o;
    o.variant = parse_enum<ThinningVariant>(variant, "variant");
    o.end_point_length = 3;
    o.threads = 1;
    const ThinningResult lib = thin_doht(m, d, nullptr, o);
    EXPECT_TRUE(*r.get<VolumeU8>("skeleton") == lib.skeleton) << variant;
    const auto t = r.get<Table>("table");
    EXPECT_EQ(t->ints("skeleton_voxels").at(0), lib.stats.skeleton_voxels);
    EXPECT_EQ(t->ints("object_voxels").at(0), lib.stats.object_voxels);
    EXPECT_EQ(t->ints("stuck_components").at(0), 0);
    EXPECT_TRUE(r.warnings.empty());
  }
}

TEST(ThinningModule, WarnsAboutLockedConfigurations) {
  const VolumeU8 m = test::bing_house(1);
  auto mask = std::make_shared<VolumeU8>(m);
  auto prio = std::make_shared<VolumeU32>(test::chamfer345(m));
  auto locked = std::make_shared<VolumeU8>(m.dims(), 0);
  const ModuleRunResult r =
      run_module("thinning.doht", {{"mask", mask}, {"priority", prio}, {"locked", locked}}, {}, {.threads = 1});
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("fig. 2.23"), std::string::npos) << r.warnings[0];
  EXPECT_EQ(r.get<Table>("table")->ints("stuck_components").at(0), 1);
}

TEST(ThinningModule, RejectsBadInputs) {
  auto mask = std::make_shared<VolumeU8>(Dims{4, 4, 4}, 1);
  auto prio = std::make_shared<VolumeU8>(Dims{4, 4, 5}, 1);
  EXPECT_THROW(run_module("thinning.doht", {{"mask", mask}, {"priority", prio}}), InputError);
  EXPECT_THROW(run_module("thinning.doht", {{"mask", mask}, {"priority", mask}},
                          {{"variant", ParamValue(std::string("fast"))}}),
               InputError);
  EXPECT_THROW(run_module("thinning.doht", {{"mask", mask}, {"priority", mask}},
                          {{"end_point_length", ParamValue(int64_t{-1})}}),
               InputError);
}

TEST(TopologyModule, Table) {
  auto m = std::make_shared<VolumeU8>(test::torus(24, 7, 3));
  const ModuleRunResult r = run_module("analysis.topology", {{"mask", m}}, {}, {.threads = 2});
  const auto t = r.get<Table>("table");
  const TopologyNumbers tn = topology(*m);
  EXPECT_EQ(t->ints("object_voxels").at(0), tn.object_voxels);
  EXPECT_EQ(t->ints("components").at(0), 1);
  EXPECT_EQ(t->ints("cavities").at(0), 0);
  EXPECT_EQ(t->ints("euler").at(0), 0);
  EXPECT_EQ(t->ints("tunnels").at(0), 1);
}

}  // namespace
}  // namespace skel
