#pragma once
// Options several commands share (run, render): parsed once.
#include <string>

#include "skel/executor.hpp"

namespace skel::cli {

// `--set node.param=value` into opt.overrides; InputError "--set TEXT: ..." when malformed.
void parse_set_option(const std::string& text, ExecOptions& opt);
// `--threads N` (0 = all cores, at most 4096) into opt.threads.
void parse_threads_option(const std::string& text, ExecOptions& opt);

}  // namespace skel::cli
