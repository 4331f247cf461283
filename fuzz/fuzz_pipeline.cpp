// The pipeline YAML loader and validator (every module registered, as `skelflow validate` sees them).
#include "fuzz_common.hpp"
#include "skel/error.hpp"
#include "skel/pipeline.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const skel::Pipeline p = skel::Pipeline::parse(skel::fuzz::as_text(data, size), "fuzz.yaml", "/nonexistent");
    (void)skel::validate(p);
    (void)p.to_yaml();
  } catch (const skel::Error&) {
  }
  return 0;
}
