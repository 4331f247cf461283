// Parameters bound to options structs (ModuleSpec::param(name, &Options::member, doc)): the spec takes
// type, default, choices and list length from the member; ctx.options<Options>() fills the struct.
#include <gtest/gtest.h>

#include <array>
#include <string>
#include <vector>

#include "skel/error.hpp"
#include "skel/module.hpp"
#include "skel/run_module.hpp"
#include "skel/table.hpp"

namespace skel {
namespace {

enum class Flavour { plain, spicy, sweet };
constexpr auto enum_names(Flavour) {
  return std::to_array<EnumName<Flavour>>({{Flavour::plain, "plain"}, {Flavour::spicy, "spicy"}, {Flavour::sweet, "sweet"}});
}

struct BaseOptions {
  bool border = false;
};
struct RecipeOptions : BaseOptions {
  using OptionsBase = BaseOptions;
  Flavour flavour = Flavour::spicy;
  int count = 7;
  uint8_t small = 3;
  double weight = 2.5;
  std::string label = "soup";
  std::array<double, 3> size{1, 2, 3};
  std::vector<int64_t> ids{4, 5};
  int64_t sum = 0;  // set by param_fn
  int threads = -1;
  Interrupter interrupter;
};

// Writes every field of the filled options into a one-row table.
class Recipe final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test.recipe", "Echoes its options")
        .output<Table>("table", "the options as filled")
        .param("flavour", &RecipeOptions::flavour, "taste")
        .param("count", &RecipeOptions::count, "how many").range(0, 100)
        .param("small", &RecipeOptions::small, "fits in a byte")
        .param("weight", &RecipeOptions::weight, "kg").min(0)
        .param("label", &RecipeOptions::label, "name")
        .param("size", &RecipeOptions::size, "box").min(0)
        .param("ids", &RecipeOptions::ids, "list")
        .param("border", &BaseOptions::border, "from the base struct")
        .param_fn<RecipeOptions>("pair", std::array<int64_t, 2>{1, 2},
                                 [](RecipeOptions& o, const std::array<int64_t, 2>& p) { o.sum = p[0] + p[1]; },
                                 "two numbers, stored as their sum")
        .param("mode", Flavour::sweet, "an unbound choice");
  }
  void run(RunContext& ctx) override {
    const auto o = ctx.options<RecipeOptions>();
    Table t;
    t.add("flavour", std::vector<std::string>{enum_name(o.flavour)});
    t.add("count", std::vector<int64_t>{o.count});
    t.add("small", std::vector<int64_t>{o.small});
    t.add("weight", std::vector<double>{o.weight});
    t.add("label", std::vector<std::string>{o.label});
    t.add("size_z", std::vector<double>{o.size[2]});
    t.add("ids", std::vector<int64_t>{static_cast<int64_t>(o.ids.size())});
    t.add("border", std::vector<int64_t>{o.border ? 1 : 0});
    t.add("sum", std::vector<int64_t>{o.sum});
    t.add("threads", std::vector<int64_t>{o.threads});
    t.add("mode", std::vector<std::string>{enum_name(ctx.param<Flavour>("mode"))});
    ctx.output("table", std::move(t));
  }
};
SKEL_REGISTER_MODULE(Recipe);

const ParamSpec& param(const std::string& name) {
  const ParamSpec* p = Registry::instance().find("test.recipe")->find_param(name);
  EXPECT_NE(p, nullptr) << name;
  return *p;
}

TEST(ParamBinding, SpecTakesTypeDefaultChoicesAndLengthFromTheMember) {
  EXPECT_EQ(param("flavour").type, ParamType::Choice);
  EXPECT_EQ(param("flavour").choices, (std::vector<std::string>{"plain", "spicy", "sweet"}));
  EXPECT_EQ(std::get<std::string>(param("flavour").default_value), "spicy");
  EXPECT_EQ(param("count").type, ParamType::Int);
  EXPECT_EQ(std::get<int64_t>(param("count").default_value), 7);
  EXPECT_EQ(*param("count").max, 100.0);
  EXPECT_EQ(param("weight").type, ParamType::Float);
  EXPECT_EQ(std::get<double>(param("weight").default_value), 2.5);
  EXPECT_EQ(param("label").type, ParamType::String);
  EXPECT_EQ(param("size").type, ParamType::FloatList);
  EXPECT_EQ(param("size").list_length, 3);
  EXPECT_EQ(std::get<std::vector<double>>(param("size").default_value), (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(param("ids").type, ParamType::IntList);
  EXPECT_EQ(param("ids").list_length, -1);
  EXPECT_EQ(param("border").type, ParamType::Bool);
  EXPECT_EQ(param("pair").type, ParamType::IntList);
  EXPECT_EQ(param("pair").list_length, 2);
  EXPECT_EQ(param("mode").type, ParamType::Choice);
  EXPECT_EQ(std::get<std::string>(param("mode").default_value), "sweet");
  // Every default passes its own check.
  for (const auto& p : Registry::instance().find("test.recipe")->params()) EXPECT_EQ(p.check(p.default_value), "") << p.name;
}

TEST(ParamBinding, DefaultsFillTheStructAsItsInitialisersDo) {
  const auto r = run_module("test.recipe", {}, {}, {.threads = 3});
  const auto t = r.get<Table>("table");
  EXPECT_EQ(t->strings("flavour")[0], "spicy");
  EXPECT_EQ(t->ints("count")[0], 7);
  EXPECT_EQ(t->ints("small")[0], 3);
  EXPECT_EQ(t->reals("weight")[0], 2.5);
  EXPECT_EQ(t->strings("label")[0], "soup");
  EXPECT_EQ(t->reals("size_z")[0], 3.0);
  EXPECT_EQ(t->ints("ids")[0], 2);
  EXPECT_EQ(t->ints("border")[0], 0);
  EXPECT_EQ(t->ints("sum")[0], 3);
  EXPECT_EQ(t->ints("threads")[0], 3);  // filled from the run context
  EXPECT_EQ(t->strings("mode")[0], "sweet");
}

TEST(ParamBinding, GivenValuesReachTheMembersIncludingTheBaseStruct) {
  const auto r = run_module("test.recipe", {},
                            {{"flavour", std::string("plain")}, {"count", int64_t{42}}, {"weight", int64_t{4}},
                             {"size", std::vector<double>{0, 0, 9}}, {"ids", std::vector<int64_t>{}},
                             {"border", true}, {"pair", std::vector<int64_t>{10, 20}}, {"mode", std::string("plain")}},
                            {.threads = 1});
  const auto t = r.get<Table>("table");
  EXPECT_EQ(t->strings("flavour")[0], "plain");
  EXPECT_EQ(t->ints("count")[0], 42);
  EXPECT_EQ(t->reals("weight")[0], 4.0);
  EXPECT_EQ(t->reals("size_z")[0], 9.0);
  EXPECT_EQ(t->ints("ids")[0], 0);
  EXPECT_EQ(t->ints("border")[0], 1);
  EXPECT_EQ(t->ints("sum")[0], 30);
  EXPECT_EQ(t->strings("mode")[0], "plain");
}

TEST(ParamBinding, ValuesOutsideTheMembersRangeAreInputErrorsNamingTheParameter) {
  try {
    (void)run_module("test.recipe", {}, {{"small", int64_t{300}}});
    FAIL() << "300 does not fit in a uint8_t";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("parameter 'small'"), std::string::npos) << e.what();
  }
  try {
    (void)run_module("test.recipe", {}, {{"flavour", std::string("bitter")}});
    FAIL() << "bitter is not a flavour";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("flavour"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("plain spicy sweet"), std::string::npos) << e.what();
  }
}

TEST(EnumNames, ParseAndNameRoundTrip) {
  for (Flavour f : {Flavour::plain, Flavour::spicy, Flavour::sweet}) EXPECT_EQ(parse_enum<Flavour>(enum_name(f), "x"), f);
  EXPECT_EQ(enum_choices<Flavour>(), (std::vector<std::string>{"plain", "spicy", "sweet"}));
  try {
    (void)parse_enum<Flavour>("sour", "parameter 'flavour'");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "parameter 'flavour': 'sour' is not one of: plain spicy sweet");
  }
}

}  // namespace
}  // namespace skel
