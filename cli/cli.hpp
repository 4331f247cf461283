#pragma once
// The `skelflow` command line as a function, so tests can build a binary with extra test modules.
int skelflow_main(int argc, char** argv);
