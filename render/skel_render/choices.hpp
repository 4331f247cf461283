#pragma once
// The named display choices of skel_render, header-only and without VTK so that the command line
// parses them (and `skelflow render --help` lists them) even when VTK's rendering is absent.
#include "skel/enum_names.hpp"

namespace skel::render {

enum class VolumeMode { Slices, Mip, IsoSurface, VolumeRendering, VoxelSurface };
constexpr auto enum_names(VolumeMode) {
  return std::to_array<EnumName<VolumeMode>>({{VolumeMode::Slices, "slices"},
                                              {VolumeMode::Mip, "mip"},
                                              {VolumeMode::IsoSurface, "iso"},
                                              {VolumeMode::VolumeRendering, "volume"},
                                              {VolumeMode::VoxelSurface, "voxels"}});
}

enum class CameraPreset { Iso, X, Y, Z };
constexpr auto enum_names(CameraPreset) {
  return std::to_array<EnumName<CameraPreset>>(
      {{CameraPreset::Iso, "iso"}, {CameraPreset::X, "x"}, {CameraPreset::Y, "y"}, {CameraPreset::Z, "z"}});
}

}  // namespace skel::render
