// One target per graph format (SKEL_FUZZ_GRAPH_FORMAT selects it at compile time): the text goes to
// graph_from_text, the in-memory reader that read_graph uses. For CSV the input is split at the first
// form feed (\f) into the edge-points table and the nodes table.
#include "fuzz_common.hpp"
#include "io/graph_io.hpp"
#include "skel/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using skel::io::GraphFormat;
  constexpr GraphFormat format = GraphFormat::SKEL_FUZZ_GRAPH_FORMAT;
  std::string text = skel::fuzz::as_text(data, size), nodes;
  if (format == GraphFormat::csv) {
    const size_t ff = text.find('\f');
    if (ff != std::string::npos) {
      nodes = text.substr(ff + 1);
      text.resize(ff);
    }
  }
  try {
    const skel::SpatialGraph g = skel::io::graph_from_text(text, format, nodes, "fuzz");
    // What a reader returns must be a valid graph.
    if (!g.check_invariants().empty()) std::abort();
  } catch (const skel::Error&) {
  }
  return 0;
}
