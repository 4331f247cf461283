#include "cli.hpp"

int main(int argc, char** argv) { return skelflow_main(argc, argv); }
