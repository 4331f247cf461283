// Landmark files: the first byte chooses the format (Amira .landmarkAscii, Slicer .fcsv, .csv), the
// rest is the file's text.
#include "fuzz_common.hpp"
#include "io/landmark_io.hpp"
#include "skel/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using skel::io::LandmarkFormat;
  if (size == 0) return 0;
  static constexpr LandmarkFormat formats[] = {LandmarkFormat::Amira, LandmarkFormat::Fcsv, LandmarkFormat::Csv};
  const LandmarkFormat format = formats[data[0] % 3];
  try {
    (void)skel::io::parse_landmarks(skel::fuzz::as_text(data + 1, size - 1), format, "fuzz");
  } catch (const skel::Error&) {
  }
  return 0;
}
