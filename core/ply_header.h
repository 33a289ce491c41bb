#pragma once

// Internals of the PLY reader (core/ply.h): the header of a PLY file, parsed and checked.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/ply.h"

namespace hw::core::ply_internal {

struct PropertyDesc {
  std::string_view name;             // a view into the file's bytes
  PlyType type = PlyType::kFloat32;  // the item type of a list
  bool is_list = false;
  PlyType count_type = PlyType::kUInt8;
};

struct ElementDesc {
  std::string_view name;  // a view into the file's bytes
  uint64_t count = 0;
  std::span<const PropertyDesc> properties;  // in Header::properties
};

// Names are views into the data parsed and element property spans point into
// `properties`: a Header is valid while the data is, and moves but does not copy.
struct Header {
  Header() = default;
  Header(const Header&) = delete;
  Header& operator=(const Header&) = delete;
  Header(Header&&) = default;
  Header& operator=(Header&&) = default;

  PlyFormat format = PlyFormat::kAscii;
  std::vector<ElementDesc> elements;
  // The properties of every element, in file order: one array sized once, rather than a
  // growing vector per element.
  std::vector<PropertyDesc> properties;
  std::vector<std::string> comments;
  size_t data_offset = 0;  // first byte after the end_header line
  size_t num_lines = 0;    // lines up to and including end_header
};

// Parses and checks the header at the start of `data`. Throws InputError naming `path`,
// with the line, for anything wrong: syntax, unknown types, duplicate element or
// property names (found by sorting, in O(n log n) for n names), counts over the limits.
// Allocates a few times the header's size at most.
Header ParseHeader(std::string_view data, const std::filesystem::path& path);

// "ascii", "binary_little_endian" or "binary_big_endian".
std::string FormatName(PlyFormat format);

// Whether `property` is the list of vertex indices of a face element.
bool IsFaceIndexList(const ElementDesc& element, const PropertyDesc& property);

}  // namespace hw::core::ply_internal
