#pragma once
// File-safety helpers: every writer writes a temporary sibling file and renames it into place, so a
// failed or interrupted write never leaves a partial file under the final name.
//
// Temporary files are named ".<name>.skelflow-tmp-<runid>-<pid>" (and backups of files being
// replaced ".<name>.skelflow-bak-<runid>-<pid>"), so that a later run into the same folder can tell
// the leftovers of a process that died (SIGKILL, power loss) from the files of a run still going
// on, and remove them (remove_stale_temps).
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace skel {

// A fresh identifier for one run (8 hex digits, random).
std::string make_run_id();

// The temporary sibling of `final_path` for run `run_id` of this process:
// "<dir>/.<name>.skelflow-tmp-<run_id>-<pid>" (same folder, so the rename is atomic). An empty
// `run_id` takes a fresh one.
std::filesystem::path temp_sibling(const std::filesystem::path& final_path, const std::string& run_id = {});
// The backup name of an existing `final_path` while a run replaces it: ".<name>.skelflow-bak-<run_id>-<pid>".
std::filesystem::path backup_sibling(const std::filesystem::path& final_path, const std::string& run_id);

// What a file name made by temp_sibling or backup_sibling says about itself.
struct TempName {
  bool backup = false;          // a backup (skelflow-bak), not a temporary (skelflow-tmp)
  std::filesystem::path final;  // the file it stands for
  std::string run_id;
  long pid = 0;                 // the process that made it
};
// Parses a temporary or backup name; false when `path` is not one.
bool parse_temp_name(const std::filesystem::path& path, TempName& out);
// The path to show users for a file being written: the final path when `path` is a temporary
// made by temp_sibling, `path` itself otherwise. Messages name the file the user asked for, not
// the temporary it is written under.
std::filesystem::path display_path(const std::filesystem::path& path);

// Removes the temporaries of processes that no longer run from `folder` (not recursive) and
// restores or removes their backups: a backup whose final file is missing is renamed back (the run
// died while replacing it), any other is removed. Returns one entry per file handled, e.g.
// "removed out/.a.h5.skelflow-tmp-1f2e3d4c-4242". Temporaries of live processes are left alone.
std::vector<std::string> remove_stale_temps(const std::filesystem::path& folder);

// Writes through `write(tmp_path)`, then renames to `final_path`. On any exception the temporary is
// removed and the exception propagates. Creates missing parent directories. When `final_path` is
// already a temporary made by temp_sibling (the engine's RunContext::output_path), `write` writes
// it directly: the engine renames it when the run succeeds (no temporary of a temporary).
void write_atomically(const std::filesystem::path& final_path,
                      const std::function<void(const std::filesystem::path&)>& write);

// Writes `bytes` to `path` through write_atomically. Throws Error "cannot write FILE: REASON" with
// the OS's reason (FILE as display_path shows it).
void write_file_atomically(const std::filesystem::path& path, const std::string& bytes);

}  // namespace skel
