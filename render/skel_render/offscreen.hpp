#pragma once
// `skelflow render`: Displays (display.hpp) drawn off-screen into an image with the GUI 3D view's
// look (background, colours, scalar bar, camera presets), saved as PNG.
//
// Debian's VTK 9.1 renders through X11/GLX only (built without OSMesa and EGL), so even an
// off-screen window needs an X server. Without DISPLAY, render_image() starts a private Xvfb (when
// it is installed) for the time of the rendering, so the command works on a headless cluster node.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "display.hpp"

namespace skel::render {

struct RenderOptions {
  int width = 1280, height = 800;
  CameraPreset camera = CameraPreset::Iso;
};

// 8-bit RGB, rows top to bottom.
struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;
};

// Draws `displays` (in this order, each with its own settings) off-screen. Throws Error when no
// X display can be had or OpenGL is unavailable, saying what to install or set.
Image render_image(const std::vector<Display*>& displays, const RenderOptions& options);

// Writes `image` as PNG through write_atomically (no partial file on failure).
void write_png(const Image& image, const std::filesystem::path& path);

}  // namespace skel::render
