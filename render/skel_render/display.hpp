#pragma once
// How Skelflow draws its data objects with VTK: one Display class per data type (volume, spatial
// graph, mesh) holding the data, its display settings and the VTK props that draw it, plus the scene
// both the GUI's 3D view and `skelflow render` use (background, scalar bar, object colours, camera
// presets). No Qt here: the GUI wraps each Display in a Representation that adds its side-panel page
// (gui/views/), the CLI renders Displays off-screen (offscreen.hpp). One look, defined once.
#include <vtkSmartPointer.h>

#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "skel/data.hpp"
#include "skel_render/choices.hpp"
#include "skel/mesh.hpp"
#include "skel/spatial_graph.hpp"

class vtkActor;
class vtkImageData;
class vtkPolyData;
class vtkProp;
class vtkRenderer;
class vtkScalarBarActor;

namespace skel::render {

using Color = std::array<double, 3>;

// The colour of the i-th object shown (cycling through six).
const Color& palette_color(size_t i);

class Display {
public:
  Display(DataPtr data, const Color& color) : data_(std::move(data)), color_(color) {}
  virtual ~Display();
  Display(const Display&) = delete;
  Display& operator=(const Display&) = delete;

  [[nodiscard]] const DataPtr& data() const { return data_; }
  [[nodiscard]] const Color& color() const { return color_; }
  void set_color(const Color& c) { color_ = c; }

  // The props that draw the data with the current settings. A display that colours by a value
  // range sets `bar`'s lookup table and title and shows it.
  [[nodiscard]] virtual std::vector<vtkSmartPointer<vtkProp>> build_props(vtkScalarBarActor* bar) = 0;
  // True while the scalar bar shows this object's colours.
  [[nodiscard]] virtual bool uses_scalar_bar() const { return false; }
  // What set_color_by() accepts (empty for types that colour by no attribute).
  [[nodiscard]] virtual std::vector<std::string> color_choices() const { return {}; }
  // Colour by an attribute (one of color_choices(), or for meshes the bare attribute name); empty:
  // the plain colour. False (nothing changed) when the object has no such attribute.
  virtual bool set_color_by(const std::string& attribute) {
    (void)attribute;
    return false;
  }
  // Takes the type's own settings from `old` when it shows the same kind of data (new data for a
  // shown object after a re-run keeps how it was displayed); `old` may be of another type.
  virtual void keep_settings(const Display& old) = 0;

private:
  DataPtr data_;
  Color color_;
};

// ------------------------------------------------------------------ volumes
// Inside a thin outline of its grid: three orthogonal slices with window/level, maximum-intensity
// projection, iso-surface, volume rendering, or voxel surface (the default for binary masks and
// skeletons; slices otherwise).
class VolumeDisplay final : public Display {
public:
  // Null if `data` is not a volume.
  static std::unique_ptr<VolumeDisplay> create(const DataPtr& data, const Color& color);
  ~VolumeDisplay() override;

  [[nodiscard]] VolumeMode mode() const { return mode_; }
  void set_mode(VolumeMode mode) { mode_ = mode; }
  [[nodiscard]] double window() const { return window_; }
  [[nodiscard]] double level() const { return level_; }
  void set_window_level(double window, double level);
  [[nodiscard]] double iso_value() const { return iso_; }
  void set_iso_value(double value) { iso_ = value; }
  [[nodiscard]] int slice(int axis) const { return slice_[axis]; }
  void set_slice(int axis, int index) { slice_[axis] = index; }
  [[nodiscard]] const int* extent() const { return extent_; }
  [[nodiscard]] const double* range() const { return range_; }

  [[nodiscard]] std::vector<vtkSmartPointer<vtkProp>> build_props(vtkScalarBarActor* bar) override;
  void keep_settings(const Display& old) override;

private:
  VolumeDisplay(const DataPtr& data, const Color& color, vtkSmartPointer<vtkImageData> image);

  vtkSmartPointer<vtkImageData> image_;
  bool binary_ = false;
  double range_[2] = {0, 1};
  int extent_[6] = {0, 0, 0, 0, 0, 0};
  VolumeMode mode_ = VolumeMode::Slices;
  double window_ = 1, level_ = 0.5, iso_ = 0.5;
  int slice_[3] = {0, 0, 0};
  vtkSmartPointer<vtkActor> outline_;
  // Surfaces are costly to extract: kept while their inputs stay the same.
  vtkSmartPointer<vtkActor> surface_;
  double surface_iso_ = std::nan("");
  vtkSmartPointer<vtkActor> voxels_;
};

// ------------------------------------------------------------------ spatial graphs
enum class GraphMode { Lines, Tubes };

// Lines or tubes (radius attribute x scale), plain or coloured by any point/edge attribute. Tubes
// coloured by radius when the graph has a radius attribute, else plain lines.
class GraphDisplay final : public Display {
public:
  GraphDisplay(const std::shared_ptr<const SpatialGraph>& graph, const Color& color);
  ~GraphDisplay() override;

  [[nodiscard]] GraphMode mode() const { return mode_; }
  void set_mode(GraphMode mode) { mode_ = mode; }
  [[nodiscard]] const std::string& color_by() const { return color_by_; }
  [[nodiscard]] double tube_scale() const { return tube_scale_; }
  void set_tube_scale(double s) { tube_scale_ = s; }
  [[nodiscard]] const SpatialGraph& graph() const { return *graph_; }

  [[nodiscard]] std::vector<vtkSmartPointer<vtkProp>> build_props(vtkScalarBarActor* bar) override;
  [[nodiscard]] bool uses_scalar_bar() const override { return !color_by_.empty(); }
  [[nodiscard]] std::vector<std::string> color_choices() const override;
  bool set_color_by(const std::string& attribute) override;
  void keep_settings(const Display& old) override;

private:
  std::shared_ptr<const SpatialGraph> graph_;
  vtkSmartPointer<vtkPolyData> poly_;
  GraphMode mode_ = GraphMode::Lines;
  std::string color_by_;
  double tube_scale_ = 1.0;
};

// ------------------------------------------------------------------ meshes
// Triangles as a surface, lines as lines or tubes, plain or coloured by any vertex, triangle or line
// attribute ("vertex:NAME", "triangle:NAME", "line:NAME"); by default by the triangles' `manifold`
// class (all-manifold / not-all-manifold) when the mesh has it (thesis §3.1.3, figs. 6.7-6.14).
class MeshDisplay final : public Display {
public:
  MeshDisplay(const std::shared_ptr<const Mesh>& mesh, const Color& color);
  ~MeshDisplay() override;

  [[nodiscard]] const std::string& color_by() const { return color_by_; }
  [[nodiscard]] bool tubes() const { return tubes_; }
  void set_tubes(bool tubes) { tubes_ = tubes; }
  [[nodiscard]] double tube_radius() const { return tube_radius_; }
  void set_tube_radius(double r) { tube_radius_ = r; }
  [[nodiscard]] const Mesh& mesh() const { return *mesh_; }

  [[nodiscard]] std::vector<vtkSmartPointer<vtkProp>> build_props(vtkScalarBarActor* bar) override;
  // True when the last build_props() coloured by an attribute (a part of the mesh has it).
  [[nodiscard]] bool uses_scalar_bar() const override { return coloured_; }
  [[nodiscard]] std::vector<std::string> color_choices() const override;
  // Also takes a bare NAME: the first of triangle:, line:, vertex: the mesh has.
  bool set_color_by(const std::string& attribute) override;
  void keep_settings(const Display& old) override;

private:
  std::shared_ptr<const Mesh> mesh_;
  vtkSmartPointer<vtkPolyData> surface_, lines_;
  std::string color_by_;
  bool tubes_ = true;
  double tube_radius_ = 1.0;  // in the mesh's unit; set from its size
  bool coloured_ = false;
};

// The display for `data`: a graph, a mesh, else a volume. Throws InputError naming the type for other
// data (tables, landmarks, ...).
std::unique_ptr<Display> make_display(const DataPtr& data, const Color& color);
// True for the type ids (skel::type_ids) make_display() shows: volumes, graphs, meshes.
bool displayable_type(const std::string& type_id);

// ------------------------------------------------------------------ the scene
// The 3D view's background (a dark vertical gradient) on `renderer`.
void setup_renderer(vtkRenderer* renderer);
// The shared scalar bar (hidden until a display colours by an attribute), added to `renderer`.
vtkSmartPointer<vtkScalarBarActor> make_scalar_bar(vtkRenderer* renderer);

// Fits the camera to what `renderer` shows: iso is the GUI's three-quarter view (all three slice
// planes visible); x, y, z look along that axis (towards -x, -y, -z, with z or y up).
void set_camera(vtkRenderer* renderer, CameraPreset preset);

}  // namespace skel::render
