// A shared library that is no plugin (no skelflow_plugin_abi): refused with the file named.
extern "C" __attribute__((visibility("default"))) int not_a_plugin_answer() { return 42; }
