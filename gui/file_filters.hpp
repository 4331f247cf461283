#pragma once
// Name filters of the GUI's file dialogs, made from what the readers and writers accept rather than
// written by hand: a Path parameter's extensions (io.read_volume / io.write_volume take theirs from
// the volume format registry, modules/io/volume_format.hpp; the graph, mesh, table and landmark
// modules from their readers and writers), one entry per volume format with its registry name.
#include <QString>

#include "skel/module.hpp"

namespace skel::gui {

// "Supported files (*.h5 *.tif ...);;HDF5 (*.h5 *.hdf5);;TIFF (*.tif *.tiff);;...;;All files (*)"
// for a Path parameter; just "All files (*)" when it names no extensions.
QString file_dialog_filter(const ParamSpec& param);

}  // namespace skel::gui
