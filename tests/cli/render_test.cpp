// `skelflow render` (issue 20): a small pipeline's graph, mesh and volume drawn off-screen into PNGs
// of the asked size that show the objects (not a blank background), and the errors that name the
// node/port. The child runs without DISPLAY, so the command's private Xvfb is what renders here.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <vtkImageData.h>
#include <vtkPNGReader.h>
#include <vtkSmartPointer.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

struct Result {
  int code = -1;
  std::string out;
};

// The child runs without DISPLAY, or with `display` as DISPLAY.
Result run(const std::vector<std::string>& args, const char* display = nullptr) {
  fs::path log = fs::temp_directory_path() / ("skel_render_" + std::to_string(getpid()) + ".log");
  pid_t pid = fork();
  if (pid == 0) {
    FILE* f = std::freopen(log.c_str(), "w", stdout);
    (void)f;
    dup2(fileno(stdout), fileno(stderr));
    if (display) setenv("DISPLAY", display, 1);
    else unsetenv("DISPLAY");
    std::vector<char*> argv;
    std::string bin = SKELFLOW_BIN;
    argv.push_back(bin.data());
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(bin.c_str(), argv.data());
    _exit(127);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  Result r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  r.out = ss.str();
  fs::remove(log);
  return r;
}

bool have_xvfb() { return std::system("command -v Xvfb >/dev/null 2>&1") == 0; }

fs::path scratch(const std::string& name) {
  fs::path d = fs::path(SKEL_BINARY_DIR) / "tests" / "render_scratch" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// Mixed rods and plates, skeleton, graph (with radius) and mesh (with the manifold class); `never`
// writes a file that rendering must not produce (it is not upstream of what is drawn).
constexpr const char* kPipeline = R"(skelflow: 1
nodes:
  phantom: {module: synthetic.network, params: {shape: mixed, size: [48, 48, 48], seed: 3}}
  seg: {module: segmentation.threshold, inputs: {image: phantom.image}, params: {method: manual, low: 0.5}}
  distance: {module: distance.euclidean, inputs: {mask: seg.mask}}
  skeleton: {module: thinning.doht, inputs: {mask: seg.mask, priority: distance.distance}, params: {end_point_length: 2}}
  graph: {module: geometry.skeleton_to_graph, inputs: {skeleton: skeleton.skeleton, distance: distance.distance}}
  mesh: {module: geometry.skeleton_to_mesh, inputs: {skeleton: skeleton.skeleton}}
  topology: {module: analysis.topology, inputs: {mask: skeleton.skeleton}}
  never: {module: io.write_graph, inputs: {graph: graph.graph}, params: {path: never.vtp}}
)";

fs::path pipeline(const fs::path& d) {
  fs::path p = d / "p.yaml";
  std::ofstream(p) << kPipeline;
  return p;
}

struct Png {
  int width = 0, height = 0;
  std::vector<unsigned char> rgb;  // bottom-up rows, as VTK reads them
};

Png read_png(const fs::path& f) {
  auto r = vtkSmartPointer<vtkPNGReader>::New();
  r->SetFileName(f.c_str());
  r->Update();
  vtkImageData* img = r->GetOutput();
  int dims[3];
  img->GetDimensions(dims);
  Png p;
  p.width = dims[0];
  p.height = dims[1];
  const int comps = img->GetNumberOfScalarComponents();
  const auto* src = static_cast<const unsigned char*>(img->GetScalarPointer());
  for (int i = 0; i < p.width * p.height; ++i)
    for (int c = 0; c < 3; ++c) p.rgb.push_back(src[i * comps + std::min(c, comps - 1)]);
  return p;
}

// Pixels that differ from their row's background (the view's vertical gradient, read at the left
// edge, which the fitted camera leaves empty) by more than 40 in some channel.
double object_fraction(const Png& p) {
  int64_t n = 0;
  for (int y = 0; y < p.height; ++y) {
    const unsigned char* row = p.rgb.data() + static_cast<size_t>(y) * p.width * 3;
    for (int x = 0; x < p.width; ++x) {
      int d = 0;
      for (int c = 0; c < 3; ++c) d = std::max(d, std::abs(int(row[3 * x + c]) - int(row[c])));
      n += d > 40;
    }
  }
  return static_cast<double>(n) / (static_cast<double>(p.width) * p.height);
}

double variance(const Png& p) {
  double s = 0, s2 = 0;
  for (unsigned char v : p.rgb) {
    s += v;
    s2 += double(v) * v;
  }
  const double n = static_cast<double>(p.rgb.size());
  return s2 / n - (s / n) * (s / n);
}

// Pixels coloured like the rainbow's ends (blue: low values; red: high): attribute colouring is on.
int64_t saturated_pixels(const Png& p) {
  int64_t n = 0;
  for (size_t i = 0; i + 2 < p.rgb.size(); i += 3) {
    const int r = p.rgb[i], g = p.rgb[i + 1], b = p.rgb[i + 2];
    n += (b > 120 && b > r + 60 && b > g + 20) || (r > 120 && r > g + 60 && r > b + 60);
  }
  return n;
}

}  // namespace

TEST(Render, GraphAndMeshToPngOfTheAskedSize) {
  if (!have_xvfb()) GTEST_SKIP() << "Xvfb is not installed (package xvfb)";
  fs::path d = scratch("graph_mesh");
  fs::path p = pipeline(d);
  Result g = run({"render", p.string(), "--node", "graph.graph", "-o", (d / "graph.png").string(), "--size", "320x240"});
  ASSERT_EQ(g.code, 0) << g.out;
  EXPECT_NE(g.out.find("wrote"), std::string::npos) << g.out;
  Png gp = read_png(d / "graph.png");
  EXPECT_EQ(gp.width, 320);
  EXPECT_EQ(gp.height, 240);
  EXPECT_GT(variance(gp), 50.0);
  EXPECT_GT(object_fraction(gp), 0.01);      // the network is drawn ...
  EXPECT_LT(object_fraction(gp), 0.9);       // ... inside a background
  EXPECT_GT(saturated_pixels(gp), 100);      // tubes coloured by radius, as the GUI does

  Result m = run({"render", p.string(), "--node", "mesh.mesh", "-o", (d / "mesh.png").string(), "--size", "300x200",
                  "--color-by", "manifold", "--camera", "z", "--quiet"});
  ASSERT_EQ(m.code, 0) << m.out;
  EXPECT_EQ(m.out, "");
  Png mp = read_png(d / "mesh.png");
  EXPECT_EQ(mp.width, 300);
  EXPECT_EQ(mp.height, 200);
  EXPECT_GT(variance(mp), 50.0);
  EXPECT_GT(object_fraction(mp), 0.01);
  EXPECT_GT(saturated_pixels(mp), 50);
  // Only what the drawn nodes need ran: the writer downstream of the graph wrote nothing.
  EXPECT_FALSE(fs::exists(d / "never.vtp"));
}

TEST(Render, OverlayDrawsMoreThanOneObject) {
  if (!have_xvfb()) GTEST_SKIP() << "Xvfb is not installed (package xvfb)";
  fs::path d = scratch("overlay");
  fs::path p = pipeline(d);
  Result a = run({"render", p.string(), "--node", "graph.graph", "-o", (d / "graph.png").string(), "--size", "256x256",
                  "--camera", "x"});
  ASSERT_EQ(a.code, 0) << a.out;
  Result b = run({"render", p.string(), "--node", "graph.graph", "--node", "seg.mask", "-o", (d / "both.png").string(),
                  "--size", "256x256", "--camera", "x"});
  ASSERT_EQ(b.code, 0) << b.out;
  const double alone = object_fraction(read_png(d / "graph.png"));
  const double both = object_fraction(read_png(d / "both.png"));
  EXPECT_GT(both, alone + 0.02) << "the mask's voxel surface adds to the graph: " << alone << " vs " << both;
}

TEST(Render, AStaleDisplayFallsBackToAPrivateServer) {
  // VTK's X window aborts the process on a display that does not answer (an ended ssh -X session).
  if (!have_xvfb()) GTEST_SKIP() << "Xvfb is not installed (package xvfb)";
  fs::path d = scratch("stale_display");
  fs::path p = pipeline(d);
  Result r = run({"render", p.string(), "--node", "graph.graph", "-o", (d / "g.png").string(), "--size", "64x64"}, ":4771");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(read_png(d / "g.png").width, 64);
}

TEST(Render, ErrorsNameTheNodeAndPortAndLeaveNoFile) {
  fs::path d = scratch("errors");
  fs::path p = pipeline(d);
  const std::string out = (d / "x.png").string();
  auto expect_error = [&](const std::vector<std::string>& args, const std::string& needle) {
    std::vector<std::string> a = {"render", p.string()};
    a.insert(a.end(), args.begin(), args.end());
    Result r = run(a);
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.out.find(needle), std::string::npos) << "expected '" << needle << "' in: " << r.out;
    EXPECT_FALSE(fs::exists(out));
  };
  expect_error({"--node", "grahp.graph", "-o", out}, "no node 'grahp' in");
  expect_error({"--node", "grahp.graph", "-o", out}, "did you mean 'graph'");
  expect_error({"--node", "graph.grpah", "-o", out}, "node 'graph' (geometry.skeleton_to_graph) has no output 'grpah'");
  expect_error({"--node", "graph.grpah", "-o", out}, "its outputs: graph");
  expect_error({"--node", "topology.table", "-o", out}, "render draws volumes, graphs and meshes");
  expect_error({"--node", "graph", "-o", out}, "--node graph: expected NODE.PORT");
  expect_error({"--node", "graph.graph", "-o", (d / "x.jpg").string()}, "give a file ending in .png");
  expect_error({"--node", "graph.graph", "-o", out, "--camera", "top"}, "--camera top: expected one of iso, x, y, z");
  expect_error({"--node", "graph.graph", "-o", out, "--size", "10x10"}, "--size 10x10");
  expect_error({"--node", "graph.graph", "-o", out, "--colour-by", "radius"}, "did you mean '--color-by'");
  expect_error({"-o", out}, "no --node");
  if (have_xvfb()) {
    expect_error({"--node", "graph.graph", "-o", out, "--color-by", "radios"},
                 "--color-by radios: graph.graph (graph) has no attribute 'radios' (did you mean 'radius'?)");
    expect_error({"--node", "seg.mask", "-o", out, "--color-by", "radius"}, "no --node is one");
  }
}

TEST(Render, HelpListsTheOptions) {
  Result r = run({"render", "--help"});
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* o : {"--node", "--size", "--color-by", "--camera", "xvfb"}) EXPECT_NE(r.out.find(o), std::string::npos) << o;
  Result all = run({"--help"});
  EXPECT_NE(all.out.find("render PIPELINE --node NODE.PORT"), std::string::npos) << all.out;
}
