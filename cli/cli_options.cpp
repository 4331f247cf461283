#include "cli_options.hpp"

#include "skel/error.hpp"
#include "skel/text.hpp"

namespace skel::cli {

void parse_set_option(const std::string& s, ExecOptions& opt) {
  auto eq = s.find('=');
  auto dot = s.find('.');
  if (eq == std::string::npos || dot == std::string::npos || dot > eq)
    throw InputError("--set " + s + ": expected node.param=value");
  if (dot == 0 || eq == dot + 1) throw InputError("--set " + s + ": expected node.param=value");
  try {
    opt.overrides[s.substr(0, dot)][s.substr(dot + 1, eq - dot - 1)] = parse_param_text(s.substr(eq + 1));
  } catch (const InputError& e) {
    throw InputError("--set " + s + ": " + e.what());
  }
}

void parse_threads_option(const std::string& v, ExecOptions& opt) {
  int64_t n = 0;
  if (!text::parse_int(v, n) || n < 0 || n > 4096)
    throw InputError("--threads " + v + ": expected a whole number from 0 (all cores) to 4096");
  opt.threads = static_cast<int>(n);
}

}  // namespace skel::cli
