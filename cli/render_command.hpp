#pragma once
// `skelflow render PIPELINE --node NODE.PORT... -o FILE.png`: runs what the nodes need and draws
// their outputs off-screen with the GUI 3D view's look (render/skel_render).
#include <atomic>
#include <functional>
#include <string>
#include <vector>

namespace skel::cli {

// `unknown_option(arg)` throws the command table's "unknown option (did you mean ...)" error.
// Returns the exit code (0) or throws InputError / Error / Cancelled as the other commands do.
int cmd_render(const std::vector<std::string>& args, const std::atomic<bool>* cancel,
               const std::function<void(const std::string&)>& unknown_option);

}  // namespace skel::cli
