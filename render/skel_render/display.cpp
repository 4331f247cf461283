#include "display.hpp"

#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkCellData.h>
#include <vtkColorTransferFunction.h>
#include <vtkDataArray.h>
#include <vtkFloatArray.h>
#include <vtkFlyingEdges3D.h>
#include <vtkGeometryFilter.h>
#include <vtkImageActor.h>
#include <vtkImageData.h>
#include <vtkImageMapper3D.h>
#include <vtkImageProperty.h>
#include <vtkLookupTable.h>
#include <vtkOutlineFilter.h>
#include <vtkPiecewiseFunction.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderer.h>
#include <vtkScalarBarActor.h>
#include <vtkSmartVolumeMapper.h>
#include <vtkTextProperty.h>
#include <vtkThreshold.h>
#include <vtkTubeFilter.h>
#include <vtkVolume.h>
#include <vtkVolumeProperty.h>

#include <algorithm>
#include <cmath>

#include "io/mesh_vtk.hpp"
#include "skel/error.hpp"
#include "vtk_convert.hpp"

namespace skel::render {

const Color& palette_color(size_t i) {
  static const std::array<Color, 6> kPalette = {{{0.90, 0.75, 0.55},
                                                 {0.55, 0.80, 0.95},
                                                 {0.95, 0.55, 0.55},
                                                 {0.65, 0.90, 0.60},
                                                 {0.85, 0.65, 0.95},
                                                 {0.95, 0.90, 0.50}}};
  return kPalette[i % kPalette.size()];
}

Display::~Display() = default;

namespace {

// The rainbow (blue = low, red = high) every attribute colouring uses, over [lo, hi].
vtkSmartPointer<vtkLookupTable> make_lut(const double range[2]) {
  auto lut = vtkSmartPointer<vtkLookupTable>::New();
  lut->SetHueRange(0.667, 0.0);
  lut->SetTableRange(range[0], range[1] > range[0] ? range[1] : range[0] + 1);
  lut->Build();
  return lut;
}

void show_bar(vtkScalarBarActor* bar, vtkLookupTable* lut, const std::string& title) {
  if (!bar) return;
  bar->SetLookupTable(lut);
  bar->SetTitle(title.c_str());
  bar->SetVisibility(true);
}

}  // namespace

// ------------------------------------------------------------------ volumes
std::unique_ptr<VolumeDisplay> VolumeDisplay::create(const DataPtr& data, const Color& color) {
  vtkSmartPointer<vtkImageData> image;
  try {
    image = volume_to_image(*data);
  } catch (const std::exception&) {
    return nullptr;  // not a volume
  }
  return std::unique_ptr<VolumeDisplay>(new VolumeDisplay(data, color, std::move(image)));
}

VolumeDisplay::VolumeDisplay(const DataPtr& data, const Color& color, vtkSmartPointer<vtkImageData> image)
    : Display(data, color), image_(std::move(image)) {
  binary_ = is_binary_volume(*data);
  image_->GetScalarRange(range_);
  image_->GetExtent(extent_);
  for (int k = 0; k < 3; ++k) slice_[k] = (extent_[2 * k] + extent_[2 * k + 1]) / 2;
  window_ = std::max(range_[1] - range_[0], 1e-9);
  level_ = 0.5 * (range_[0] + range_[1]);
  iso_ = binary_ ? 0.5 : range_[0] + 0.5 * (range_[1] - range_[0]);
  mode_ = binary_ ? VolumeMode::VoxelSurface : VolumeMode::Slices;
  // A thin outline of the grid so slices and surfaces have context.
  auto outline = vtkSmartPointer<vtkOutlineFilter>::New();
  outline->SetInputData(image_);
  auto om = vtkSmartPointer<vtkPolyDataMapper>::New();
  om->SetInputConnection(outline->GetOutputPort());
  outline_ = vtkSmartPointer<vtkActor>::New();
  outline_->SetMapper(om);
  outline_->GetProperty()->SetColor(0.6, 0.6, 0.65);
}

VolumeDisplay::~VolumeDisplay() = default;

void VolumeDisplay::keep_settings(const Display& old) {
  const auto* v = dynamic_cast<const VolumeDisplay*>(&old);
  if (!v || v->binary_ != binary_) return;
  mode_ = v->mode_;
  // Window, level, iso value and slices mean the same only for the same voxel type.
  if (v->data()->type_id() != data()->type_id()) return;
  window_ = v->window_;
  level_ = v->level_;
  iso_ = v->iso_;
  for (int k = 0; k < 3; ++k) slice_[k] = std::clamp(v->slice_[k], extent_[2 * k], extent_[2 * k + 1]);
}

void VolumeDisplay::set_window_level(double window, double level) {
  window_ = std::max(window, 1e-12);
  level_ = level;
}

std::vector<vtkSmartPointer<vtkProp>> VolumeDisplay::build_props(vtkScalarBarActor* /*bar*/) {
  std::vector<vtkSmartPointer<vtkProp>> props{outline_};
  switch (mode_) {
    case VolumeMode::Slices: {
      for (int k = 0; k < 3; ++k) {
        auto actor = vtkSmartPointer<vtkImageActor>::New();
        actor->GetMapper()->SetInputData(image_);
        int e[6];
        std::copy(std::begin(extent_), std::end(extent_), e);
        e[2 * k] = e[2 * k + 1] = std::clamp(slice_[k], extent_[2 * k], extent_[2 * k + 1]);
        actor->SetDisplayExtent(e);
        actor->GetProperty()->SetColorWindow(window_);
        actor->GetProperty()->SetColorLevel(level_);
        actor->GetProperty()->SetInterpolationTypeToNearest();
        props.push_back(actor);
      }
      break;
    }
    case VolumeMode::Mip:
    case VolumeMode::VolumeRendering: {
      auto mapper = vtkSmartPointer<vtkSmartVolumeMapper>::New();
      mapper->SetInputData(image_);
      const bool mip = mode_ == VolumeMode::Mip;
      if (mip) mapper->SetBlendModeToMaximumIntensity();
      else mapper->SetBlendModeToComposite();
      const double lo = level_ - 0.5 * window_, hi = level_ + 0.5 * window_;
      auto color = vtkSmartPointer<vtkColorTransferFunction>::New();
      auto opacity = vtkSmartPointer<vtkPiecewiseFunction>::New();
      if (mip) {
        color->AddRGBPoint(lo, 0, 0, 0);
        color->AddRGBPoint(hi, 1, 1, 1);
        opacity->AddPoint(lo, 0.0);
        opacity->AddPoint(hi, 1.0);
      } else {
        color->AddRGBPoint(lo, 0.2, 0.1, 0.05);
        color->AddRGBPoint(lo + 0.5 * (hi - lo), 0.9, 0.5, 0.2);
        color->AddRGBPoint(hi, 1.0, 1.0, 0.9);
        opacity->AddPoint(lo, 0.0);
        opacity->AddPoint(hi, 0.6);
      }
      auto prop = vtkSmartPointer<vtkVolumeProperty>::New();
      prop->SetColor(color);
      prop->SetScalarOpacity(opacity);
      prop->SetInterpolationTypeToLinear();
      if (!mip) prop->ShadeOn();
      auto volume = vtkSmartPointer<vtkVolume>::New();
      volume->SetMapper(mapper);
      volume->SetProperty(prop);
      props.push_back(volume);
      break;
    }
    case VolumeMode::IsoSurface: {
      if (!surface_ || surface_iso_ != iso_) {
        auto fe = vtkSmartPointer<vtkFlyingEdges3D>::New();
        fe->SetInputData(image_);
        fe->SetValue(0, iso_);
        fe->ComputeNormalsOn();
        fe->ComputeScalarsOff();
        auto m = vtkSmartPointer<vtkPolyDataMapper>::New();
        m->SetInputConnection(fe->GetOutputPort());
        m->ScalarVisibilityOff();
        surface_ = vtkSmartPointer<vtkActor>::New();
        surface_->SetMapper(m);
        surface_iso_ = iso_;
      }
      surface_->GetProperty()->SetColor(color()[0], color()[1], color()[2]);
      props.push_back(surface_);
      break;
    }
    case VolumeMode::VoxelSurface: {
      if (!voxels_) {
        // Each voxel >= iso is a cube; the outer faces of the kept cubes are the voxel surface.
        auto cells = volume_to_cell_image(*data());
        auto th = vtkSmartPointer<vtkThreshold>::New();
        th->SetInputData(cells);
        th->SetInputArrayToProcess(0, 0, 0, vtkDataObject::FIELD_ASSOCIATION_CELLS, "voxels");
        th->SetLowerThreshold(binary_ ? 0.5 : iso_);
        th->SetUpperThreshold(VTK_DOUBLE_MAX);
        th->SetThresholdFunction(vtkThreshold::THRESHOLD_BETWEEN);
        auto geom = vtkSmartPointer<vtkGeometryFilter>::New();
        geom->SetInputConnection(th->GetOutputPort());
        auto m = vtkSmartPointer<vtkPolyDataMapper>::New();
        m->SetInputConnection(geom->GetOutputPort());
        m->ScalarVisibilityOff();
        voxels_ = vtkSmartPointer<vtkActor>::New();
        voxels_->SetMapper(m);
      }
      voxels_->GetProperty()->SetColor(color()[0], color()[1], color()[2]);
      props.push_back(voxels_);
      break;
    }
  }
  return props;
}

// ------------------------------------------------------------------ spatial graphs
GraphDisplay::GraphDisplay(const std::shared_ptr<const SpatialGraph>& graph, const Color& color)
    : Display(graph, color), graph_(graph), poly_(graph_to_polydata(*graph)) {
  const auto attrs = graph_attribute_names(*graph);
  const bool has_radius = std::find(attrs.begin(), attrs.end(), "radius") != attrs.end();
  mode_ = has_radius ? GraphMode::Tubes : GraphMode::Lines;
  if (has_radius) color_by_ = "radius";
}

GraphDisplay::~GraphDisplay() = default;

std::vector<std::string> GraphDisplay::color_choices() const { return graph_attribute_names(*graph_); }

bool GraphDisplay::set_color_by(const std::string& attribute) {
  if (attribute.empty()) {
    color_by_.clear();
    return true;
  }
  const auto c = color_choices();
  if (std::find(c.begin(), c.end(), attribute) == c.end()) return false;
  color_by_ = attribute;
  return true;
}

void GraphDisplay::keep_settings(const Display& old) {
  const auto* g = dynamic_cast<const GraphDisplay*>(&old);
  if (!g) return;
  mode_ = g->mode_;
  tube_scale_ = g->tube_scale_;
  color_by_ = g->color_by_;
}

std::vector<vtkSmartPointer<vtkProp>> GraphDisplay::build_props(vtkScalarBarActor* bar) {
  auto mapper = vtkSmartPointer<vtkPolyDataMapper>::New();
  vtkPointData* pd = poly_->GetPointData();
  const bool tubes = mode_ == GraphMode::Tubes && pd->GetArray("radius");
  if (tubes) {
    // Tube radius = radius attribute x scale (clamped away from 0 so tubes never degenerate).
    vtkDataArray* r = pd->GetArray("radius");
    auto scaled = vtkSmartPointer<vtkFloatArray>::New();
    scaled->SetName("tube_radius");
    scaled->SetNumberOfTuples(r->GetNumberOfTuples());
    double range[2];
    r->GetRange(range);
    const double floor_r = std::max(1e-3, 0.05 * range[1]) * tube_scale_;
    for (vtkIdType i = 0; i < r->GetNumberOfTuples(); ++i) {
      scaled->SetValue(i, static_cast<float>(std::max(r->GetTuple1(i) * tube_scale_, floor_r)));
    }
    pd->AddArray(scaled);
    pd->SetActiveScalars("tube_radius");
    auto tube = vtkSmartPointer<vtkTubeFilter>::New();
    tube->SetInputData(poly_);
    tube->SetVaryRadiusToVaryRadiusByAbsoluteScalar();
    tube->SetNumberOfSides(10);
    tube->CappingOn();
    mapper->SetInputConnection(tube->GetOutputPort());
  } else {
    mapper->SetInputData(poly_);
  }
  vtkDataArray* colors = color_by_.empty() ? nullptr : pd->GetArray(color_by_.c_str());
  if (colors) {
    double r[2];
    colors->GetRange(r);
    auto lut = make_lut(r);
    mapper->SetLookupTable(lut);
    mapper->SetScalarModeToUsePointFieldData();
    mapper->SelectColorArray(color_by_.c_str());
    mapper->SetScalarRange(lut->GetTableRange());
    mapper->ScalarVisibilityOn();
    show_bar(bar, lut, color_by_);
  } else {
    mapper->ScalarVisibilityOff();
  }
  auto actor = vtkSmartPointer<vtkActor>::New();
  actor->SetMapper(mapper);
  actor->GetProperty()->SetColor(color()[0], color()[1], color()[2]);
  actor->GetProperty()->SetLineWidth(2.0);
  return {actor};
}

// ------------------------------------------------------------------ meshes
namespace {

// The mesh's triangles or lines alone, with the vertex attributes and their own attributes.
vtkSmartPointer<vtkPolyData> mesh_part(const Mesh& m, bool triangles) {
  Mesh p;
  p.points = m.points;
  p.vertex_attributes = m.vertex_attributes;
  p.unit = m.unit;
  if (triangles) {
    p.triangles = m.triangles;
    p.triangle_attributes = m.triangle_attributes;
  } else {
    p.line_offsets = m.line_offsets;
    p.line_vertices = m.line_vertices;
    p.line_attributes = m.line_attributes;
  }
  return io::mesh_to_vtk(p);
}

}  // namespace

MeshDisplay::MeshDisplay(const std::shared_ptr<const Mesh>& mesh, const Color& color)
    : Display(mesh, color), mesh_(mesh), surface_(mesh_part(*mesh, true)), lines_(mesh_part(*mesh, false)) {
  if (mesh->triangle_attributes.count("manifold")) color_by_ = "triangle:manifold";
  else if (mesh->line_attributes.count("manifold")) color_by_ = "line:manifold";
  // Tubes scale with the whole mesh (triangles and lines), so a line-only mesh gets tubes too.
  double b[6];
  io::mesh_to_vtk(*mesh)->GetBounds(b);
  const double diag =
      std::sqrt((b[1] - b[0]) * (b[1] - b[0]) + (b[3] - b[2]) * (b[3] - b[2]) + (b[5] - b[4]) * (b[5] - b[4]));
  tube_radius_ = diag > 0 ? 0.004 * diag : 0.5;
}

MeshDisplay::~MeshDisplay() = default;

std::vector<std::string> MeshDisplay::color_choices() const {
  std::vector<std::string> out;
  for (const auto& [n, a] : mesh_->vertex_attributes) out.push_back("vertex:" + n);
  for (const auto& [n, a] : mesh_->triangle_attributes) out.push_back("triangle:" + n);
  for (const auto& [n, a] : mesh_->line_attributes) out.push_back("line:" + n);
  return out;
}

bool MeshDisplay::set_color_by(const std::string& attribute) {
  if (attribute.empty()) {
    color_by_.clear();
    return true;
  }
  const auto c = color_choices();
  if (std::find(c.begin(), c.end(), attribute) != c.end()) {
    color_by_ = attribute;
    return true;
  }
  // A bare name: the triangles' attribute first (the GUI's default colouring), then the lines', then
  // the vertices'.
  for (const char* kind : {"triangle:", "line:", "vertex:"}) {
    if (std::find(c.begin(), c.end(), kind + attribute) != c.end()) {
      color_by_ = kind + attribute;
      return true;
    }
  }
  return false;
}

void MeshDisplay::keep_settings(const Display& old) {
  const auto* m = dynamic_cast<const MeshDisplay*>(&old);
  if (!m) return;
  const auto c = color_choices();
  if (m->color_by_.empty() || std::find(c.begin(), c.end(), m->color_by_) != c.end()) color_by_ = m->color_by_;
  tubes_ = m->tubes_;
  tube_radius_ = m->tube_radius_;
}

std::vector<vtkSmartPointer<vtkProp>> MeshDisplay::build_props(vtkScalarBarActor* bar) {
  const auto colon = color_by_.find(':');
  const std::string kind = color_by_.substr(0, colon);
  const std::string attr = colon == std::string::npos ? std::string() : color_by_.substr(colon + 1);
  vtkSmartPointer<vtkLookupTable> lut;
  auto colour = [&](vtkPolyDataMapper* mapper, vtkPolyData* poly, bool is_surface) {
    vtkDataArray* a = nullptr;
    if (kind == "vertex") {
      a = poly->GetPointData()->GetArray(attr.c_str());
      mapper->SetScalarModeToUsePointFieldData();
    } else if ((kind == "triangle" && is_surface) || (kind == "line" && !is_surface)) {
      a = poly->GetCellData()->GetArray(attr.c_str());
      mapper->SetScalarModeToUseCellFieldData();
    }
    if (!a) {
      mapper->ScalarVisibilityOff();
      return;
    }
    if (!lut) {
      double r[2];
      a->GetRange(r);
      lut = make_lut(r);
    }
    mapper->SetLookupTable(lut);
    mapper->SelectColorArray(attr.c_str());
    mapper->SetScalarRange(lut->GetTableRange());
    mapper->ScalarVisibilityOn();
  };
  std::vector<vtkSmartPointer<vtkProp>> props;
  if (mesh_->triangle_count() > 0) {
    auto mapper = vtkSmartPointer<vtkPolyDataMapper>::New();
    mapper->SetInputData(surface_);
    colour(mapper, surface_, true);
    auto actor = vtkSmartPointer<vtkActor>::New();
    actor->SetMapper(mapper);
    actor->GetProperty()->SetColor(color()[0], color()[1], color()[2]);
    actor->GetProperty()->SetInterpolationToGouraud();
    actor->GetProperty()->BackfaceCullingOff();
    props.push_back(actor);
  }
  if (mesh_->line_count() > 0) {
    auto mapper = vtkSmartPointer<vtkPolyDataMapper>::New();
    if (tubes_) {
      auto tube = vtkSmartPointer<vtkTubeFilter>::New();
      tube->SetInputData(lines_);
      tube->SetRadius(tube_radius_);
      tube->SetNumberOfSides(8);
      tube->CappingOn();
      mapper->SetInputConnection(tube->GetOutputPort());
    } else {
      mapper->SetInputData(lines_);
    }
    colour(mapper, lines_, false);
    auto actor = vtkSmartPointer<vtkActor>::New();
    actor->SetMapper(mapper);
    actor->GetProperty()->SetColor(color()[0], color()[1], color()[2]);
    actor->GetProperty()->SetLineWidth(2.0);
    props.push_back(actor);
  }
  coloured_ = lut != nullptr;
  if (lut) show_bar(bar, lut, color_by_);
  return props;
}

// ------------------------------------------------------------------ factory and scene
std::unique_ptr<Display> make_display(const DataPtr& data, const Color& color) {
  if (!data) throw InputError("no data to show");
  if (auto g = std::dynamic_pointer_cast<const SpatialGraph>(data)) return std::make_unique<GraphDisplay>(g, color);
  if (auto m = std::dynamic_pointer_cast<const Mesh>(data)) return std::make_unique<MeshDisplay>(m, color);
  if (auto v = VolumeDisplay::create(data, color)) return v;
  throw InputError("the 3D view shows volumes, graphs and meshes, not " + data->type_id());
}

bool displayable_type(const std::string& type_id) {
  return type_id == type_ids::graph || type_id == type_ids::mesh || type_id.rfind("volume.", 0) == 0;
}

void setup_renderer(vtkRenderer* renderer) {
  renderer->SetBackground(0.10, 0.11, 0.13);
  renderer->SetBackground2(0.25, 0.27, 0.32);
  renderer->GradientBackgroundOn();
}

vtkSmartPointer<vtkScalarBarActor> make_scalar_bar(vtkRenderer* renderer) {
  auto bar = vtkSmartPointer<vtkScalarBarActor>::New();
  bar->SetNumberOfLabels(5);
  bar->SetWidth(0.08);
  bar->SetHeight(0.5);
  bar->SetPosition(0.9, 0.25);
  bar->GetTitleTextProperty()->SetFontSize(12);
  bar->SetVisibility(false);
  renderer->AddActor2D(bar);
  return bar;
}

void set_camera(vtkRenderer* renderer, CameraPreset preset) {
  vtkCamera* cam = renderer->GetActiveCamera();
  // Start from VTK's default (looking down -z, y up) so a preset does not depend on the last one.
  cam->SetPosition(0, 0, 1);
  cam->SetFocalPoint(0, 0, 0);
  cam->SetViewUp(0, 1, 0);
  switch (preset) {
    case CameraPreset::Iso:
      renderer->ResetCamera();
      // A three-quarter view shows all three slice planes.
      cam->Azimuth(35);
      cam->Elevation(25);
      cam->OrthogonalizeViewUp();
      break;
    case CameraPreset::X:
      cam->SetPosition(1, 0, 0);
      cam->SetViewUp(0, 0, 1);
      break;
    case CameraPreset::Y:
      cam->SetPosition(0, -1, 0);
      cam->SetViewUp(0, 0, 1);
      break;
    case CameraPreset::Z:
      break;
  }
  renderer->ResetCamera();
  renderer->ResetCameraClippingRange();
}

}  // namespace skel::render
