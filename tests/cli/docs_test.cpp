// docs/modules.md is what the registry generates (`skelflow modules --markdown`): a module, port or
// parameter changed without regenerating the reference fails here.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

namespace {

std::string run_command(const std::string& cmd) {
  std::string out;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return out;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  pclose(p);
  return out;
}

TEST(Docs, ModulesMarkdownMatchesTheRegistry) {
  std::ifstream in(std::string(SKEL_SOURCE_DIR) + "/docs/modules.md", std::ios::binary);
  ASSERT_TRUE(in) << "docs/modules.md is missing";
  std::ostringstream committed;
  committed << in.rdbuf();
  const std::string generated = run_command(std::string("'") + SKELFLOW_BIN + "' modules --markdown");
  ASSERT_FALSE(generated.empty());
  if (generated != committed.str()) {
    // Name the first differing line so the failure says what to regenerate.
    std::istringstream a(committed.str()), b(generated);
    std::string la, lb;
    int line = 0;
    while (true) {
      ++line;
      const bool ha = static_cast<bool>(std::getline(a, la)), hb = static_cast<bool>(std::getline(b, lb));
      if (!ha && !hb) break;
      if (la != lb || ha != hb) {
        ADD_FAILURE() << "docs/modules.md differs from `skelflow modules --markdown` at line " << line
                      << "\n  committed: " << (ha ? la : "<end>") << "\n  generated: " << (hb ? lb : "<end>")
                      << "\nregenerate with: build/cli/skelflow modules --markdown > docs/modules.md";
        break;
      }
    }
  }
}

}  // namespace
