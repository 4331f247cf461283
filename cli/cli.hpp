#pragma once
#include <string>
// The `skelflow` command line as a function, so tests can build a binary with extra test modules.
int skelflow_main(int argc, char** argv);
// A duration as the progress line shows it: "7s", "3m05s", "2h04m".
std::string format_duration(double seconds);
