// The header of a PLY file (core/ply_header.h).
//
// A header is a list of names written by whoever made the file, so nothing here is
// quadratic in its length: duplicate names are found by sorting once (not by comparing
// each new name with all before it: 100k properties took 15 s), and the arrays are sized
// once from a first count of the lines, so that a long header costs a few times its bytes.

#include "core/ply_header.h"

#include <algorithm>
#include <cassert>
#include <climits>
#include <cstdio>
#include <optional>
#include <utility>

#include "core/error.h"
#include "core/ply_codec.h"

namespace hw::core::ply_internal {

namespace fs = std::filesystem;

namespace {

// The lines after the "ply" line as the parser sees them: each ends with '\n' (an
// unterminated last line is not a line), without a trailing '\r'. Numbered from 1 for the
// "ply" line.
class HeaderLines {
 public:
  explicit HeaderLines(std::string_view data) : data_(data) {
    const size_t first_end = data.find('\n');
    pos_ = first_end == std::string_view::npos ? data.size() : first_end + 1;
  }

  bool Next(std::string_view* line) {
    const size_t end = data_.find('\n', pos_);
    if (end == std::string_view::npos) return false;
    *line = data_.substr(pos_, end - pos_);
    pos_ = end + 1;
    ++number_;
    if (!line->empty() && line->back() == '\r') line->remove_suffix(1);
    return true;
  }

  size_t number() const { return number_; }  // of the last line returned
  size_t pos() const { return pos_; }        // just after it

 private:
  std::string_view data_;
  size_t pos_ = 0;
  size_t number_ = 1;
};

// The number of fields of `line` (as SplitFields splits it) and, if any, the first one;
// without allocating.
size_t CountFields(std::string_view line, std::string_view* first) {
  size_t n = 0;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const size_t begin = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > begin && n++ == 0) *first = line.substr(begin, i - begin);
  }
  return n;
}

struct LineCounts {
  size_t comments = 0;
  size_t elements = 0;
  size_t properties = 0;
};

// Counts the lines that can become comments, elements and properties (those with the
// keyword and a valid number of fields) up to end_header, so that their arrays are
// allocated once at their final size: no growth slack, no copying while they grow.
LineCounts CountLines(std::string_view data) {
  LineCounts counts;
  HeaderLines lines(data);
  std::string_view line;
  while (lines.Next(&line)) {
    std::string_view keyword;
    const size_t n = CountFields(line, &keyword);
    if (n == 0) continue;
    if (keyword == "comment") {
      ++counts.comments;
    } else if (keyword == "element" && n == 3) {
      ++counts.elements;
    } else if (keyword == "property" && (n == 3 || n == 5)) {
      ++counts.properties;
    } else if (keyword == "end_header") {
      break;
    }
  }
  return counts;
}

// The number of the line that starts with the `nth` (0-based) `keyword`. Every such line
// before an error became an element or property (or the error would have been there), so
// the nth element or property parsed is on that line. Only used for messages: lines are
// not stored with the names, which keeps the header small.
size_t LineOf(std::string_view data, std::string_view keyword, size_t nth) {
  HeaderLines lines(data);
  std::string_view line;
  size_t seen = 0;
  while (lines.Next(&line)) {
    std::string_view first;
    if (CountFields(line, &first) > 0 && first == keyword && seen++ == nth) return lines.number();
  }
  assert(false && "LineOf: fewer lines than parsed names");
  return 0;
}

// Points every element's span at its part of header.properties (the elements' sizes are
// kept while parsing; the array may not have been where it is now).
void RepointProperties(Header& header) {
  size_t offset = 0;
  for (ElementDesc& element : header.elements) {
    const size_t n = element.properties.size();
    element.properties = std::span<const PropertyDesc>(header.properties).subspan(offset, n);
    offset += n;
  }
  assert(offset == header.properties.size());
}

// The error for the first name in file order that repeats an earlier one (element names
// in the file, property names in their element), or nullopt when none does.
std::optional<InputError> DuplicateError(Header& header, std::string_view data,
                                         const fs::path& path) {
  RepointProperties(header);
  const std::vector<ElementDesc>& elements = header.elements;
  const size_t repeated_element =
      FirstRepeated(elements.size(), [&](size_t i) { return elements[i].name; });
  // Properties of the elements before the repeated one come before it in the file.
  size_t offset = 0;  // of the element's properties in header.properties
  for (size_t i = 0; i < repeated_element; ++i) {
    const std::span<const PropertyDesc> properties = elements[i].properties;
    const size_t j = FirstRepeated(properties.size(), [&](size_t k) { return properties[k].name; });
    if (j < properties.size()) {
      return InputError(path, "line " + std::to_string(LineOf(data, "property", offset + j)) +
                                  ": duplicate property " + Quoted(properties[j].name) +
                                  " in element " + std::string(elements[i].name));
    }
    offset += properties.size();
  }
  if (repeated_element < elements.size()) {
    return InputError(path, "line " + std::to_string(LineOf(data, "element", repeated_element)) +
                                ": duplicate element " + Quoted(elements[repeated_element].name));
  }
  return std::nullopt;
}

}  // namespace

std::string FormatName(PlyFormat format) {
  switch (format) {
    case PlyFormat::kAscii:
      return "ascii";
    case PlyFormat::kBinaryLittleEndian:
      return "binary_little_endian";
    case PlyFormat::kBinaryBigEndian:
      return "binary_big_endian";
  }
  assert(false && "bad PlyFormat");
  return "";
}

bool IsFaceIndexList(const ElementDesc& element, const PropertyDesc& property) {
  return element.name == "face" && property.is_list &&
         (property.name == "vertex_indices" || property.name == "vertex_index");
}

Header ParseHeader(std::string_view data, const fs::path& path) {
  if (!data.starts_with("ply\n") && !data.starts_with("ply\r\n")) {
    throw InputError(path, "not a PLY file: the first line is not 'ply'");
  }
  Header header;
  const LineCounts counts = CountLines(data);
  header.comments.reserve(counts.comments);
  header.elements.reserve(counts.elements);
  header.properties.reserve(counts.properties);

  // Names are checked for repeats once, at the end or at the first other error: a
  // repeated name on an earlier line than that error is the one reported, as if each
  // line had been checked in turn.
  const auto error = [&](size_t line, const std::string& reason) -> InputError {
    if (std::optional<InputError> duplicate = DuplicateError(header, data, path)) {
      return *duplicate;
    }
    return InputError(path, "line " + std::to_string(line) + ": " + reason);
  };
  bool have_format = false;
  HeaderLines lines(data);
  std::string_view line;
  while (true) {
    if (!lines.Next(&line)) {
      if (std::optional<InputError> duplicate = DuplicateError(header, data, path)) {
        throw *duplicate;
      }
      throw InputError(
          path, "no end_header line (header ends at line " + std::to_string(lines.number()) + ")");
    }
    const size_t line_number = lines.number();
    // The header is text: a control byte means binary garbage, and would end up in names
    // and comments that could not be written back.
    for (const char c : line) {
      const auto u = static_cast<unsigned char>(c);
      if ((u < 0x20 && c != '\t') || u == 0x7f) {
        char hex[8];
        std::snprintf(hex, sizeof(hex), "0x%02x", u);
        throw error(line_number, std::string("control character ") + hex + " in the header");
      }
    }
    const std::vector<std::string_view> fields = SplitFields(line);
    if (fields.empty()) continue;
    const std::string_view keyword = fields[0];
    if (keyword == "comment") {
      std::string_view text = line.substr(line.find("comment") + 7);
      while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
      header.comments.emplace_back(text);
    } else if (keyword == "obj_info") {
      // Free text about the object; nothing to keep.
    } else if (keyword == "format") {
      if (have_format) throw error(line_number, "second format line");
      if (!header.elements.empty()) throw error(line_number, "format line after an element");
      if (fields.size() != 3) {
        throw error(line_number,
                    "expected 'format ascii|binary_little_endian|binary_big_endian 1.0', got " +
                        Quoted(line));
      }
      if (fields[1] == "ascii") {
        header.format = PlyFormat::kAscii;
      } else if (fields[1] == "binary_little_endian") {
        header.format = PlyFormat::kBinaryLittleEndian;
      } else if (fields[1] == "binary_big_endian") {
        header.format = PlyFormat::kBinaryBigEndian;
      } else {
        throw error(line_number, "unknown format " + Quoted(fields[1]) +
                                     " (expected ascii, binary_little_endian or "
                                     "binary_big_endian)");
      }
      if (fields[2] != "1.0" && fields[2] != "1") {
        throw error(line_number,
                    "unsupported PLY version " + Quoted(fields[2]) + " (expected 1.0)");
      }
      have_format = true;
    } else if (keyword == "element") {
      if (!have_format) throw error(line_number, "element before the format line");
      if (fields.size() != 3) {
        throw error(line_number, "expected 'element <name> <count>', got " + Quoted(line));
      }
      ElementDesc element;
      element.name = fields[1];
      if (!ParseUInt64(fields[2], &element.count)) {
        throw error(line_number, "element " + Quoted(fields[1]) +
                                     ": count is not a non-negative integer: " + Quoted(fields[2]));
      }
      header.elements.push_back(element);
    } else if (keyword == "property") {
      if (header.elements.empty()) throw error(line_number, "property before any element");
      PropertyDesc property;
      if (fields.size() >= 2 && fields[1] == "list") {
        if (fields.size() != 5) {
          throw error(
              line_number,
              "expected 'property list <count type> <item type> <name>', got " + Quoted(line));
        }
        const std::optional<PlyType> count_type = ParsePlyType(fields[2]);
        const std::optional<PlyType> item_type = ParsePlyType(fields[3]);
        if (!count_type) throw error(line_number, "unknown property type " + Quoted(fields[2]));
        if (!item_type) throw error(line_number, "unknown property type " + Quoted(fields[3]));
        if (!PlyTypeIsInteger(*count_type)) {
          throw error(line_number,
                      "list count type must be an integer type, got " + Quoted(fields[2]));
        }
        property.is_list = true;
        property.count_type = *count_type;
        property.type = *item_type;
        property.name = fields[4];
      } else {
        if (fields.size() != 3) {
          throw error(line_number, "expected 'property <type> <name>', got " + Quoted(line));
        }
        const std::optional<PlyType> type = ParsePlyType(fields[1]);
        if (!type) throw error(line_number, "unknown property type " + Quoted(fields[1]));
        property.type = *type;
        property.name = fields[2];
      }
      // Added before the checks below so that, as a repeated name, it is reported first.
      header.properties.push_back(property);
      ElementDesc& element = header.elements.back();
      element.properties =
          std::span<const PropertyDesc>(header.properties).last(element.properties.size() + 1);
      if (element.name == "face" && !property.is_list &&
          (property.name == "vertex_indices" || property.name == "vertex_index")) {
        throw error(line_number, "face property " + std::string(property.name) + " must be a list");
      }
      if (IsFaceIndexList(element, property) && !PlyTypeIsInteger(property.type)) {
        throw error(line_number, "vertex indices must be of an integer type, got " +
                                     std::string(PlyTypeName(property.type)));
      }
    } else if (keyword == "end_header") {
      if (fields.size() != 1) throw error(line_number, "text after end_header");
      if (!have_format) throw error(line_number, "end_header before the format line");
      break;
    } else {
      throw error(line_number, "unknown header keyword " + Quoted(keyword));
    }
  }
  header.data_offset = lines.pos();
  header.num_lines = lines.number();
  if (std::optional<InputError> duplicate = DuplicateError(header, data, path)) throw *duplicate;

  for (const ElementDesc& element : header.elements) {
    if (element.name == "vertex") {
      const bool has_scalar = std::any_of(element.properties.begin(), element.properties.end(),
                                          [](const PropertyDesc& p) { return !p.is_list; });
      if (element.count > 0 && !has_scalar) {
        throw InputError(path, "element vertex has " + std::to_string(element.count) +
                                   " vertices but no scalar property");
      }
      if (element.count > static_cast<uint64_t>(INT_MAX)) {
        throw InputError(path, "element vertex: " + std::to_string(element.count) +
                                   " vertices, more than the " + std::to_string(INT_MAX) +
                                   " supported");
      }
    } else if (element.name == "face") {
      const auto n =
          std::count_if(element.properties.begin(), element.properties.end(),
                        [&](const PropertyDesc& p) { return IsFaceIndexList(element, p); });
      if (n == 0 && element.count > 0) {
        throw InputError(path, "element face has no list property vertex_indices");
      }
      if (n > 1) {
        throw InputError(path, "element face has both vertex_indices and vertex_index");
      }
    }
  }
  return header;
}

}  // namespace hw::core::ply_internal
