// registration.stitch_tiles (thesis §6.1): tiles cut from a known textured volume with perturbed
// stage positions are placed back, merged exactly (noise-free) or within the noise, the global fit
// beats chaining pairwise offsets, low-correlation pairs are dropped, tile lists with errors name
// the line and the tile, and the merge onto disk equals the one in memory.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "io/volume_format.hpp"
#include "registration/stitch.hpp"
#include "skel/out_of_core.hpp"
#include "skel/run_module.hpp"

using namespace skel;
using namespace skel::registration;
namespace fs = std::filesystem;

namespace {

fs::path dir() {
  const fs::path d = fs::path(SKEL_BINARY_DIR) / "test_scratch" / "registration_stitch";
  fs::create_directories(d);
  return d;
}

// Smoothed noise (Gaussian, sigma 2 voxels) scaled to 0..1000 plus three bright tubes (radius 3).
VolumeU16 textured_volume(const Dims& d, uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  const int64_t n = d[0] * d[1] * d[2];
  std::vector<double> v(static_cast<size_t>(n));
  for (auto& x : v) x = g(rng);
  const int r = 5;
  std::vector<double> k(2 * r + 1);
  for (int i = -r; i <= r; ++i) k[static_cast<size_t>(i + r)] = std::exp(-0.5 * i * i / 4.0);
  const std::array<int64_t, 3> stride{1, d[0], d[0] * d[1]};
  for (size_t a = 0; a < 3; ++a) {
    std::vector<double> out(v.size(), 0.0);
    for (int64_t z = 0; z < d[2]; ++z)
      for (int64_t y = 0; y < d[1]; ++y)
        for (int64_t x = 0; x < d[0]; ++x) {
          const std::array<int64_t, 3> p{x, y, z};
          double s = 0, w = 0;
          for (int i = -r; i <= r; ++i) {
            const int64_t q = p[a] + i;
            if (q < 0 || q >= d[a]) continue;
            s += k[static_cast<size_t>(i + r)] * v[static_cast<size_t>(x * stride[0] + y * stride[1] + z * stride[2] + i * stride[a])];
            w += k[static_cast<size_t>(i + r)];
          }
          out[static_cast<size_t>(x + d[0] * (y + d[1] * z))] = s / w;
        }
    v.swap(out);
  }
  const auto [mn, mx] = std::minmax_element(v.begin(), v.end());
  VolumeU16 vol(d);
  for (int64_t z = 0; z < d[2]; ++z)
    for (int64_t y = 0; y < d[1]; ++y)
      for (int64_t x = 0; x < d[0]; ++x) {
        double val = 1000.0 * (v[static_cast<size_t>(x + d[0] * (y + d[1] * z))] - *mn) / (*mx - *mn);
        const double dx = static_cast<double>(x), dy = static_cast<double>(y), dz = static_cast<double>(z);
        if (std::hypot(dy - 0.4 * dx - 20.0, dz - 10.0) < 3.0) val += 2000.0;
        if (std::hypot(dx - 0.7 * dy - 30.0, dz - 20.0) < 3.0) val += 2000.0;
        if (std::hypot(dx - 100.0, dy - 90.0) < 3.0) val += 2000.0;
        vol(x, y, z) = static_cast<uint16_t>(std::lround(val));
      }
  return vol;
}

struct Mosaic {
  VolumeU16 original;
  std::vector<std::shared_ptr<const VolumeU16>> tiles;
  std::vector<Vec3> truth;  // true positions (voxels)
  std::vector<StitchTile> stitch;
};

// A gx × gy grid of tiles (64 × 64 × nz, step 40: 24-voxel overlaps) cut from one textured volume;
// nominal positions perturbed by up to ±5 voxels per axis; Gaussian noise of `noise` added per tile.
Mosaic make_mosaic(int gx, int gy, double noise, uint32_t seed, int64_t nz = 32) {
  Mosaic m;
  const int64_t t = 64, step = 40;
  m.original = textured_volume({step * (gx - 1) + t, step * (gy - 1) + t, nz}, seed);
  std::mt19937_64 rng(seed + 1);
  std::uniform_real_distribution<double> perturb(-5.0, 5.0);
  std::normal_distribution<double> gauss(0.0, noise);
  for (int j = 0; j < gy; ++j)
    for (int i = 0; i < gx; ++i) {
      const Dims begin{step * i, step * j, 0};
      auto tile = std::make_shared<VolumeU16>(read_block<uint16_t>(m.original, begin, {t, t, nz}, "original"));
      if (noise > 0)
        for (int64_t k = 0; k < tile->size(); ++k)
          tile->data()[k] = static_cast<uint16_t>(std::clamp(std::lround(tile->data()[k] + gauss(rng)), 0L, 65535L));
      m.truth.push_back({static_cast<double>(begin[0]), static_cast<double>(begin[1]), 0.0});
      StitchTile s;
      s.name = "tile_" + std::to_string(i) + "_" + std::to_string(j);
      s.grid = Grid({t, t, nz});
      s.type_id = type_ids::volume_u16;
      s.position = {begin[0] + perturb(rng), begin[1] + perturb(rng), perturb(rng)};
      s.read_box = [tile](const Dims& b, const Dims& size) -> DataPtr {
        return std::make_shared<VolumeU16>(read_block<uint16_t>(*tile, b, size, "tile"));
      };
      m.tiles.push_back(tile);
      m.stitch.push_back(std::move(s));
    }
  return m;
}

// Largest distance between the refined and the true positions, both relative to tile 0.
double max_relative_error(const std::vector<Vec3>& pos, const std::vector<Vec3>& truth) {
  double e = 0.0;
  for (size_t i = 0; i < pos.size(); ++i)
    for (size_t k = 0; k < 3; ++k) e = std::max(e, std::abs((pos[i][k] - pos[0][k]) - (truth[i][k] - truth[0][k])));
  return e;
}

void expect_placed_exactly(const Mosaic& m, const StitchLayout& layout) {
  for (size_t i = 0; i < m.truth.size(); ++i)
    for (size_t k = 0; k < 3; ++k)
      EXPECT_EQ(static_cast<double>(layout.placed[i][k] - layout.placed[0][k]), m.truth[i][k] - m.truth[0][k]) << "tile " << i;
}

}  // namespace

TEST(StitchTiles, NoiseFreeGridIsPlacedBackAndMergedExactly) {
  Mosaic m = make_mosaic(3, 3, 0.0, 5);
  std::vector<std::string> notes;
  std::atomic<bool> cancel{false};
  StitchOptions o;
  o.interrupter = Interrupter([](double) {}, &cancel, [&](const std::string& s) { notes.push_back(s); });
  const StitchLayout layout = align_tiles(m.stitch, o);
  EXPECT_EQ(layout.pairs.size(), 20u);  // 12 edge neighbours + 8 diagonal (corner overlaps)
  for (const auto& p : layout.pairs) {
    EXPECT_EQ(p.status, PairStatus::used);
    EXPECT_GT(p.correlation, 0.99);
  }
  EXPECT_LT(max_relative_error(layout.positions, m.truth), 0.5);
  expect_placed_exactly(m, layout);
  EXPECT_TRUE(std::find(notes.begin(), notes.end(), "pair 1/20") != notes.end());
  EXPECT_TRUE(std::find(notes.begin(), notes.end(), "pair 20/20") != notes.end());
  const DataPtr merged = merge_tiles_in_memory(m.stitch, layout, o);
  const auto& v = dynamic_cast<const VolumeU16&>(*merged);
  ASSERT_EQ(v.dims(), m.original.dims());
  for (int64_t i = 0; i < v.size(); ++i) ASSERT_EQ(v.data()[i], m.original.data()[i]) << "voxel " << i;
}

TEST(StitchTiles, NoisyGridIsPlacedWithinHalfAVoxelAndMergedWithinTheNoise) {
  const double sigma = 30.0;  // 3% of the texture's range
  Mosaic m = make_mosaic(3, 3, sigma, 9);
  const StitchLayout layout = align_tiles(m.stitch, StitchOptions{});
  EXPECT_LT(max_relative_error(layout.positions, m.truth), 0.5);
  expect_placed_exactly(m, layout);
  const auto merged = merge_tiles_in_memory(m.stitch, layout, StitchOptions{});
  const auto& v = dynamic_cast<const VolumeU16&>(*merged);
  ASSERT_EQ(v.dims(), m.original.dims());
  double sum = 0.0, worst = 0.0;
  for (int64_t i = 0; i < v.size(); ++i) {
    const double d = std::abs(static_cast<double>(v.data()[i]) - static_cast<double>(m.original.data()[i]));
    sum += d;
    worst = std::max(worst, d);
  }
  EXPECT_LT(sum / static_cast<double>(v.size()), sigma);  // |N(0, σ)| has mean 0.8 σ; blending lowers it
  EXPECT_LT(worst, 7.0 * sigma);
}

TEST(StitchTiles, LeastSquaresBeatsChainingInconsistentPairs) {
  // A 4 × 4 grid with pairwise measurements off by up to ±0.4 voxel each, inconsistently: chaining
  // them from tile 0 accumulates the errors, the global fit averages them.
  const int g = 4;
  double ls_total = 0.0, chain_total = 0.0;
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> err(-0.4, 0.4);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<Vec3> truth, nominal;
    for (int j = 0; j < g; ++j)
      for (int i = 0; i < g; ++i) {
        truth.push_back({40.0 * i, 40.0 * j, 0.0});
        nominal.push_back({40.0 * i + 3.0, 40.0 * j - 2.0, 1.0});
      }
    std::vector<StitchPair> pairs;
    std::map<std::pair<int64_t, int64_t>, Vec3> measured;
    for (int j = 0; j < g; ++j)
      for (int i = 0; i < g; ++i)
        for (const auto& [di, dj] : {std::pair{1, 0}, std::pair{0, 1}}) {
          if (i + di >= g || j + dj >= g) continue;
          StitchPair p;
          p.a = j * g + i;
          p.b = (j + dj) * g + i + di;
          p.correlation = 0.9;
          for (size_t k = 0; k < 3; ++k)
            p.measured[k] = truth[static_cast<size_t>(p.b)][k] - truth[static_cast<size_t>(p.a)][k] + err(rng);
          measured[{p.a, p.b}] = p.measured;
          pairs.push_back(p);
        }
    const auto pos = solve_positions(nominal, pairs, 0);
    EXPECT_EQ(pos[0], nominal[0]);  // the fixed tile keeps its nominal position
    // Chaining: along row 0, then up every column.
    std::vector<Vec3> chain(truth.size(), nominal[0]);
    for (int j = 0; j < g; ++j)
      for (int i = 0; i < g; ++i) {
        if (i == 0 && j == 0) continue;
        const int64_t b = j * g + i, a = j == 0 ? b - 1 : b - g;
        for (size_t k = 0; k < 3; ++k) chain[static_cast<size_t>(b)][k] = chain[static_cast<size_t>(a)][k] + measured[{a, b}][k];
      }
    auto rms = [&](const std::vector<Vec3>& p) {
      double s = 0.0;
      for (size_t i = 0; i < p.size(); ++i)
        for (size_t k = 0; k < 3; ++k) {
          const double d = (p[i][k] - p[0][k]) - (truth[i][k] - truth[0][k]);
          s += d * d;
        }
      return std::sqrt(s / static_cast<double>(3 * p.size()));
    };
    ls_total += rms(pos);
    chain_total += rms(chain);
    // The residuals are those of the fitted positions.
    for (const auto& p : pairs)
      for (size_t k = 0; k < 3; ++k)
        EXPECT_NEAR(p.residual[k], pos[static_cast<size_t>(p.b)][k] - pos[static_cast<size_t>(p.a)][k] - p.measured[k], 1e-9);
  }
  EXPECT_LT(ls_total, 0.7 * chain_total) << "least squares " << ls_total / 20 << ", chaining " << chain_total / 20;
}

TEST(StitchTiles, LowCorrelationPairIsDroppedAndTheTileKeepsItsNominalPosition) {
  Mosaic m = make_mosaic(3, 1, 0.0, 13);
  const VolumeU16 other = textured_volume({64, 64, 32}, 99);  // tile 2 shows something else
  auto foreign = std::make_shared<VolumeU16>(other);
  m.stitch[2].read_box = [foreign](const Dims& b, const Dims& size) -> DataPtr {
    return std::make_shared<VolumeU16>(read_block<uint16_t>(*foreign, b, size, "tile"));
  };
  StitchOptions o;
  o.min_correlation = 0.8;
  const StitchLayout layout = align_tiles(m.stitch, o);
  ASSERT_EQ(layout.pairs.size(), 2u);
  EXPECT_EQ(layout.pairs[0].status, PairStatus::used);
  EXPECT_EQ(layout.pairs[1].status, PairStatus::low_correlation);
  EXPECT_LT(layout.pairs[1].correlation, 0.8);
  EXPECT_EQ(layout.unconnected, std::vector<int64_t>{2});
  EXPECT_EQ(layout.positions[2], m.stitch[2].position);
  const Table pairs = pair_table(m.stitch, layout);
  EXPECT_EQ(pairs.strings("status"), (std::vector<std::string>{"used", "low_correlation"}));
}

TEST(StitchTiles, MergeOntoDiskEqualsMergeInMemory) {
  Mosaic m = make_mosaic(2, 2, 10.0, 17, 24);
  const StitchLayout layout = align_tiles(m.stitch, StitchOptions{});
  const auto in_memory = merge_tiles_in_memory(m.stitch, layout, StitchOptions{});
  ChunkedVolume disk(layout.grid, layout.type_id,
                     create_volume_store(dir() / "merged.scratch.h5", layout.type_id, layout.grid, {16, 16, 16}));
  merge_tiles_into(m.stitch, layout, disk, {32, 32, 16}, StitchOptions{});
  const auto back = disk.read<uint16_t>({0, 0, 0}, layout.grid.dims);
  const auto& mem = dynamic_cast<const VolumeU16&>(*in_memory);
  ASSERT_EQ(back.dims(), mem.dims());
  for (int64_t i = 0; i < mem.size(); ++i) ASSERT_EQ(back.data()[i], mem.data()[i]) << "voxel " << i;
}

TEST(StitchTiles, CancelledBetweenPairs) {
  Mosaic m = make_mosaic(2, 2, 0.0, 3, 16);
  std::atomic<bool> cancel{true};
  StitchOptions o;
  o.interrupter = Interrupter([](double) {}, &cancel);
  EXPECT_THROW(align_tiles(m.stitch, o), Cancelled);
}

// ---------------------------------------------------------------- the module and its tile lists

namespace {

// Writes the tiles of `m` as NRRD files (spacing 0.5 µm) and a tile list with physical positions.
fs::path write_tile_list(const Mosaic& m, const std::string& name, const std::string& extra_line = {}) {
  const fs::path d = dir() / name;
  fs::remove_all(d);
  fs::create_directories(d);
  std::ofstream list(d / "tiles.csv");
  list << "file,x,y,z\n# stage positions in µm\n";
  for (size_t i = 0; i < m.tiles.size(); ++i) {
    VolumeU16 t = *m.tiles[i];
    t.set_spacing({0.5, 0.5, 0.5});
    const std::string f = m.stitch[i].name + ".nrrd";
    io::write_any_volume(d / f, t);
    list << f << "," << m.stitch[i].position[0] * 0.5 << "," << m.stitch[i].position[1] * 0.5 << ","
         << m.stitch[i].position[2] * 0.5 << "\n";
  }
  list << extra_line;
  return d / "tiles.csv";
}

std::string run_error(const fs::path& list) {
  try {
    run_module("registration.stitch_tiles", {}, {{"tile_list", ParamValue(list.string())}});
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(StitchTilesModule, StitchesATileListOfFiles) {
  Mosaic m = make_mosaic(3, 2, 0.0, 31, 20);
  const fs::path list = write_tile_list(m, "ok");
  auto r = run_module("registration.stitch_tiles", {}, {{"tile_list", ParamValue(list.string())}}, {.threads = 2});
  const auto v = r.get<VolumeU16>("volume");
  ASSERT_EQ(v->dims(), m.original.dims());
  EXPECT_EQ(v->spacing(), (Vec3{0.5, 0.5, 0.5}));
  for (int64_t i = 0; i < v->size(); ++i) ASSERT_EQ(v->data()[i], m.original.data()[i]) << "voxel " << i;
  const auto tiles = r.get<Table>("tiles");
  EXPECT_EQ(tiles->rows(), 6);
  EXPECT_EQ(tiles->strings("file")[4], "tile_1_1.nrrd");
  EXPECT_EQ(tiles->column("x").unit, "µm");
  for (int64_t i = 0; i < 6; ++i) {
    // refined positions relative to tile 0 within half a voxel (0.25 µm) of the truth
    EXPECT_NEAR(tiles->reals("x")[static_cast<size_t>(i)] - tiles->reals("x")[0], 0.5 * m.truth[static_cast<size_t>(i)][0], 0.25);
    EXPECT_NEAR(tiles->reals("y")[static_cast<size_t>(i)] - tiles->reals("y")[0], 0.5 * m.truth[static_cast<size_t>(i)][1], 0.25);
  }
  const auto pairs = r.get<Table>("pairs");
  EXPECT_EQ(pairs->rows(), 11);  // 4 + 3 edge neighbours, 4 diagonal (corner overlaps)
  for (double c : pairs->reals("correlation")) EXPECT_GT(c, 0.99);
}

TEST(StitchTilesModule, TileListErrorsNameTheLineAndTheTile) {
  Mosaic m = make_mosaic(2, 1, 0.0, 41, 16);
  {
    const std::string e = run_error(write_tile_list(m, "missing", "gone.nrrd,0,0,0\n"));
    EXPECT_NE(e.find("tiles.csv:5: tile 'gone.nrrd'"), std::string::npos) << e;
  }
  {
    const std::string e = run_error(write_tile_list(m, "fields", "tile_0_0.nrrd,0,0\n"));
    EXPECT_NE(e.find("tiles.csv:5: expected 4 fields (file,x,y,z), got 3"), std::string::npos) << e;
  }
  {
    const std::string e = run_error(write_tile_list(m, "number", "tile_0_0.nrrd,0,zero,0\n"));
    EXPECT_NE(e.find("tiles.csv:5: y position 'zero' is not a finite number"), std::string::npos) << e;
  }
  {  // a third tile far away
    const std::string e = run_error(write_tile_list(m, "apart", "tile_0_0.nrrd,500,0,0\n"));
    EXPECT_NE(e.find("tiles.csv:5: tile 'tile_0_0.nrrd' overlaps no other tile"), std::string::npos) << e;
  }
  {  // mixed voxel types
    const fs::path list = write_tile_list(m, "types", "u8.nrrd,10,0,0\n");
    io::write_any_volume(list.parent_path() / "u8.nrrd", VolumeU8({64, 64, 16}, 1, {0.5, 0.5, 0.5}));
    const std::string e = run_error(list);
    EXPECT_NE(e.find("tiles.csv:5: tile 'u8.nrrd' holds volume.u8 voxels, but tiles.csv:3: tile 'tile_0_0.nrrd' holds volume.u16"),
              std::string::npos) << e;
  }
  {  // mixed spacing
    const fs::path list = write_tile_list(m, "spacing", "coarse.nrrd,10,0,0\n");
    io::write_any_volume(list.parent_path() / "coarse.nrrd", VolumeU16({64, 64, 16}, 1, {1.0, 0.5, 0.5}));
    const std::string e = run_error(list);
    EXPECT_NE(e.find("tiles.csv:5: tile 'coarse.nrrd' has spacing (1, 0.5, 0.5), but tiles.csv:3: tile 'tile_0_0.nrrd' has (0.5, 0.5, 0.5)"),
              std::string::npos) << e;
  }
}
