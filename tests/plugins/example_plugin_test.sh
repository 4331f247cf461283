#!/bin/sh
# Plugin.ExampleBuildsAgainstInstalledTree: runs example_plugin_test.cmake with the cmake given
# first (the one that configured this build), or the one on PATH; skipped (77) when there is none.
cmake="$1"
shift
if [ ! -x "$cmake" ]; then
  cmake=$(command -v cmake) || { echo "cmake not found: Plugin.ExampleBuildsAgainstInstalledTree skipped"; exit 77; }
fi
exec "$cmake" "$@"
