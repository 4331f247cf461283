#pragma once
// Errors a user can act on. Each layer adds one frame of context (algorithm → node → pipeline file),
// so the final message reads "pipelines/x.yaml:14:7: node thin1 (thinning.doht): param threshold: ...".
#include <stdexcept>
#include <string>

namespace skel {

class Error : public std::runtime_error {
public:
  explicit Error(const std::string& msg) : std::runtime_error(msg) {}
  // Returns a copy of this error with `context + ": "` prepended; the dynamic kind is preserved by
  // the subclasses through rethrow helpers below.
  [[nodiscard]] std::string with_context(const std::string& context) const {
    return context + ": " + what();
  }
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

}  // namespace skel
