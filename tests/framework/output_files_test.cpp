// Output files of a run: temporary names that carry the run and the process, no temporary of a
// temporary, stale temporaries of dead processes cleaned up, and the outputs committed as one set
// (a failure part-way takes back the files already moved).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "context.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {

fs::path scratch(const std::string& name) {
  fs::path d = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / ("output_files_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void put(const fs::path& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }

std::vector<std::string> names_in(const fs::path& d) {
  std::vector<std::string> r;
  for (const auto& e : fs::directory_iterator(d)) r.push_back(e.path().filename().string());
  std::sort(r.begin(), r.end());
  return r;
}

// A process id that is not running any more (a child that exited and was reaped).
long dead_pid() {
  const pid_t pid = fork();
  if (pid == 0) _exit(0);
  int status = 0;
  waitpid(pid, &status, 0);
  return static_cast<long>(pid);
}

}  // namespace

TEST(TempNames, CarryTheRunIdAndTheProcess) {
  const fs::path t = temp_sibling("/data/out/image.h5", "0badc0de");
  EXPECT_EQ(t, fs::path("/data/out/.image.h5.skelflow-tmp-0badc0de-" + std::to_string(getpid())));
  TempName n;
  ASSERT_TRUE(parse_temp_name(t, n));
  EXPECT_FALSE(n.backup);
  EXPECT_EQ(n.final, fs::path("/data/out/image.h5"));
  EXPECT_EQ(n.run_id, "0badc0de");
  EXPECT_EQ(n.pid, static_cast<long>(getpid()));
  EXPECT_EQ(display_path(t), fs::path("/data/out/image.h5"));
  ASSERT_TRUE(parse_temp_name(backup_sibling("/d/a.csv", "12ab"), n));
  EXPECT_TRUE(n.backup);
  EXPECT_EQ(n.final, fs::path("/d/a.csv"));
  // Other hidden files are not temporaries.
  for (const char* other : {"/d/.a.csv", "/d/a.csv", "/d/.a.tmp-123456", "/d/.a.skelflow-tmp-xyz-1", "/d/.skelflow-tmp-1-1"})
    EXPECT_FALSE(parse_temp_name(other, n)) << other;
  EXPECT_EQ(display_path("/d/.a.csv"), fs::path("/d/.a.csv"));
  // A fresh run id each time one is not given.
  EXPECT_NE(temp_sibling("/d/a"), temp_sibling("/d/a"));
}

// The engine hands writers a temporary; a writer going through write_atomically must write that
// file itself, not a temporary of it ("..x.h5.tmp-….tmp-…" before).
TEST(TempNames, WriteAtomicallyWritesAnEngineTemporaryInPlace) {
  const fs::path d = scratch("in_place");
  const fs::path engine_tmp = temp_sibling(d / "x.h5", "1234abcd");
  fs::path written;
  write_atomically(engine_tmp, [&](const fs::path& p) {
    written = p;
    put(p, "data");
  });
  EXPECT_EQ(written, engine_tmp);
  EXPECT_EQ(names_in(d), std::vector<std::string>{engine_tmp.filename().string()});
  // A failing write names the final file, not the temporary.
  try {
    write_file_atomically(d / "no_such_folder" / ".t.csv.skelflow-tmp-1-1", "x");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "cannot write " + (d / "no_such_folder" / "t.csv").string() +
                                         ": No such file or directory");
  }
}

TEST(StaleTemps, OnlyThoseOfDeadProcessesAreRemoved) {
  const fs::path d = scratch("stale");
  const std::string dead = std::to_string(dead_pid()), live = std::to_string(getpid());
  put(d / (".a.h5.skelflow-tmp-0badc0de-" + dead), "partial");
  put(d / ("..a.h5.skelflow-tmp-0badc0de-" + dead + ".skelflow-tmp-1-" + dead), "partial");
  put(d / (".b.csv.skelflow-tmp-12345678-" + live), "still being written");
  put(d / (".c.csv.skelflow-bak-0badc0de-" + dead), "previous c");  // c.csv missing: restored
  put(d / "d.csv", "new d");
  put(d / (".d.csv.skelflow-bak-0badc0de-" + dead), "previous d");  // d.csv exists: removed
  put(d / ".hidden", "not ours");
  const auto done = remove_stale_temps(d);
  EXPECT_EQ(names_in(d), (std::vector<std::string>{".b.csv.skelflow-tmp-12345678-" + live, ".hidden", "c.csv", "d.csv"}));
  EXPECT_EQ(read(d / "c.csv"), "previous c");
  EXPECT_EQ(read(d / "d.csv"), "new d");
  ASSERT_EQ(done.size(), 4u);
  std::string all;
  for (const auto& s : done) all += s + "\n";
  EXPECT_NE(all.find("removed " + (d / (".a.h5.skelflow-tmp-0badc0de-" + dead)).string()), std::string::npos) << all;
  EXPECT_NE(all.find("restored " + (d / "c.csv").string()), std::string::npos) << all;
  EXPECT_TRUE(remove_stale_temps(d).empty());
}

TEST(OutputFiles, CommitReplacesTheSetAndLeavesNoBackup) {
  const fs::path d = scratch("commit_ok");
  put(d / "a.txt", "old a");
  detail::OutputFiles files;
  put(files.add(d / "a.txt"), "new a");
  put(files.add(d / "sub" / "b.txt"), "new b");
  const fs::path not_written = files.add(d / "c.txt");
  EXPECT_EQ(not_written.filename().string().find(".c.txt.skelflow-tmp-" + files.run_id() + "-"), 0u);
  files.commit();
  EXPECT_EQ(read(d / "a.txt"), "new a");
  EXPECT_EQ(read(d / "sub" / "b.txt"), "new b");
  EXPECT_EQ(names_in(d), (std::vector<std::string>{"a.txt", "sub"}));
  EXPECT_EQ(names_in(d / "sub"), std::vector<std::string>{"b.txt"});
}

// One output cannot be moved into place after others were: those are taken back, the previous
// files restored, and nothing of the run is left (before: the files moved first stayed).
TEST(OutputFiles, AFailedCommitTakesBackTheFilesAlreadyMoved) {
  const fs::path d = scratch("commit_fail");
  put(d / "a.txt", "old a");
  detail::OutputFiles files;
  put(files.add(d / "a.txt"), "new a");
  put(files.add(d / "c.txt"), "new c");
  put(files.add(d / "summary.csv"), "new summary");
  fs::create_directories(d / "summary.csv" / "blocked");  // appears while the run goes on
  std::vector<std::string> notes;
  try {
    files.commit(&notes);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "cannot replace " + (d / "summary.csv").string() +
                                         ": it is a folder; no output was changed (2 files already moved were taken "
                                         "back: 1 restored, 1 removed)");
  }
  EXPECT_EQ(read(d / "a.txt"), "old a");
  EXPECT_EQ(names_in(d), (std::vector<std::string>{"a.txt", "summary.csv"}));
  EXPECT_EQ(notes, (std::vector<std::string>{"removed the new " + (d / "c.txt").string(),
                                             "restored the previous " + (d / "a.txt").string()}));
}
