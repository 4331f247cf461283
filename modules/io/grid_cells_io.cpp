#include "io/grid_cells_io.hpp"

#include <cstring>

#include "io/hdf5_volume.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"

namespace skel::io {

void write_grid_cells(const std::filesystem::path& file, const GridCells& cells, const std::string& dataset,
                      int compression, int threads) {
  const Grid& g = cells.grid();
  Grid lg(cells.lattice_dims(), g.spacing, {g.origin[0] - 0.5 * g.spacing[0], g.origin[1] - 0.5 * g.spacing[1], g.origin[2] - 0.5 * g.spacing[2]},
          g.unit);
  lg.direction = g.direction;
  VolumeU8 v = VolumeU8::uninitialized(lg);
  std::memcpy(v.data(), cells.bytes_data().data(), cells.bytes_data().size());
  WriteOptions o;
  o.compression = compression;
  o.threads = threads;
  write_volume(file, v, dataset, o);
  write_string_attribute(file, dataset, "encoding", GridCells::kEncoding);
}

GridCells read_grid_cells(const std::filesystem::path& file, const std::string& dataset) {
  const std::string name = display_path(file).string();
  const std::string enc = read_string_attribute(file, dataset, "encoding");
  if (enc != GridCells::kEncoding)
    throw InputError(name + ": dataset '" + dataset + "' is not a grid cell complex (attribute 'encoding' is " +
                     (enc.empty() ? std::string("absent") : "'" + enc + "'") + ", expected '" + GridCells::kEncoding + "')");
  const DataPtr d = read_volume(file, dataset);
  const auto* v = dynamic_cast<const VolumeU8*>(d.get());
  if (!v) throw InputError(name + ": dataset '" + dataset + "' holds " + d->type_id() + ", a grid cell complex is uint8");
  const Grid& lg = v->grid();
  if (lg.dims[0] < 1 || lg.dims[1] < 1 || lg.dims[2] < 1) throw InputError(name + ": dataset '" + dataset + "' is empty");
  Grid g(Dims{lg.dims[0] - 1, lg.dims[1] - 1, lg.dims[2] - 1}, lg.spacing,
         {lg.origin[0] + 0.5 * lg.spacing[0], lg.origin[1] + 0.5 * lg.spacing[1], lg.origin[2] + 0.5 * lg.spacing[2]}, lg.unit);
  g.direction = lg.direction;
  GridCells c(g);
  std::memcpy(c.bytes_data().data(), v->data(), c.bytes_data().size());
  // Cells outside the box and cells whose faces are absent.
  const Dims kd = c.cell_dims();
  const Dims ld = c.lattice_dims();
  for (int64_t l = 0; l < ld[2]; ++l)
    for (int64_t j = 0; j < ld[1]; ++j)
      for (int64_t i = 0; i < ld[0]; ++i) {
        const uint8_t b = c.bytes_data()[static_cast<size_t>(i + ld[0] * (j + ld[1] * l))];
        for (int bit = 0; bit < 8; ++bit) {
          if (!((b >> bit) & 1)) continue;
          const int64_t k[3] = {2 * i + (bit & 1), 2 * j + ((bit >> 1) & 1), 2 * l + ((bit >> 2) & 1)};
          const std::string where = "cell (" + std::to_string(k[0]) + ", " + std::to_string(k[1]) + ", " + std::to_string(k[2]) + ")";
          if (k[0] >= kd[0] || k[1] >= kd[1] || k[2] >= kd[2])
            throw InputError(name + ": dataset '" + dataset + "': " + where + " lies outside the complex's box");
          for (int a = 0; a < 3; ++a) {
            if (!(k[a] & 1)) continue;
            for (int s = -1; s <= 1; s += 2) {
              int64_t f[3] = {k[0], k[1], k[2]};
              f[a] += s;
              if (!c.has(f[0], f[1], f[2]))
                throw InputError(name + ": dataset '" + dataset + "': not a cell complex: " + where + " lacks its face (" +
                                 std::to_string(f[0]) + ", " + std::to_string(f[1]) + ", " + std::to_string(f[2]) + ")");
            }
          }
        }
      }
  return c;
}

}  // namespace skel::io
