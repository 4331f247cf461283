#pragma once
// The resume state of an out-of-core run (executor-internal; docs/architecture.md "Out-of-core
// execution"): under a memory budget a headless run keeps its scratch volumes in a folder of the
// scratch folder, `.skelflow-resume-<pipeline>-<hash>`, with a manifest naming the run (pid), the
// pipeline (hash of its nodes and connections), its parameters (hash of every node's cache key and of
// the input files' sizes and times), the memory budget and block shape, and the finished stages
// with their outputs (volumes as HDF5 files, tables as files of their own). The folder is removed
// when the run ends, whatever the outcome; only a killed run leaves it, for `--resume`.
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "skel/table.hpp"
#include "skel/volume.hpp"

namespace skel::detail {

struct ResumeOutput {
  std::string port;
  std::string kind;  // "volume" | "table"
  std::string file;  // name inside the resume folder
  std::string type_id;  // volumes
  Grid grid;            // volumes
};

struct ResumeNode {
  uint64_t key = 0;  // the node's cache key when it finished
  std::vector<ResumeOutput> outputs;
};

struct ResumeManifest {
  int64_t pid = 0;
  // skelflow-mpi: the number of ranks of the run (1 for skelflow); each rank keeps a manifest of its
  // own in the folder (resume_manifest_name), rank 0's is kResumeManifest.
  int64_t ranks = 1;
  uint64_t pipeline_hash = 0, params_hash = 0;
  uint64_t memory_budget = 0;
  Dims block{0, 0, 0};
  std::map<std::string, uint64_t> keys;         // every node's cache key (to name a changed node)
  std::map<std::string, std::string> inputs;    // input file -> "size mtime"
  std::map<std::string, ResumeNode> done;       // finished stages
};

inline constexpr const char* kResumeManifest = "manifest.txt";
// The manifest of `rank` of a run on `ranks` ranks: kResumeManifest for rank 0 (and one process),
// manifest.rR.txt for the others.
std::string resume_manifest_name(int rank, int ranks);

// Text form (one record per line) and back; parse throws Error naming the file and line.
std::string manifest_text(const ResumeManifest& m);
ResumeManifest parse_manifest(const std::filesystem::path& file);

// A table in a file of its own and back, exactly (doubles bit for bit).
void save_table(const std::filesystem::path& file, const Table& t);
Table load_table(const std::filesystem::path& file);

// "size mtime" of an input file or folder; "missing" when it does not exist.
std::string file_stamp(const std::filesystem::path& p);

// True when a process with this id runs (and is not this process).
bool other_process_alive(int64_t pid);

}  // namespace skel::detail
