// Transform files: the first byte chooses the format (4x4 matrix text, ITK .tfm), the rest is the
// file's text.
#include "fuzz_common.hpp"
#include "io/landmark_io.hpp"
#include "skel/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using skel::io::TransformFormat;
  if (size == 0) return 0;
  const TransformFormat format = data[0] % 2 ? TransformFormat::Itk : TransformFormat::Matrix;
  try {
    (void)skel::io::parse_transform(skel::fuzz::as_text(data + 1, size - 1), format, "fuzz");
  } catch (const skel::Error&) {
  }
  return 0;
}
