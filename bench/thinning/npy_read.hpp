#pragma once
// Minimal .npy reader for uint8 volumes written by NumPy (C order, shape (z, y, x)): reads the
// skeletons computed by the Python peer back for topology numbers.
#include <cstdint>
#include <fstream>
#include <string>

#include "skel/error.hpp"
#include "skel/volume.hpp"

namespace skel::bench {

inline VolumeU8 read_npy_u8(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("cannot read " + path);
  char magic[8];
  f.read(magic, 8);
  if (std::string(magic + 1, 5) != "NUMPY") throw Error(path + ": not a .npy file");
  uint32_t header_len = 0;
  if (magic[6] == 1) {
    uint16_t l = 0;
    f.read(reinterpret_cast<char*>(&l), 2);
    header_len = l;
  } else {
    f.read(reinterpret_cast<char*>(&header_len), 4);
  }
  std::string header(header_len, '\0');
  f.read(header.data(), header_len);
  if (header.find("'|u1'") == std::string::npos && header.find("'|b1'") == std::string::npos)
    throw Error(path + ": expected dtype uint8 or bool, header " + header);
  if (header.find("'fortran_order': False") == std::string::npos) throw Error(path + ": expected C order");
  const size_t s = header.find("'shape': (");
  if (s == std::string::npos) throw Error(path + ": no shape");
  int64_t dims[3] = {0, 0, 0};
  size_t p = s + 10;
  for (int k = 0; k < 3; ++k) {
    dims[k] = std::stoll(header.substr(p));
    p = header.find_first_of(",)", p) + 1;
    while (p < header.size() && header[p] == ' ') ++p;
  }
  VolumeU8 v(Dims{dims[2], dims[1], dims[0]}, 0);
  f.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(v.size()));
  if (!f) throw Error(path + ": short read");
  return v;
}

}  // namespace skel::bench
