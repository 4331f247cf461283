#pragma once
// File-safety helpers: every writer writes a temporary sibling file and renames it into place, so a
// failed or interrupted write never leaves a partial file under the final name.
#include <filesystem>
#include <functional>

namespace skel {

// A unique temporary sibling of `final_path`: "<dir>/.<name>.tmp-XXXXXX" (same filesystem, so the
// rename is atomic).
std::filesystem::path temp_sibling(const std::filesystem::path& final_path);

// Writes through `write(tmp_path)`, then renames to `final_path`. On any exception the temporary is
// removed and the exception propagates. Creates missing parent directories.
void write_atomically(const std::filesystem::path& final_path,
                      const std::function<void(const std::filesystem::path&)>& write);

}  // namespace skel
