#include "skel/table.hpp"

#include <iomanip>
#include <limits>
#include <sstream>

#include "skel/error.hpp"

namespace skel {

namespace {
int64_t column_size(const Table::Column& c) {
  return std::visit([](const auto& v) { return static_cast<int64_t>(v.size()); }, c);
}
std::string format_double(double v) {
  std::ostringstream s;
  s << std::setprecision(std::numeric_limits<double>::max_digits10 - 2) << v;
  return s.str();
}
std::string csv_quote(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}
}  // namespace

Table& Table::add(std::string name, Column values, std::string unit) {
  if (has(name)) throw Error("table already has a column '" + name + "'");
  if (!columns_.empty() && column_size(values) != rows()) {
    throw Error("table column '" + name + "' has " + std::to_string(column_size(values)) +
                " rows; the table has " + std::to_string(rows()));
  }
  columns_.push_back({std::move(name), std::move(unit), std::move(values)});
  return *this;
}

int64_t Table::rows() const { return columns_.empty() ? 0 : column_size(columns_.front().values); }

bool Table::has(const std::string& name) const {
  for (const auto& c : columns_)
    if (c.name == name) return true;
  return false;
}

const Table::NamedColumn& Table::column(const std::string& name) const {
  for (const auto& c : columns_)
    if (c.name == name) return c;
  throw Error("table has no column '" + name + "'");
}

template <class V>
static const V& typed(const Table& t, const std::string& name, const char* what) {
  const auto& c = t.column(name);
  if (auto* p = std::get_if<V>(&c.values)) return *p;
  throw Error("table column '" + name + "' is not of type " + what);
}
const std::vector<int64_t>& Table::ints(const std::string& n) const { return typed<std::vector<int64_t>>(*this, n, "int"); }
const std::vector<double>& Table::reals(const std::string& n) const { return typed<std::vector<double>>(*this, n, "float"); }
const std::vector<std::string>& Table::strings(const std::string& n) const {
  return typed<std::vector<std::string>>(*this, n, "string");
}

std::string Table::cell(size_t col, int64_t row) const {
  const auto& v = columns_.at(col).values;
  if (auto* i = std::get_if<std::vector<int64_t>>(&v)) return std::to_string((*i)[static_cast<size_t>(row)]);
  if (auto* d = std::get_if<std::vector<double>>(&v)) return format_double((*d)[static_cast<size_t>(row)]);
  return std::get<std::vector<std::string>>(v)[static_cast<size_t>(row)];
}

std::string Table::to_csv() const {
  std::ostringstream s;
  for (size_t c = 0; c < columns_.size(); ++c) {
    if (c) s << ',';
    std::string h = columns_[c].name;
    if (!columns_[c].unit.empty()) h += " [" + columns_[c].unit + "]";
    s << csv_quote(h);
  }
  s << '\n';
  for (int64_t r = 0; r < rows(); ++r) {
    for (size_t c = 0; c < columns_.size(); ++c) {
      if (c) s << ',';
      s << csv_quote(cell(c, r));
    }
    s << '\n';
  }
  return s.str();
}

uint64_t Table::bytes() const {
  uint64_t b = 0;
  for (const auto& c : columns_) {
    std::visit(
        [&](const auto& v) {
          using E = typename std::decay_t<decltype(v)>::value_type;
          if constexpr (std::is_same_v<E, std::string>) {
            for (const auto& s : v) b += s.size() + sizeof(std::string);
          } else {
            b += v.size() * sizeof(E);
          }
        },
        c.values);
  }
  return b;
}

std::string Table::describe() const {
  std::ostringstream s;
  s << "table " << rows() << " rows x " << columns_.size() << " columns (";
  for (size_t c = 0; c < columns_.size(); ++c) s << (c ? ", " : "") << columns_[c].name;
  s << ")";
  return s.str();
}

}  // namespace skel
