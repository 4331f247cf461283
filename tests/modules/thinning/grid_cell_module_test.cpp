// thinning.grid_cell through the module API (run_module): ports, table, parameter errors.
#include <gtest/gtest.h>

#include <memory>

#include "analysis/topology.hpp"
#include "shapes.hpp"
#include "skel/grid_cells.hpp"
#include "skel/run_module.hpp"
#include "skel/table.hpp"
#include "thinning/grid_cell.hpp"

using namespace skel::thinning;
using namespace skel::analysis;

namespace skel {
namespace {

GridCellThinningOptions gopts(int l, int threads = 1) {
  GridCellThinningOptions o;
  o.end_point_length = l;
  o.threads = threads;
  return o;
}

TEST(GridCellThinningModule, OutputsSkeletonAndTable) {
  const VolumeU8 m = test::random_blobs(20, 5, 0.49, 1);
  auto mask = std::make_shared<VolumeU8>(m);
  auto prio = std::make_shared<VolumeU32>(test::chamfer345(m));
  const ModuleRunResult r = run_module("thinning.grid_cell", {{"mask", mask}, {"priority", prio}},
                                       {{"end_point_length", ParamValue(int64_t{4})}}, {.threads = 2});
  const auto s = r.get<GridCells>("skeleton");
  EXPECT_TRUE(*s == thin_grid_cells(m, *prio, nullptr, gopts(4)).skeleton);
  const auto t = r.get<Table>("table");
  EXPECT_EQ(t->ints("euler")[0], topology(m).euler);
  EXPECT_EQ(t->ints("cells3_after")[0], 0);
  EXPECT_THROW(run_module("thinning.grid_cell", {{"mask", mask}, {"priority", prio}},
                          {{"end_point_length", ParamValue(int64_t{-1})}}),
               InputError);
}

}  // namespace
}  // namespace skel
