// The resume manifest and table files of out-of-core runs (resume.hpp).
#include "resume.hpp"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <type_traits>
#include <sstream>

#include "skel/error.hpp"
#include "skel/fs.hpp"

namespace fs = std::filesystem;

namespace skel::detail {

namespace {

std::string hex(uint64_t v) {
  char b[24];
  std::snprintf(b, sizeof b, "%016llx", static_cast<unsigned long long>(v));
  return b;
}

uint64_t from_hex(const std::string& s, const std::string& where) {
  if (s.empty() || s.size() > 16 || s.find_first_not_of("0123456789abcdef") != std::string::npos)
    throw Error(where + ": '" + s + "' is no hash");
  return std::stoull(s, nullptr, 16);
}

std::string num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

}  // namespace

std::string resume_manifest_name(int rank, int ranks) {
  return ranks > 1 && rank > 0 ? "manifest.r" + std::to_string(rank) + ".txt" : std::string(kResumeManifest);
}

std::string manifest_text(const ResumeManifest& m) {
  std::ostringstream o;
  o << "skelflow-resume 1\n";
  o << "pid " << m.pid << "\n";
  if (m.ranks != 1) o << "ranks " << m.ranks << "\n";
  o << "pipeline " << hex(m.pipeline_hash) << "\n";
  o << "params " << hex(m.params_hash) << "\n";
  o << "budget " << m.memory_budget << "\n";
  o << "block " << m.block[0] << " " << m.block[1] << " " << m.block[2] << "\n";
  for (const auto& [id, k] : m.keys) o << "key " << id << " " << hex(k) << "\n";
  for (const auto& [path, stamp] : m.inputs) o << "input " << stamp << "\t" << path << "\n";
  for (const auto& [id, n] : m.done) {
    o << "done " << id << " " << hex(n.key) << "\n";
    for (const auto& out : n.outputs) {
      o << "out " << id << " " << out.port << " " << out.kind << " " << out.file;
      if (out.kind == "volume") {
        const Grid& g = out.grid;
        o << " " << out.type_id << " " << g.dims[0] << " " << g.dims[1] << " " << g.dims[2];
        for (double v : g.spacing) o << " " << num(v);
        for (double v : g.origin) o << " " << num(v);
        for (double v : g.direction) o << " " << num(v);
        o << " " << g.unit;
      }
      o << "\n";
    }
  }
  o << "end\n";
  return o.str();
}

ResumeManifest parse_manifest(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw Error(file.string() + ": cannot read");
  ResumeManifest m;
  std::string line;
  int n = 0;
  bool ended = false;
  while (std::getline(in, line)) {
    ++n;
    const std::string where = file.string() + ":" + std::to_string(n);
    std::istringstream l(line);
    std::string what;
    l >> what;
    if (n == 1) {
      if (line != "skelflow-resume 1") throw Error(where + ": not a Skelflow resume manifest");
      continue;
    }
    if (what == "pid") l >> m.pid;
    else if (what == "ranks") l >> m.ranks;
    else if (what == "pipeline") { std::string h; l >> h; m.pipeline_hash = from_hex(h, where); }
    else if (what == "params") { std::string h; l >> h; m.params_hash = from_hex(h, where); }
    else if (what == "budget") l >> m.memory_budget;
    else if (what == "block") l >> m.block[0] >> m.block[1] >> m.block[2];
    else if (what == "key") { std::string id, h; l >> id >> h; m.keys[id] = from_hex(h, where); }
    else if (what == "input") {
      const size_t tab = line.find('\t');
      if (tab == std::string::npos) throw Error(where + ": malformed input line");
      m.inputs[line.substr(tab + 1)] = line.substr(6, tab - 6);
    } else if (what == "done") { std::string id, h; l >> id >> h; m.done[id].key = from_hex(h, where); }
    else if (what == "out") {
      std::string id;
      ResumeOutput o;
      l >> id >> o.port >> o.kind >> o.file;
      if (!m.done.count(id)) throw Error(where + ": output of a stage not listed as done");
      if (o.kind == "volume") {
        Grid& g = o.grid;
        l >> o.type_id >> g.dims[0] >> g.dims[1] >> g.dims[2];
        for (double& v : g.spacing) l >> v;
        for (double& v : g.origin) l >> v;
        for (double& v : g.direction) l >> v;
        std::getline(l >> std::ws, g.unit);
      } else if (o.kind != "table") {
        throw Error(where + ": unknown output kind '" + o.kind + "'");
      }
      if (!l && !l.eof()) throw Error(where + ": malformed output line");
      m.done[id].outputs.push_back(std::move(o));
    } else if (what == "end") {
      ended = true;
    } else {
      throw Error(where + ": unknown record '" + what + "'");
    }
    if (l.fail() && !l.eof()) throw Error(where + ": malformed line");
  }
  if (!ended) throw Error(file.string() + ": incomplete (no 'end' line)");
  return m;
}

void save_table(const fs::path& file, const Table& t) {
  std::string b = "skelflow-table 1\n";
  auto put = [&](const void* p, size_t n) { b.append(static_cast<const char*>(p), n); };
  auto put_u64 = [&](uint64_t v) { put(&v, sizeof v); };
  auto put_str = [&](const std::string& s) { put_u64(s.size()); put(s.data(), s.size()); };
  put_u64(t.columns().size());
  for (const auto& c : t.columns()) {
    put_str(c.name);
    put_str(c.unit);
    put_u64(c.values.index());
    std::visit([&](const auto& v) {
      put_u64(v.size());
      using E = typename std::decay_t<decltype(v)>::value_type;
      if constexpr (std::is_same_v<E, std::string>)
        for (const auto& s : v) put_str(s);
      else
        put(v.data(), v.size() * sizeof(E));
    }, c.values);
  }
  write_file_atomically(file, b);
}

Table load_table(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::string b((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string magic = "skelflow-table 1\n";
  if (b.compare(0, magic.size(), magic) != 0) throw Error(file.string() + ": not a Skelflow table file");
  size_t pos = magic.size();
  auto get = [&](void* p, size_t n) {
    if (pos + n > b.size()) throw Error(file.string() + ": truncated");
    std::memcpy(p, b.data() + pos, n);
    pos += n;
  };
  auto get_u64 = [&] { uint64_t v; get(&v, sizeof v); return v; };
  auto get_str = [&] {
    const uint64_t n = get_u64();
    if (n > b.size() - pos) throw Error(file.string() + ": truncated");
    std::string s = b.substr(pos, n);
    pos += n;
    return s;
  };
  Table t;
  const uint64_t cols = get_u64();
  for (uint64_t c = 0; c < cols; ++c) {
    std::string name = get_str(), unit = get_str();
    const uint64_t kind = get_u64(), count = get_u64();
    if (count > b.size()) throw Error(file.string() + ": truncated");
    if (kind == 0) {
      std::vector<int64_t> v(count);
      get(v.data(), count * sizeof(int64_t));
      t.add(std::move(name), std::move(v), std::move(unit));
    } else if (kind == 1) {
      std::vector<double> v(count);
      get(v.data(), count * sizeof(double));
      t.add(std::move(name), std::move(v), std::move(unit));
    } else if (kind == 2) {
      std::vector<std::string> v(count);
      for (auto& s : v) s = get_str();
      t.add(std::move(name), std::move(v), std::move(unit));
    } else {
      throw Error(file.string() + ": unknown column kind");
    }
  }
  return t;
}

std::string file_stamp(const fs::path& p) {
  std::error_code ec;
  const auto st = fs::status(p, ec);
  if (ec || !fs::exists(st)) return "missing";
  const auto t = fs::last_write_time(p, ec).time_since_epoch().count();
  const uintmax_t size = fs::is_regular_file(st) ? fs::file_size(p, ec) : 0;
  return std::to_string(size) + "-" + std::to_string(static_cast<long long>(t));
}

bool other_process_alive(int64_t pid) {
  if (pid <= 0 || pid == static_cast<int64_t>(::getpid())) return false;
  return ::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM;
}

}  // namespace skel::detail
