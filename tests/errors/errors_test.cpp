// Golden tests of the messages users see. Every data/NAME.yaml is run by the real `skelflow` binary
// as a user would (`skelflow run NAME.yaml --quiet --threads 1`, in the data folder, plus the
// arguments of a first line "# args: ..."), and its whole output and exit code must equal
// data/NAME.expected. The data folder's absolute path reads "<data>" there, so the files do not
// depend on where the tree lives. To accept new messages: SKEL_UPDATE_GOLDEN=1 ctest -R errors_test,
// then review the diff of the .expected files.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

const fs::path kData = fs::canonical(SKEL_ERRORS_DATA);

std::vector<std::string> cases() {
  std::vector<std::string> r;
  for (const auto& e : fs::directory_iterator(kData))
    if (e.path().extension() == ".yaml") r.push_back(e.path().stem().string());
  std::sort(r.begin(), r.end());
  return r;
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Extra command-line arguments from a first line "# args: a b c" (split at spaces).
std::vector<std::string> extra_args(const fs::path& yaml) {
  std::ifstream in(yaml);
  std::string first;
  std::getline(in, first);
  const std::string key = "# args:";
  if (first.rfind(key, 0) != 0) return {};
  std::istringstream words(first.substr(key.size()));
  std::vector<std::string> r;
  for (std::string w; words >> w;) r.push_back(w);
  return r;
}

void replace_all(std::string& s, const std::string& from, const std::string& to) {
  for (size_t i = s.find(from); i != std::string::npos; i = s.find(from, i + to.size())) s.replace(i, from.size(), to);
}

// Runs skelflow in the data folder; returns its output (stdout + stderr) and "[exit N]".
std::string run_case(const std::string& name) {
  std::vector<std::string> args{SKELFLOW_BIN, "run", name + ".yaml", "--quiet", "--threads", "1"};
  for (auto& a : extra_args(kData / (name + ".yaml"))) args.push_back(a);
  const fs::path log = fs::temp_directory_path() / ("skel_errors_" + std::to_string(getpid()) + ".log");
  const pid_t pid = fork();
  if (pid == 0) {
    if (chdir(kData.c_str()) != 0) _exit(126);
    if (!std::freopen(log.c_str(), "w", stdout)) _exit(126);
    dup2(fileno(stdout), fileno(stderr));
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  std::string out = read_text(log);
  fs::remove(log);
  replace_all(out, kData.string(), "<data>");
  return out + "[exit " + std::to_string(code) + "]\n";
}

class ErrorMessage : public testing::TestWithParam<std::string> {};

TEST_P(ErrorMessage, MatchesGolden) {
  const std::string name = GetParam();
  const fs::path expected_file = kData / (name + ".expected");
  const std::string actual = run_case(name);
  if (const char* u = std::getenv("SKEL_UPDATE_GOLDEN"); u && std::string(u) == "1") {
    std::ofstream(expected_file, std::ios::binary) << actual;
    return;
  }
  ASSERT_TRUE(fs::exists(expected_file)) << expected_file << " is missing; the output is:\n" << actual;
  EXPECT_EQ(actual, read_text(expected_file)) << "case " << name;
}

INSTANTIATE_TEST_SUITE_P(Golden, ErrorMessage, testing::ValuesIn(cases()),
                         [](const testing::TestParamInfo<std::string>& i) { return i.param; });

TEST(ErrorMessages, EveryGoldenFileHasItsPipeline) {
  for (const auto& e : fs::directory_iterator(kData)) {
    if (e.path().extension() == ".expected") {
      EXPECT_TRUE(fs::exists(fs::path(e.path()).replace_extension(".yaml"))) << e.path();
    }
  }
}

}  // namespace
