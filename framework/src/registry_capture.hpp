#pragma once
// Framework-internal (not installed): the plugin loader's hook into Registry::instance().
#include "skel/module.hpp"

namespace skel::detail {
// While set, Registry::instance().add() and add_inspector() put what they are given into `capture`
// instead: the loader sees every registration a plugin's code makes (its static initialisers at
// dlopen, its register function) before anything reaches the registry. nullptr ends it.
void set_registry_capture(Registry* capture);
}  // namespace skel::detail
