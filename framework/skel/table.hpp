#pragma once
// Table: named, typed columns of equal length (component sizes, segment statistics, residuals...).
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "skel/data.hpp"

namespace skel {

class Table final : public DataObject {
public:
  using Column = std::variant<std::vector<int64_t>, std::vector<double>, std::vector<std::string>>;
  struct NamedColumn {
    std::string name;
    std::string unit;  // physical unit or empty
    Column values;
  };

  // Adds a column; throws Error if the name exists or the length differs from existing columns.
  Table& add(std::string name, Column values, std::string unit = {});
  [[nodiscard]] int64_t rows() const;
  [[nodiscard]] const std::vector<NamedColumn>& columns() const { return columns_; }
  [[nodiscard]] bool has(const std::string& name) const;
  [[nodiscard]] const NamedColumn& column(const std::string& name) const;  // throws if missing
  // Typed access; throws Error if missing or of another type.
  [[nodiscard]] const std::vector<int64_t>& ints(const std::string& name) const;
  [[nodiscard]] const std::vector<double>& reals(const std::string& name) const;
  [[nodiscard]] const std::vector<std::string>& strings(const std::string& name) const;
  // Cell as text (for CSV and display).
  [[nodiscard]] std::string cell(size_t col, int64_t row) const;
  // CSV with a header line "name [unit]"; strings quoted when needed.
  [[nodiscard]] std::string to_csv() const;

  [[nodiscard]] std::string type_id() const override { return type_ids::table; }
  [[nodiscard]] uint64_t bytes() const override;
  [[nodiscard]] std::string describe() const override;

private:
  std::vector<NamedColumn> columns_;
};

}  // namespace skel
