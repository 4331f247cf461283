#pragma once
// What the 3D view shows by itself after a run (as Amira does): the pipeline's final geometry. No
// widgets here, so the model tests check the choice.
#include <QStringList>

#include <functional>

#include "skel/data.hpp"
#include "skel/module.hpp"
#include "skel/pipeline.hpp"

namespace skel::gui {

// "node.port" names of the computed outputs to show after a run: the sink-most mesh and the
// sink-most graph (an output no computed output of the same kind derives from, downstream; the last
// in topological order when several are), else the sink-most volume. `output(node, port)` gives a
// computed output or null. Empty when nothing drawable was computed.
QStringList final_geometry_outputs(const Pipeline& pipeline, const Registry& registry,
                                   const std::function<DataPtr(const std::string& node, const std::string& port)>& output);

}  // namespace skel::gui
