// Every registered module documents itself completely: one-line doc, details, every port and
// parameter with a description, valid defaults, snake_case names, and distinct port names.
#include <gtest/gtest.h>

#include <cctype>
#include <set>

#include "skel/module.hpp"

using namespace skel;

namespace {
bool snake_case(const std::string& s) {
  if (s.empty() || !std::islower(static_cast<unsigned char>(s[0]))) return false;
  for (char c : s)
    if (!(std::islower(static_cast<unsigned char>(c)) || std::isdigit(static_cast<unsigned char>(c)) || c == '_'))
      return false;
  return true;
}
}  // namespace

TEST(ModuleDocs, EveryModuleIsFullyDocumented) {
  const auto specs = Registry::instance().specs();
  ASSERT_FALSE(specs.empty());
  for (const ModuleSpec* m : specs) {
    SCOPED_TRACE(m->name());
    const auto dot = m->name().find('.');
    ASSERT_NE(dot, std::string::npos);
    EXPECT_TRUE(snake_case(m->name().substr(0, dot)));
    EXPECT_TRUE(snake_case(m->name().substr(dot + 1)));
    EXPECT_GE(m->doc().size(), 10u) << "one-line doc missing";
    EXPECT_GE(m->details().size(), 80u) << "details() should describe algorithm, memory and conventions";
    std::set<std::string> names;
    for (const auto& p : m->inputs()) {
      EXPECT_TRUE(snake_case(p.name)) << p.name;
      EXPECT_FALSE(p.doc.empty()) << "input " << p.name;
      EXPECT_FALSE(p.types.empty()) << "input " << p.name;
      EXPECT_TRUE(names.insert("in:" + p.name).second) << "duplicate input " << p.name;
    }
    for (const auto& p : m->outputs()) {
      EXPECT_TRUE(snake_case(p.name)) << p.name;
      EXPECT_FALSE(p.doc.empty()) << "output " << p.name;
      EXPECT_TRUE(names.insert("out:" + p.name).second) << "duplicate output " << p.name;
    }
    for (const auto& p : m->params()) {
      EXPECT_TRUE(snake_case(p.name)) << p.name;
      EXPECT_FALSE(p.doc.empty()) << "param " << p.name;
      EXPECT_TRUE(names.insert("param:" + p.name).second) << "duplicate param " << p.name;
      // The default must pass the parameter's own check (paths may be required, i.e. empty).
      if (p.type != ParamType::Path) {
        EXPECT_EQ(p.check(p.default_value), "") << "default of " << p.name;
      }
    }
  }
}
