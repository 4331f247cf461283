#include "render_command.hpp"

#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>

#include "cli_options.hpp"
#include "skel/enum_names.hpp"
#include "skel/error.hpp"
#include "skel/executor.hpp"
#include "skel/module.hpp"
#include "skel/pipeline.hpp"
#include "skel/text.hpp"
#include "skel_render/choices.hpp"

#ifdef SKEL_HAVE_RENDER
#include "skel_render/offscreen.hpp"
#endif

namespace fs = std::filesystem;

namespace skel::cli {
namespace {

// "--camera up: expected one of iso, x, y, z (did you mean ...)".
template <NamedEnum E>
E parse_choice(const std::string& option, const std::string& value) {
  const auto c = enum_choices<E>();
  for (const auto& n : enum_names(E{}))
    if (value == n.name) return n.value;
  std::string all;
  for (const auto& x : c) all += (all.empty() ? "" : ", ") + x;
  throw InputError(option + " " + value + ": expected one of " + all + did_you_mean(value, c));
}

bool displayable_type_id(const std::string& t) {
  return t == type_ids::graph || t == type_ids::mesh || t.rfind("volume.", 0) == 0;
}

struct Target {
  std::string text;  // "node.port" as given
  PortRef ref;
};

}  // namespace

int cmd_render(const std::vector<std::string>& args, const std::atomic<bool>* cancel,
               const std::function<void(const std::string&)>& unknown_option) {
  std::string file, out, color_by;
  render::CameraPreset camera = render::CameraPreset::Iso;
  std::optional<render::VolumeMode> volume_mode;
  int width = 1280, height = 800;
  bool quiet = false;
  std::vector<Target> targets;
  ExecOptions opt;
  auto need = [&](size_t& i, const std::string& what) -> const std::string& {
    if (i + 1 >= args.size()) throw InputError("render: " + what + " needs a value");
    return args[++i];
  };
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--node") {
      const std::string& t = need(i, "--node");
      auto ref = parse_port_ref(t);
      if (!ref) throw InputError("--node " + t + ": expected NODE.PORT (e.g. graph.graph)");
      targets.push_back({t, *ref});
    } else if (a == "-o" || a == "--output") {
      out = need(i, a);
    } else if (a == "--size") {
      const std::string& s = need(i, "--size");
      const auto x = s.find('x');
      int64_t w = 0, h = 0;
      if (x == std::string::npos || !text::parse_int(s.substr(0, x), w) || !text::parse_int(s.substr(x + 1), h) || w < 16 ||
          h < 16 || w > 16384 || h > 16384)
        throw InputError("--size " + s + ": expected WIDTHxHEIGHT in pixels, 16 to 16384 each (e.g. 1280x800)");
      width = static_cast<int>(w);
      height = static_cast<int>(h);
    } else if (a == "--color-by") {
      color_by = need(i, "--color-by");
    } else if (a == "--camera") {
      camera = parse_choice<render::CameraPreset>("--camera", need(i, "--camera"));
    } else if (a == "--volume-mode") {
      volume_mode = parse_choice<render::VolumeMode>("--volume-mode", need(i, "--volume-mode"));
    } else if (a == "--set") {
      parse_set_option(need(i, "--set"), opt);
    } else if (a == "--threads") {
      parse_threads_option(need(i, "--threads"), opt);
    } else if (a == "--quiet" || a == "-q") {
      quiet = true;
    } else if (!a.empty() && a[0] == '-') {
      unknown_option(a);
    } else if (file.empty()) {
      file = a;
    } else {
      throw InputError("render: more than one pipeline given");
    }
  }
  if (file.empty()) throw InputError("render: no PIPELINE given");
  if (targets.empty()) throw InputError("render: no --node NODE.PORT given (what to draw)");
  if (out.empty()) throw InputError("render: no -o FILE.png given");
  if (text::to_lower(fs::path(out).extension().string()) != ".png")
    throw InputError("-o " + out + ": the picture is written as PNG; give a file ending in .png");

  Pipeline p = Pipeline::load_file(file);
  const Registry& reg = Registry::instance();
  // Each NODE.PORT must name a node of the pipeline and an output of its module that the 3D view
  // draws; checked before anything runs.
  std::vector<std::string> ids;
  for (const auto& n : p.nodes()) ids.push_back(n.id);
  for (const auto& t : targets) {
    const PipelineNode* n = p.find(t.ref.node);
    if (!n) throw InputError("--node " + t.text + ": no node '" + t.ref.node + "' in " + file + did_you_mean(t.ref.node, ids));
    const ModuleSpec* m = reg.find(n->module);
    if (!m) throw InputError("--node " + t.text + ": node '" + n->id + "' has the unknown module '" + n->module + "'");
    const PortSpec* port = nullptr;
    std::vector<std::string> outs;
    for (const auto& o : m->outputs()) {
      outs.push_back(o.name);
      if (o.name == t.ref.port) port = &o;
    }
    if (!port) {
      std::string list;
      for (const auto& o : outs) list += (list.empty() ? "" : ", ") + o;
      throw InputError("--node " + t.text + ": node '" + n->id + "' (" + n->module + ") has no output '" + t.ref.port + "'" +
                       did_you_mean(t.ref.port, outs) + "; its outputs: " + (list.empty() ? "none" : list));
    }
    bool drawable = false;
    for (const auto& ty : port->types) drawable |= displayable_type_id(ty);
    if (!drawable)
      throw InputError("--node " + t.text + ": output '" + t.ref.port + "' of node '" + n->id + "' is a " +
                       (port->types.empty() ? std::string("?") : port->types.front()) +
                       "; render draws volumes, graphs and meshes");
  }
#ifndef SKEL_HAVE_RENDER
  (void)cancel;
  (void)quiet;
  (void)camera;
  (void)width;
  (void)height;
  throw Error("render: this skelflow was built without VTK's rendering components (RenderingOpenGL2, "
              "RenderingVolumeOpenGL2, RenderingFreeType, IOImage, ...); install them (Debian: libvtk9-dev) and "
              "reconfigure");
#else
  // Run what the drawn nodes need (the executor's cache keeps each node's result once), keeping
  // their outputs.
  for (const auto& t : targets) opt.targets.push_back(t.ref.node);
  opt.cancel = cancel;
  std::map<std::string, std::map<std::string, DataPtr>> results;
  opt.on_outputs = [&](const std::string& node, const std::map<std::string, DataPtr>& outputs) {
    for (const auto& t : targets)
      if (t.ref.node == node) {
        results[node] = outputs;
        break;
      }
  };
  opt.on_warning = [&](const std::string& node, const std::string& msg) {
    std::fprintf(stderr, "warning: node '%s': %s\n", node.c_str(), msg.c_str());
  };
  Executor ex;
  ex.run(p, opt);

  std::vector<std::unique_ptr<render::Display>> displays;
  for (size_t k = 0; k < targets.size(); ++k) {
    const auto& t = targets[k];
    DataPtr data;
    if (auto it = results.find(t.ref.node); it != results.end())
      if (auto o = it->second.find(t.ref.port); o != it->second.end()) data = o->second;
    if (!data) throw Error("--node " + t.text + ": node '" + t.ref.node + "' gave no output '" + t.ref.port + "'");
    try {
      displays.push_back(render::make_display(data, render::palette_color(k)));
    } catch (const InputError& e) {
      throw InputError("--node " + t.text + ": " + e.what());
    }
  }
  if (!color_by.empty()) {
    bool any = false;
    for (size_t k = 0; k < displays.size(); ++k) {
      auto* d = displays[k].get();
      if (dynamic_cast<render::VolumeDisplay*>(d)) continue;
      any = true;
      if (!d->set_color_by(color_by)) {
        std::string list;
        for (const auto& c : d->color_choices()) list += (list.empty() ? "" : ", ") + c;
        throw InputError("--color-by " + color_by + ": " + targets[k].text + " (" + d->data()->type_id() +
                         ") has no attribute '" + color_by + "'" + did_you_mean(color_by, d->color_choices()) +
                         "; it has: " + (list.empty() ? "none" : list));
      }
    }
    if (!any) throw InputError("--color-by " + color_by + ": colours graphs and meshes; no --node is one");
  }
  if (volume_mode)
    for (auto& d : displays)
      if (auto* v = dynamic_cast<render::VolumeDisplay*>(d.get())) v->set_mode(*volume_mode);

  render::RenderOptions ro;
  ro.width = width;
  ro.height = height;
  ro.camera = camera;
  std::vector<render::Display*> raw;
  for (auto& d : displays) raw.push_back(d.get());
  const render::Image img = render::render_image(raw, ro);
  render::write_png(img, out);
  if (!quiet) std::printf("wrote %s (%dx%d)\n", out.c_str(), img.width, img.height);
  return 0;
#endif
}

}  // namespace skel::cli
