#pragma once
// Type-erased data objects that flow between nodes. Published outputs are immutable and shared by
// reference (std::shared_ptr<const DataObject>); editing makes a copy.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace skel {

// Type identifiers used by ports. Volumes are "volume.<dtype>"; others name their kind.
namespace type_ids {
inline constexpr const char* volume_u8 = "volume.u8";
inline constexpr const char* volume_u16 = "volume.u16";
inline constexpr const char* volume_u32 = "volume.u32";
inline constexpr const char* volume_u64 = "volume.u64";
inline constexpr const char* volume_i32 = "volume.i32";
inline constexpr const char* volume_f32 = "volume.f32";
inline constexpr const char* volume_f64 = "volume.f64";
inline constexpr const char* table = "table";
inline constexpr const char* graph = "graph";
inline constexpr const char* landmarks = "landmarks";
inline constexpr const char* transform = "transform";
inline constexpr const char* mesh = "mesh";
}  // namespace type_ids

class DataObject {
public:
  virtual ~DataObject() = default;
  // The port type identifier of this object, e.g. "volume.u8" or "table".
  [[nodiscard]] virtual std::string type_id() const = 0;
  // Bytes held in memory (for the run report and memory accounting).
  [[nodiscard]] virtual uint64_t bytes() const = 0;
  // One line for `skelflow info`, logs and the GUI, e.g. "volume.u8 128x128x64, spacing 1 1 2 µm".
  [[nodiscard]] virtual std::string describe() const = 0;
  // Physical unit of the object's coordinates and lengths ("µm", "mm", ...); empty when it has none
  // (tables carry a unit per column, transforms none). The run report lists it per output.
  [[nodiscard]] virtual std::string physical_unit() const { return {}; }
};

using DataPtr = std::shared_ptr<const DataObject>;

// All volume type ids, for ports that accept any volume.
const std::vector<std::string>& all_volume_types();
// Volume type ids of integer voxel types.
const std::vector<std::string>& integer_volume_types();

}  // namespace skel
