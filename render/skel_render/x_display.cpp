// Whether the X display named by DISPLAY accepts a connection. On its own so that Xlib's macros
// (None, Status, Bool) stay out of the VTK code.
#include <X11/Xlib.h>

namespace skel::render::detail {

bool can_open_x_display() {
  Display* d = XOpenDisplay(nullptr);
  if (!d) return false;
  XCloseDisplay(d);
  return true;
}

}  // namespace skel::render::detail
