#include "offscreen.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <vtkImageData.h>
#include <vtkPNGWriter.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkScalarBarActor.h>
#include <vtkUnsignedCharArray.h>
#include <vtkWindowToImageFilter.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "skel/error.hpp"
#include "skel/fs.hpp"

extern char** environ;

namespace skel::render {
namespace detail {
bool can_open_x_display();  // x_display.cpp
}  // namespace detail
namespace {

// The private Xvfb of the rendering in progress, stopped when the process aborts (VTK aborts on X
// errors), so that no server is left behind.
std::atomic<pid_t> g_xvfb_pid{-1};
extern "C" void stop_xvfb_on_abort(int sig) {
  const pid_t p = g_xvfb_pid.load();
  if (p > 0) kill(p, SIGTERM);
  signal(sig, SIG_DFL);
  raise(sig);
}

// A private Xvfb for the time of one rendering when DISPLAY is not set (VTK 9.1 on Debian has no
// OSMesa/EGL back end: every render window is an X window, off-screen ones included).
class PrivateXServer {
public:
  PrivateXServer(int width, int height) {
    const char* d = std::getenv("DISPLAY");
    // The user's display (or xvfb-run's) when it answers; a stale one (e.g. from an ended ssh -X
    // session) would make VTK abort, so then a private server is used instead.
    if (d && *d && detail::can_open_x_display()) return;
    if (d) old_display_ = d;
    for (int attempt = 0; attempt < 5; ++attempt)
      if (start(width, height)) return;
    throw Error("render: no X display (DISPLAY is not set or does not answer) and the private Xvfb did not start; "
                "run under xvfb-run");
  }
  ~PrivateXServer() { stop(); }
  PrivateXServer(const PrivateXServer&) = delete;
  PrivateXServer& operator=(const PrivateXServer&) = delete;

private:
  // Starts Xvfb and points DISPLAY at it; false (nothing left running) when it did not come up.
  bool start(int width, int height) {
    int fds[2];
    if (pipe(fds) != 0) throw Error(std::string("render: cannot start Xvfb: pipe: ") + std::strerror(errno));
    const std::string fd = std::to_string(fds[1]);
    const std::string screen = std::to_string(std::max(width, 64)) + "x" + std::to_string(std::max(height, 64)) + "x24";
    // -noreset: an X server resets when its last client leaves, and refuses connections meanwhile; the
    // check below is such a client, VTK connects right after it.
    std::vector<std::string> args = {"Xvfb", "-displayfd", fd, "-screen", "0", screen, "-nolisten", "tcp", "-noreset"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addclose(&actions, fds[0]);
    posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
    const int rc = posix_spawnp(&pid_, "Xvfb", &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    close(fds[1]);
    if (rc != 0) {
      close(fds[0]);
      pid_ = -1;
      throw Error(std::string("render: no X display (DISPLAY is not set or does not answer) and Xvfb cannot be started (") +
                  std::strerror(rc) +
                  "): this VTK renders through X/GLX only (no OSMesa or EGL back end), so off-screen "
                  "rendering needs an X server; install Xvfb (Debian: xvfb) or run under xvfb-run");
    }
    // Xvfb writes its display number to the pipe once it accepts connections.
    std::string number;
    pollfd p{fds[0], POLLIN, 0};
    while (poll(&p, 1, 20000) > 0) {
      char buf[16];
      const ssize_t n = read(fds[0], buf, sizeof buf);
      if (n <= 0) break;
      number.append(buf, static_cast<size_t>(n));
      if (number.find('\n') != std::string::npos) break;
    }
    close(fds[0]);
    while (!number.empty() && (number.back() == '\n' || number.back() == ' ')) number.pop_back();
    if (number.empty() || number.find_first_not_of("0123456789") != std::string::npos) {
      stop();
      return false;
    }
    setenv("DISPLAY", (":" + number).c_str(), 1);
    set_display_ = true;
    g_xvfb_pid.store(pid_);
    static const bool handler = [] {
      struct sigaction sa {};
      sa.sa_handler = stop_xvfb_on_abort;
      sigemptyset(&sa.sa_mask);
      return sigaction(SIGABRT, &sa, nullptr) == 0;
    }();
    (void)handler;
    // Another server started at the same moment (xvfb-run -a, a second render) can take the number
    // this one reported: then it does not answer, and a new one is started.
    if (detail::can_open_x_display()) return true;
    stop();
    return false;
  }

  void stop() {
    if (set_display_) {
      if (old_display_.empty()) unsetenv("DISPLAY");
      else setenv("DISPLAY", old_display_.c_str(), 1);
    }
    set_display_ = false;
    if (pid_ <= 0) return;
    g_xvfb_pid.store(-1);
    kill(pid_, SIGTERM);
    int status = 0;
    while (waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
    }
    pid_ = -1;
  }
  pid_t pid_ = -1;
  bool set_display_ = false;
  std::string old_display_;
};

}  // namespace

Image render_image(const std::vector<Display*>& displays, const RenderOptions& options) {
  if (options.width < 16 || options.height < 16 || options.width > 16384 || options.height > 16384)
    throw InputError("render: image size " + std::to_string(options.width) + "x" + std::to_string(options.height) +
                     " is outside 16..16384 pixels per side");
  PrivateXServer x(options.width, options.height);
  Image out;
  {
    auto window = vtkSmartPointer<vtkRenderWindow>::New();
    window->SetOffScreenRendering(1);
    window->SetSize(options.width, options.height);
    window->SetMultiSamples(0);
    auto renderer = vtkSmartPointer<vtkRenderer>::New();
    setup_renderer(renderer);
    window->AddRenderer(renderer);
    auto bar = make_scalar_bar(renderer);
    bool uses_bar = false;
    for (Display* d : displays) {
      for (auto& p : d->build_props(bar)) renderer->AddViewProp(p);
      uses_bar |= d->uses_scalar_bar();
    }
    bar->SetVisibility(uses_bar);
    if (!window->SupportsOpenGL())
      throw Error("render: OpenGL 3.2 is not available on display '" + std::string(std::getenv("DISPLAY") ? std::getenv("DISPLAY") : "") +
                  "' (with Mesa, LIBGL_ALWAYS_SOFTWARE=1 gives a software renderer)");
    set_camera(renderer, options.camera);
    window->Render();
    auto w2i = vtkSmartPointer<vtkWindowToImageFilter>::New();
    w2i->SetInput(window);
    w2i->SetInputBufferTypeToRGB();
    w2i->ReadFrontBufferOff();
    w2i->Update();
    vtkImageData* img = w2i->GetOutput();
    int dims[3];
    img->GetDimensions(dims);
    const int comps = img->GetNumberOfScalarComponents();
    if (dims[0] != options.width || dims[1] != options.height || comps < 3)
      throw Error("render: the off-screen window gave a " + std::to_string(dims[0]) + "x" + std::to_string(dims[1]) +
                  " image, not " + std::to_string(options.width) + "x" + std::to_string(options.height));
    out.width = dims[0];
    out.height = dims[1];
    out.rgb.resize(static_cast<size_t>(out.width) * static_cast<size_t>(out.height) * 3);
    const auto* src = static_cast<const unsigned char*>(img->GetScalarPointer());
    for (int y = 0; y < out.height; ++y) {
      uint8_t* dst = out.rgb.data() + static_cast<size_t>(out.height - 1 - y) * static_cast<size_t>(out.width) * 3;
      const unsigned char* row = src + static_cast<size_t>(y) * static_cast<size_t>(out.width) * static_cast<size_t>(comps);
      for (int x0 = 0; x0 < out.width; ++x0)
        for (int c = 0; c < 3; ++c) dst[3 * x0 + c] = row[comps * x0 + c];
    }
    window->Finalize();  // closes the X connection before the private server goes
  }
  return out;
}

void write_png(const Image& image, const std::filesystem::path& path) {
  auto img = vtkSmartPointer<vtkImageData>::New();
  img->SetDimensions(image.width, image.height, 1);
  img->AllocateScalars(VTK_UNSIGNED_CHAR, 3);
  auto* dst = static_cast<unsigned char*>(img->GetScalarPointer());
  const size_t row = static_cast<size_t>(image.width) * 3;
  for (int y = 0; y < image.height; ++y)  // VTK rows go bottom-up
    std::memcpy(dst + static_cast<size_t>(y) * row, image.rgb.data() + static_cast<size_t>(image.height - 1 - y) * row, row);
  auto writer = vtkSmartPointer<vtkPNGWriter>::New();
  writer->SetInputData(img);
  writer->WriteToMemoryOn();
  writer->Write();
  vtkUnsignedCharArray* bytes = writer->GetResult();
  if (!bytes || bytes->GetNumberOfTuples() == 0) throw Error("cannot encode " + path.string() + " as PNG");
  write_file_atomically(path, std::string(reinterpret_cast<const char*>(bytes->GetPointer(0)),
                                          static_cast<size_t>(bytes->GetNumberOfTuples())));
}

}  // namespace skel::render
