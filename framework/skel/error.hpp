#pragma once
// Errors a user can act on. Each layer adds one frame of context (algorithm → node → pipeline file),
// so the final message reads "pipelines/x.yaml:14:7: node 'thin1' (thinning.doht): param threshold: ...".
#include <memory>
#include <stdexcept>
#include <string>

namespace skel {

// "file:line:col: " — the prefix of every message about a place in a file (validation diagnostics,
// errors of a running node). "file: " when the line is unknown, "line:col: " without a file, "" when
// neither is known.
std::string location_prefix(const std::string& file, int line, int column);

// Where a run-time error happened: the failing node and its place in the pipeline file. The executor
// attaches it to every error escaping a module's run() (see rethrow_at); what() then reads
// "file:line:col: node 'id' (module): message", the format of validation errors.
struct ErrorSite {
  std::string file;          // pipeline file
  int line = 0, column = 0;  // the node's position in `file`, 1-based; 0 = unknown (built in code)
  std::string node, module;
  std::string message;       // the error's own message, without the site
  // "file:line:col: node 'id' (module)" — without the file when the position is unknown, so that
  // pipelines built in code or added in the GUI read "node 'id' (module)".
  [[nodiscard]] std::string context() const;
};

class Error : public std::runtime_error {
public:
  explicit Error(const std::string& msg) : std::runtime_error(msg) {}
  // Message `site.context() + ": " + site.message`, remembering the site.
  explicit Error(ErrorSite site);
  // Returns this error's message with `context + ": "` prepended; the dynamic kind is preserved by
  // the subclasses through rethrow helpers below.
  [[nodiscard]] std::string with_context(const std::string& context) const {
    return context + ": " + what();
  }
  // The failing node and its position when the executor attached them; nullptr otherwise.
  [[nodiscard]] const ErrorSite* site() const { return site_.get(); }

private:
  std::shared_ptr<const ErrorSite> site_;  // shared: exceptions must copy without throwing
};

// The user's input (pipeline, parameter, file, data) is wrong: CLI exit code 2.
class InputError : public Error {
public:
  using Error::Error;
};

// The run was cancelled (Ctrl+C, GUI Cancel): CLI exit code 130.
class Cancelled : public Error {
public:
  Cancelled() : Error("cancelled") {}
  using Error::Error;
};

// Rethrows the exception currently being handled with `context` prepended, keeping its kind
// (InputError, Cancelled, Error). Non-skel exceptions become skel::Error.
[[noreturn]] void rethrow_with_context(const std::string& context);

// Rethrows the exception currently being handled as the same kind of error at `site` (its
// `message` is filled from the exception). Cancelled passes unchanged; out of memory and other
// non-skel exceptions become skel::Error.
[[noreturn]] void rethrow_at(ErrorSite site);

}  // namespace skel
