// Model tests of the GUI document (no window): every edit is one undoable command, undo/redo
// sequences keep the graph valid, refusals change nothing, and a pipeline built through the model
// and saved equals the YAML loaded back.
#include <gtest/gtest.h>

#include <QCoreApplication>
#include <QRegularExpression>
#include <QSignalSpy>
#include <QTemporaryDir>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <random>

#include "file_filters.hpp"
#include "pipeline_document.hpp"
#include "run_controller.hpp"
#include "io/names.hpp"
#include "io/volume_format.hpp"
#include "skel/error.hpp"

using namespace skel;
using namespace skel::gui;

namespace {

// Structural invariants of a graph the editor may hold at any time: every connection points at an
// existing node's output port of a compatible type, ids are unique, and there is no cycle.
// (Missing required inputs are allowed while editing.)
void expect_graph_valid(const PipelineDocument& doc) {
  const Pipeline& p = doc.pipeline();
  std::set<std::string> ids;
  for (const auto& n : p.nodes()) {
    EXPECT_TRUE(ids.insert(n.id).second) << "duplicate id " << n.id;
    EXPECT_TRUE(doc.positions().contains(QString::fromStdString(n.id))) << "no position for " << n.id;
  }
  EXPECT_EQ(doc.positions().size(), static_cast<int>(p.nodes().size()));
  EXPECT_NO_THROW((void)p.topological_order());
  for (const auto& n : p.nodes()) {
    const ModuleSpec* ms = doc.registry().find(n.module);
    ASSERT_NE(ms, nullptr);
    for (const auto& [port, ref] : n.inputs) {
      const PipelineNode* src = p.find(ref.node);
      ASSERT_NE(src, nullptr) << n.id << "." << port << " <- " << ref.str();
      const PortSpec* out = doc.registry().find(src->module)->find_output(ref.port);
      ASSERT_NE(out, nullptr) << ref.str();
      const PortSpec* in = ms->find_input(port);
      ASSERT_NE(in, nullptr) << n.id << "." << port;
      bool compatible = false;
      for (const auto& t : out->types) compatible |= std::find(in->types.begin(), in->types.end(), t) != in->types.end();
      EXPECT_TRUE(compatible) << ref.str() << " -> " << n.id << "." << port;
    }
  }
  for (const auto& d : validate(p)) {
    EXPECT_NE(d.message.find("not connected"), std::string::npos) << d.format();
  }
}

bool done(NodeState s) { return s == NodeState::Done || s == NodeState::Cached; }

struct DocTest : ::testing::Test {
  PipelineDocument doc;
};

}  // namespace

TEST_F(DocTest, AddConnectUndoRedo) {
  const QString f = doc.add_node("gui_test.field", {0, 0});
  const QString t = doc.add_node("gui_test.threshold", {240, 0});
  const QString c = doc.add_node("gui_test.count", {480, 0});
  EXPECT_EQ(f, "field");
  EXPECT_EQ(t, "threshold");
  EXPECT_EQ(doc.add_node("gui_test.threshold", {240, 140}), "threshold2");
  EXPECT_EQ(doc.connect_ports(f, "image", t, "image"), "");
  EXPECT_EQ(doc.connect_ports(t, "mask", c, "mask"), "");
  EXPECT_EQ(doc.undo_stack()->count(), 6);
  expect_graph_valid(doc);
  EXPECT_TRUE(validate(doc.pipeline()).size() == 1);  // threshold2.image is not connected
  EXPECT_TRUE(doc.is_modified());

  // Undo everything, then redo everything: same graph at every step.
  std::vector<std::string> forward;
  for (int i = doc.undo_stack()->count(); i > 0; --i) {
    forward.push_back(doc.pipeline().to_yaml());
    doc.undo_stack()->undo();
    expect_graph_valid(doc);
  }
  EXPECT_TRUE(doc.pipeline().nodes().empty());
  for (auto it = forward.rbegin(); it != forward.rend(); ++it) {
    doc.undo_stack()->redo();
    EXPECT_EQ(doc.pipeline().to_yaml(), *it);
    expect_graph_valid(doc);
  }
}

TEST_F(DocTest, RefusedConnectionsChangeNothingAndGiveTheReason) {
  const QString f = doc.add_node("gui_test.field", {0, 0});
  const QString t = doc.add_node("gui_test.threshold", {240, 0});
  const QString c = doc.add_node("gui_test.count", {480, 0});
  const int commands = doc.undo_stack()->count();
  // float32 image into a uint8 mask input: type mismatch.
  QString reason = doc.connect_ports(f, "image", c, "mask");
  EXPECT_NE(reason, "");
  EXPECT_TRUE(reason.contains("volume.f32")) << reason.toStdString();
  // Unknown port.
  EXPECT_NE(doc.connect_ports(f, "nope", t, "image"), "");
  // Cycle: threshold.mask -> ... cannot feed its own upstream (types permitting, use two thresholds
  // through count? count has a table output, so build the cycle with volume.convert).
  const QString a = doc.add_node("volume.convert", {0, 200});
  const QString b = doc.add_node("volume.convert", {240, 200});
  EXPECT_EQ(doc.connect_ports(a, "output", b, "input"), "");
  reason = doc.connect_ports(b, "output", a, "input");
  EXPECT_TRUE(reason.contains("cycle")) << reason.toStdString();
  EXPECT_EQ(doc.undo_stack()->count(), commands + 3);
  expect_graph_valid(doc);
}

TEST_F(DocTest, DeleteRemovesConnectionsAndUndoRestoresThem) {
  const QString f = doc.add_node("gui_test.field", {0, 0});
  const QString t = doc.add_node("gui_test.threshold", {240, 0});
  const QString c = doc.add_node("gui_test.count", {480, 0});
  ASSERT_EQ(doc.connect_ports(f, "image", t, "image"), "");
  ASSERT_EQ(doc.connect_ports(t, "mask", c, "mask"), "");
  const std::string before = doc.pipeline().to_yaml();
  doc.remove_nodes({t});
  EXPECT_FALSE(doc.has_node(t));
  EXPECT_TRUE(doc.pipeline().find("count")->inputs.empty());
  expect_graph_valid(doc);
  doc.undo_stack()->undo();
  EXPECT_EQ(doc.pipeline().to_yaml(), before);
  EXPECT_EQ(doc.position(t), QPointF(240, 0));
  doc.disconnect_port(c, "mask");
  EXPECT_TRUE(doc.pipeline().find("count")->inputs.empty());
  doc.undo_stack()->undo();
  EXPECT_EQ(doc.pipeline().to_yaml(), before);
}

TEST_F(DocTest, ParamsAreCheckedAndUndoable) {
  const QString t = doc.add_node("gui_test.threshold", {0, 0});
  QSignalSpy spy(&doc, &PipelineDocument::param_changed);
  EXPECT_EQ(doc.set_param(t, "level", ParamValue(0.25)), "");
  EXPECT_EQ(std::get<double>(doc.pipeline().find("threshold")->params.at("level")), 0.25);
  // int is coerced to float.
  EXPECT_EQ(doc.set_param(t, "level", ParamValue(int64_t{1})), "");
  EXPECT_EQ(std::get<double>(doc.pipeline().find("threshold")->params.at("level")), 1.0);
  // Out of range, wrong type, unknown parameter: refused, nothing changes.
  const int commands = doc.undo_stack()->count();
  EXPECT_NE(doc.set_param(t, "level", ParamValue(1.5)), "");
  EXPECT_NE(doc.set_param(t, "level", ParamValue(std::string("high"))), "");
  EXPECT_NE(doc.set_param(t, "nope", ParamValue(1.0)), "");
  EXPECT_EQ(doc.undo_stack()->count(), commands);
  EXPECT_EQ(spy.count(), 2);
  doc.undo_stack()->undo();
  EXPECT_EQ(std::get<double>(doc.pipeline().find("threshold")->params.at("level")), 0.25);
  doc.reset_param(t, "level");
  EXPECT_TRUE(doc.pipeline().find("threshold")->params.empty());
  doc.undo_stack()->undo();
  EXPECT_EQ(std::get<double>(doc.pipeline().find("threshold")->params.at("level")), 0.25);
  // Renaming keeps connections and positions.
  const QString f = doc.add_node("gui_test.field", {-240, 0});
  ASSERT_EQ(doc.connect_ports(f, "image", t, "image"), "");
  EXPECT_EQ(doc.rename_node(f, "source"), "");
  EXPECT_EQ(doc.pipeline().find("threshold")->inputs.at("image").node, "source");
  EXPECT_EQ(doc.position("source"), QPointF(-240, 0));
  EXPECT_NE(doc.rename_node("source", "threshold"), "");
  EXPECT_NE(doc.rename_node("source", "bad id"), "");
}

TEST_F(DocTest, MoveIsOneCommand) {
  const QString a = doc.add_node("gui_test.field", {0, 0});
  const QString b = doc.add_node("gui_test.threshold", {240, 0});
  doc.move_nodes({{a, QPointF(10, 20)}, {b, QPointF(250, 20)}});
  EXPECT_EQ(doc.position(a), QPointF(10, 20));
  EXPECT_EQ(doc.position(b), QPointF(250, 20));
  EXPECT_EQ(doc.undo_stack()->count(), 3);
  doc.undo_stack()->undo();
  EXPECT_EQ(doc.position(a), QPointF(0, 0));
  EXPECT_EQ(doc.position(b), QPointF(240, 0));
}

TEST_F(DocTest, CopyPasteKeepsInternalConnectionsOnly) {
  const QString f = doc.add_node("gui_test.field", {0, 0});
  const QString t = doc.add_node("gui_test.threshold", {240, 0});
  const QString c = doc.add_node("gui_test.count", {480, 0});
  ASSERT_EQ(doc.connect_ports(f, "image", t, "image"), "");
  ASSERT_EQ(doc.connect_ports(t, "mask", c, "mask"), "");
  ASSERT_EQ(doc.set_param(t, "level", ParamValue(0.3)), "");
  const QString clip = doc.copy_nodes({t, c});
  const QStringList pasted = doc.paste(clip, QPointF(0, 300));
  ASSERT_EQ(pasted.size(), 2);
  EXPECT_EQ(pasted[0], "threshold2");
  EXPECT_EQ(pasted[1], "count2");
  const PipelineNode* t2 = doc.pipeline().find("threshold2");
  EXPECT_TRUE(t2->inputs.empty());  // field was not copied
  EXPECT_EQ(std::get<double>(t2->params.at("level")), 0.3);
  EXPECT_EQ(doc.pipeline().find("count2")->inputs.at("mask").node, "threshold2");
  EXPECT_EQ(doc.position("threshold2"), QPointF(0, 300));
  EXPECT_EQ(doc.position("count2"), QPointF(240, 300));
  expect_graph_valid(doc);
  doc.undo_stack()->undo();  // one command
  EXPECT_EQ(doc.pipeline().nodes().size(), 3u);
  QString error;
  EXPECT_TRUE(doc.paste("not: [a pipeline", {}, &error).isEmpty());
  EXPECT_FALSE(error.isEmpty());
}

TEST_F(DocTest, RandomEditSequencesKeepTheGraphValid) {
  std::mt19937 rng(7);
  const std::vector<QString> modules = {"gui_test.field", "gui_test.threshold", "gui_test.count",
                                        "volume.convert"};
  for (int step = 0; step < 300; ++step) {
    const QStringList ids = doc.node_ids();
    const int op = static_cast<int>(rng() % 7);
    auto pick = [&] { return ids[static_cast<int>(rng() % static_cast<unsigned>(ids.size()))]; };
    if (op == 0 || ids.size() < 2) {
      doc.add_node(modules[rng() % modules.size()], QPointF(rng() % 500, rng() % 500));
    } else if (op == 1 || op == 2) {
      const QString from = pick(), to = pick();
      const ModuleSpec* fs = doc.spec(from);
      const ModuleSpec* ts = doc.spec(to);
      if (fs->outputs().empty() || ts->inputs().empty()) continue;
      const auto& out = fs->outputs()[rng() % fs->outputs().size()];
      const auto& in = ts->inputs()[rng() % ts->inputs().size()];
      const std::string before = doc.pipeline().to_yaml();
      const QString reason = doc.connect_ports(from, QString::fromStdString(out.name), to,
                                               QString::fromStdString(in.name));
      if (!reason.isEmpty()) {
        EXPECT_EQ(doc.pipeline().to_yaml(), before);  // refusal changes nothing
      }
    } else if (op == 3) {
      const QString to = pick();
      const PipelineNode* n = doc.pipeline().find(to.toStdString());
      if (!n->inputs.empty()) doc.disconnect_port(to, QString::fromStdString(n->inputs.begin()->first));
    } else if (op == 4) {
      doc.remove_nodes({pick()});
    } else if (op == 5 && doc.undo_stack()->canUndo()) {
      doc.undo_stack()->undo();
    } else if (doc.undo_stack()->canRedo()) {
      doc.undo_stack()->redo();
    }
    expect_graph_valid(doc);
    if (HasFailure()) FAIL() << "after step " << step;
  }
  // Undoing everything returns to the empty document.
  while (doc.undo_stack()->canUndo()) doc.undo_stack()->undo();
  EXPECT_TRUE(doc.pipeline().nodes().empty());
}

TEST_F(DocTest, SavedModelEqualsTheYamlLoadedBack) {
  QTemporaryDir dir;
  const QString f = doc.add_node("gui_test.field", {0, 0});
  const QString t = doc.add_node("gui_test.threshold", {240, 10});
  const QString c = doc.add_node("gui_test.count", {480, 20});
  ASSERT_EQ(doc.connect_ports(f, "image", t, "image"), "");
  ASSERT_EQ(doc.connect_ports(t, "mask", c, "mask"), "");
  ASSERT_EQ(doc.set_param(f, "size", ParamValue(std::vector<int64_t>{32, 32, 16})), "");
  ASSERT_EQ(doc.set_param(t, "level", ParamValue(0.4)), "");
  EXPECT_TRUE(doc.is_modified());
  const QString path = dir.filePath("built.yaml");
  doc.save(path);
  EXPECT_FALSE(doc.is_modified());
  EXPECT_EQ(doc.file_path(), path);

  Pipeline loaded = Pipeline::load_file(path.toStdString());
  EXPECT_TRUE(loaded == doc.pipeline());
  EXPECT_TRUE(validate(loaded).empty());
  EXPECT_EQ(loaded.to_yaml(), doc.pipeline().to_yaml());

  PipelineDocument other;
  other.load(path);
  EXPECT_TRUE(other.pipeline() == doc.pipeline());
  EXPECT_EQ(other.positions(), doc.positions());
  EXPECT_FALSE(other.is_modified());
  // Saving again without edits writes the same bytes.
  const QString path2 = dir.filePath("again.yaml");
  other.save(path2);
  std::ifstream a(path.toStdString()), b(path2.toStdString());
  std::string sa((std::istreambuf_iterator<char>(a)), {}), sb((std::istreambuf_iterator<char>(b)), {});
  EXPECT_EQ(sa, sb);
  EXPECT_NE(sa.find("positions"), std::string::npos);
}

TEST_F(DocTest, LoadKeepsOtherGuiKeysAndLaysOutNodesWithoutPositions) {
  doc.load_text(
      "skelflow: 1\n"
      "nodes:\n"
      "  a: {module: gui_test.field}\n"
      "  b: {module: gui_test.threshold, inputs: {image: a.image}}\n"
      "gui: {theme: dark}\n",
      "inline.yaml", ".");
  EXPECT_LT(doc.position("a").x(), doc.position("b").x());  // columns by depth
  const QString yaml = doc.to_yaml();
  EXPECT_TRUE(yaml.contains("theme: dark")) << yaml.toStdString();
  EXPECT_TRUE(yaml.contains("positions")) << yaml.toStdString();
}

TEST_F(DocTest, RunControllerRunsOffTheUiThreadAndMarksStaleNodes) {
  int argc = 1;
  char arg0[] = "document_test";
  char* argv[] = {arg0, nullptr};
  QCoreApplication app(argc, argv);
  const QString f = doc.add_node("gui_test.field", {0, 0});
  const QString t = doc.add_node("gui_test.threshold", {240, 0});
  const QString c = doc.add_node("gui_test.count", {480, 0});
  ASSERT_EQ(doc.set_param(f, "size", ParamValue(std::vector<int64_t>{32, 32, 32})), "");
  ASSERT_EQ(doc.connect_ports(f, "image", t, "image"), "");
  ASSERT_EQ(doc.connect_ports(t, "mask", c, "mask"), "");
  RunController run(&doc);
  run.set_threads(2);
  QSignalSpy finished(&run, &RunController::finished);

  // Up to the threshold only.
  ASSERT_TRUE(run.start({t}));
  EXPECT_TRUE(run.is_running());
  ASSERT_TRUE(finished.wait(30000));
  EXPECT_TRUE(finished.takeFirst().at(0).toBool());
  EXPECT_EQ(run.status(f).state, NodeState::Done);
  EXPECT_EQ(run.status(t).state, NodeState::Done);
  EXPECT_EQ(run.status(c).state, NodeState::Idle);
  ASSERT_NE(run.output(t, "mask"), nullptr);
  EXPECT_EQ(run.output(t, "mask")->type_id(), "volume.u8");

  // Whole pipeline: only count runs now (cache).
  const int64_t runs = run.executor().modules_run();
  ASSERT_TRUE(run.start());
  ASSERT_TRUE(finished.wait(30000));
  EXPECT_TRUE(finished.takeFirst().at(0).toBool());
  EXPECT_EQ(run.executor().modules_run(), runs + 1);
  EXPECT_EQ(run.progress(), 1.0);
  for (const QString& id : {f, t, c}) {
    EXPECT_TRUE(done(run.status(id).state)) << id.toStdString();
  }

  // A parameter change makes the node and its dependants stale, not its upstream.
  ASSERT_EQ(doc.set_param(t, "level", ParamValue(0.7)), "");
  EXPECT_TRUE(done(run.status(f).state));
  EXPECT_EQ(run.status(t).state, NodeState::Stale);
  EXPECT_EQ(run.status(c).state, NodeState::Stale);
  EXPECT_EQ(run.output(t, "mask"), nullptr);
  // Undo makes the cached results current again.
  doc.undo_stack()->undo();
  EXPECT_TRUE(done(run.status(t).state));
  EXPECT_NE(run.output(c, "table"), nullptr);

  // An invalid pipeline finishes at once with the validator's message.
  doc.add_node("gui_test.threshold", {0, 300});
  ASSERT_TRUE(run.start());
  ASSERT_TRUE(finished.wait(30000));
  const auto args = finished.takeFirst();
  EXPECT_FALSE(args.at(0).toBool());
  EXPECT_TRUE(args.at(1).toString().contains("threshold2")) << args.at(1).toString().toStdString();
}

TEST_F(DocTest, RunControllerReportsRunTimeErrorsAtTheNodesLine) {
  int argc = 1;
  char arg0[] = "document_test";
  char* argv[] = {arg0, nullptr};
  QCoreApplication app(argc, argv);
  QTemporaryDir dir;
  ASSERT_TRUE(dir.isValid());
  // A file whose header is sound (validation reads headers) but whose voxels are damaged: found
  // while running.
  const std::string broken = (std::filesystem::path(dir.path().toStdString()) / "broken.h5").string();
  {
    VolumeF32 v(Dims{64, 64, 64});  // float32: what gui_test.threshold takes (validate reads the header)
    std::mt19937 rng(7);
    for (auto& x : v) x = static_cast<float>(rng() % 1000) / 1000.0f;
    io::VolumeWriteOptions wo;
    wo.compression = 1;
    io::write_any_volume(broken, v, wo);
    std::fstream f(broken, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(std::filesystem::file_size(broken) / 2));
    const std::string junk(4096, '\xff');
    f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
  }
  doc.load_text(
      "skelflow: 1\nnodes:\n"
      "  image: {module: io.read_volume, params: {path: broken.h5}}\n"
      "  t: {module: gui_test.threshold, inputs: {image: image.volume}}\n",
      "pipes/gui.yaml", dir.path());
  RunController run(&doc);
  QSignalSpy finished(&run, &RunController::finished);
  ASSERT_TRUE(run.start());
  ASSERT_TRUE(finished.wait(30000));
  const auto args = finished.takeFirst();
  EXPECT_FALSE(args.at(0).toBool());
  // The run's message has the format of validation errors; the node shows its own message.
  const std::string reason = run.status("image").message;
  // Read by our chunk decoding (io/hdf5_chunks.hpp), which names the damaged chunk.
  EXPECT_EQ(reason.rfind(broken + ": dataset '/volume': chunk (0, 0, 0) ", 0), 0u) << reason;
  EXPECT_NE(reason.find("the file is damaged"), std::string::npos) << reason;
  EXPECT_EQ(args.at(1).toString().toStdString(), "pipes/gui.yaml:3:3: node 'image' (io.read_volume): " + reason);
  EXPECT_EQ(run.status("image").state, NodeState::Error);
}

// Issue 19: the file dialogs' filters come from the readers and writers — every extension of the
// volume format registry (and each format's name), and the graph and mesh readers' extensions.
TEST(FileFilters, EveryRegistryExtensionIsInTheDialogFilter) {
  const Registry& reg = Registry::instance();
  auto filter_of = [&](const char* module) {
    const ModuleSpec* m = reg.find(module);
    EXPECT_NE(m, nullptr) << module;
    const ParamSpec* path = m ? m->find_param("path") : nullptr;
    EXPECT_NE(path, nullptr) << module;
    return path ? file_dialog_filter(*path) : QString();
  };
  auto has_pattern = [](const QString& filter, const std::string& ext) {
    return filter.split(QRegularExpression("[ ()]"), Qt::SkipEmptyParts).contains("*" + QString::fromStdString(ext));
  };
  const QString read = filter_of(io::names::read_volume), write = filter_of(io::names::write_volume);
  ASSERT_FALSE(io::readable_volume_extensions().empty());
  for (const auto& e : io::readable_volume_extensions()) EXPECT_TRUE(has_pattern(read, e)) << e << " in " << read.toStdString();
  for (const auto& e : io::writable_volume_extensions()) EXPECT_TRUE(has_pattern(write, e)) << e << " in " << write.toStdString();
  for (const auto& f : io::volume_formats()) {
    EXPECT_TRUE(read.contains(QString::fromStdString(f.name) + " (")) << f.name << " in " << read.toStdString();
    for (const auto& e : f.extensions) EXPECT_TRUE(has_pattern(read, e)) << f.name << " " << e;
    if (f.write) EXPECT_TRUE(write.contains(QString::fromStdString(f.name) + " (")) << f.name;
    else EXPECT_FALSE(write.contains(QString::fromStdString(f.name) + " (")) << f.name << " cannot write";
  }
  for (const char* m : {io::names::read_graph, io::names::read_mesh, io::names::write_graph, io::names::write_mesh}) {
    const QString f = filter_of(m);
    for (const auto& e : reg.find(m)->find_param("path")->extensions)
      EXPECT_TRUE(has_pattern(f, e)) << m << ": " << e << " in " << f.toStdString();
    EXPECT_TRUE(f.startsWith("Supported files (")) << f.toStdString();
    EXPECT_TRUE(f.endsWith("All files (*)")) << f.toStdString();
  }
  // Upper-case files too (the dialogs match case-sensitively on Linux).
  EXPECT_TRUE(has_pattern(read, ".TIF")) << read.toStdString();
  ParamSpec plain;
  EXPECT_EQ(file_dialog_filter(plain), "All files (*)");
}
