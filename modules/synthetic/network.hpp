#pragma once
// Synthetic test objects (thesis ch. 4, fig. 4.1): rods, plates, spheres and mixtures drawn on a
// grid, smoothed by a separable Gaussian, optional noise at two frequencies, thresholded at 0.5. Reproducible from `seed`; the
// result never depends on the thread count (all randomness comes from a counter-based hash).
#include <cstdint>
#include <string>

#include "skel/enum_names.hpp"
#include "skel/interrupter.hpp"
#include "skel/volume.hpp"

namespace skel::synthetic {

enum class Shape { rods, plates, spheres, mixed };
constexpr auto enum_names(Shape) {
  return std::to_array<EnumName<Shape>>(
      {{Shape::rods, "rods"}, {Shape::plates, "plates"}, {Shape::spheres, "spheres"}, {Shape::mixed, "mixed"}});
}

struct NetworkOptions {
  Shape shape = Shape::rods;
  Dims size{128, 128, 128};
  uint64_t seed = 1;
  double noise = 0.0;            // amplitude of the two-frequency noise, 0..1
  Vec3 spacing{1, 1, 1};         // physical voxel size (only stored in the output grids)
  std::string unit = kDefaultUnit;  // physical unit of spacing (stored in the output grids)
  double period = 24;            // lattice cell size: distance between neighbouring elements, voxels
  double radius = 2.0;           // rod radius (each rod varies ±20 %); balls are 1.5..(0.35·period − 1.5)
  double plate_thickness = 3.0;  // plate thickness, voxels
  double sigma = 1.0;            // Gaussian smoothing of the drawn object, voxels (0 = none)
  double threshold = 0.5;        // mask = image > threshold
  int threads = 0;
  Interrupter interrupter;
};

struct NetworkResult {
  VolumeF32 image;  // smoothed drawing in [0, 1] plus noise; `threshold` is the object boundary
  VolumeU8 mask;    // image > threshold (0/1)
};

NetworkResult make_network(const NetworkOptions& options);

// Adds noise of amplitude `amplitude` (0..1) at two frequencies: smooth value noise on a 16-voxel
// lattice (±0.35·amplitude) and independent per-voxel noise (±0.25·amplitude). Depends only on the
// seed and the voxel position, never on the thread count.
void add_two_frequency_noise(VolumeF32& image, uint64_t seed, double amplitude, int threads);

// Counter-based hash of (seed, a, b, c) -> uniform double in [0, 1).
double hash_uniform(uint64_t seed, int64_t a, int64_t b, int64_t c);

}  // namespace skel::synthetic
