// Reading PLY files (core/ply.h): the data after the header, binary or ASCII.
//
// Memory stays within what the mesh itself takes (8 bytes per vertex value, 12 per
// triangle) plus the file: every count in the file is checked against the bytes that
// follow before anything is allocated for it, polygons are triangulated straight from
// the data (no copy of the polygon), and the triangle array is allocated once at its
// final size, counted in a first pass over the face rows (growing it would hold up to
// three times its size for a moment).

#include <algorithm>
#include <cassert>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/ply.h"
#include "core/ply_codec.h"
#include "core/ply_header.h"

namespace hw::core {

namespace fs = std::filesystem;

namespace {

using ply_internal::Dispatch;
using ply_internal::ElementDesc;
using ply_internal::Header;
using ply_internal::IsFaceIndexList;
using ply_internal::Load;
using ply_internal::LoadAsDouble;
using ply_internal::NeedsSwap;
using ply_internal::ParseAsciiValue;
using ply_internal::PropertyDesc;
using ply_internal::Quoted;
using ply_internal::ToText;

// What reading an element fills in.
struct Sink {
  // Per property of the element: the column its values go to, or null to skip.
  std::vector<double*> columns;
  std::vector<Eigen::Vector3i>* faces = nullptr;  // for face: triangles go here
  int64_t num_vertices = 0;                       // for face: indices must be below
};

// Decodes one column of a table of fixed-size rows.
template <typename T, bool kSwap>
void DecodeColumn(const char* first, size_t stride, size_t n, double* out) {
  for (size_t i = 0; i < n; ++i) out[i] = static_cast<double>(Load<T, kSwap>(first + i * stride));
}

std::string TooFewIndices(uint64_t n) {
  return std::to_string(n) + " vertex indices, a face needs at least 3";
}

std::string OutOfRange(int64_t index, int64_t num_vertices) {
  return "vertex index " + std::to_string(index) + " out of range (" +
         std::to_string(num_vertices) + " vertices)";
}

std::string BytesOf(uint64_t count, size_t row_bytes) {
  if (row_bytes != 0 && count > std::numeric_limits<uint64_t>::max() / row_bytes) {
    return std::to_string(count) + " x " + std::to_string(row_bytes);
  }
  return std::to_string(count * row_bytes);
}

// "face 12", naming a row in messages.
std::string RowName(const ElementDesc& element, uint64_t row) {
  return std::string(element.name) + " " + std::to_string(row);
}

// Reads one vertex index of a given integer type and byte order.
using IndexLoader = int64_t (*)(const char*);

template <typename T, bool kSwap>
int64_t LoadIndex(const char* p) {
  return static_cast<int64_t>(Load<T, kSwap>(p));
}

IndexLoader IndexLoaderFor(PlyType type, bool swap) {
  return Dispatch(type, [&](auto tag) -> IndexLoader {
    using T = decltype(tag);
    if constexpr (std::is_integral_v<T>) {
      return swap ? &LoadIndex<T, true> : &LoadIndex<T, false>;
    } else {
      assert(false && "vertex indices of a float type are rejected with the header");
      return nullptr;
    }
  });
}

class BinaryReader {
 public:
  BinaryReader(std::string_view data, size_t pos, bool swap, const fs::path& path)
      : data_(data), pos_(pos), swap_(swap), path_(path) {}

  // Throws unless the rest of the data can hold `element`, judging by the smallest
  // possible row, so that nothing is allocated for counts a corrupted header made up.
  void CheckFits(const ElementDesc& element) const {
    const size_t remaining = data_.size() - pos_;
    size_t min_row = 0;
    bool has_list = false;
    for (const PropertyDesc& p : element.properties) {
      has_list = has_list || p.is_list;
      min_row += p.is_list ? PlyTypeSize(p.count_type) : PlyTypeSize(p.type);
      if (IsFaceIndexList(element, p)) min_row += 3 * PlyTypeSize(p.type);
    }
    if (min_row == 0 || element.count <= remaining / min_row) return;
    throw InputError(path_, "truncated: expected " + std::string(has_list ? "at least " : "") +
                                BytesOf(element.count, min_row) + " bytes of " +
                                std::string(element.name) + " data, got " +
                                std::to_string(remaining));
  }

  void ReadElement(const ElementDesc& element, const Sink& sink) {
    CheckFits(element);
    const bool has_list = std::any_of(element.properties.begin(), element.properties.end(),
                                      [](const PropertyDesc& p) { return p.is_list; });
    if (!has_list) {
      size_t stride = 0;
      for (const PropertyDesc& p : element.properties) stride += PlyTypeSize(p.type);
      if (stride == 0) return;  // rows of no properties take no bytes
      const size_t n = element.count;
      size_t offset = 0;
      for (size_t j = 0; j < element.properties.size(); ++j) {
        const PlyType type = element.properties[j].type;
        if (sink.columns[j] != nullptr) {
          const char* first = data_.data() + pos_ + offset;
          Dispatch(type, [&](auto tag) {
            using T = decltype(tag);
            if (swap_) {
              DecodeColumn<T, true>(first, stride, n, sink.columns[j]);
            } else {
              DecodeColumn<T, false>(first, stride, n, sink.columns[j]);
            }
          });
        }
        offset += PlyTypeSize(type);
      }
      pos_ += n * stride;
      return;
    }

    // Rows of variable length. Per-property decisions are made once, not per row.
    std::vector<IndexLoader> index_loaders(element.properties.size(), nullptr);
    for (size_t j = 0; j < element.properties.size(); ++j) {
      if (sink.faces != nullptr && IsFaceIndexList(element, element.properties[j])) {
        index_loaders[j] = IndexLoaderFor(element.properties[j].type, swap_);
      }
    }
    if (sink.faces != nullptr) sink.faces->reserve(sink.faces->size() + CountTriangles(element));
    const auto num_vertices = static_cast<uint64_t>(sink.num_vertices);
    for (uint64_t row = 0; row < element.count; ++row) {
      for (size_t j = 0; j < element.properties.size(); ++j) {
        const PropertyDesc& p = element.properties[j];
        if (!p.is_list) {
          const char* value = Take(PlyTypeSize(p.type), element, row);
          if (sink.columns[j] != nullptr) sink.columns[j][row] = LoadAsDouble(p.type, value, swap_);
          continue;
        }
        const double count =
            LoadAsDouble(p.count_type, Take(PlyTypeSize(p.count_type), element, row), swap_);
        if (count < 0) {
          throw InputError(path_, RowName(element, row) + ": list " + std::string(p.name) +
                                      " has negative length " + ToText(count));
        }
        const auto n = static_cast<uint64_t>(count);
        const size_t item_size = PlyTypeSize(p.type);
        if (n > (data_.size() - pos_) / item_size) {
          throw InputError(path_, "truncated: " + RowName(element, row) + ": list " +
                                      std::string(p.name) + " of " + std::to_string(n) +
                                      " items needs " + BytesOf(n, item_size) + " bytes, got " +
                                      std::to_string(data_.size() - pos_));
        }
        const char* items = Take(n * item_size, element, row);
        const IndexLoader load = index_loaders[j];
        if (load == nullptr) continue;
        // Negative indices wrap to huge unsigned values: one comparison each.
        const auto valid = [&](int64_t index) {
          return static_cast<uint64_t>(index) < num_vertices;
        };
        if (n == 3) {  // the common case, checked at once
          const int64_t a = load(items);
          const int64_t b = load(items + item_size);
          const int64_t c = load(items + 2 * item_size);
          if (valid(a) && valid(b) && valid(c)) {
            sink.faces->emplace_back(static_cast<int>(a), static_cast<int>(b), static_cast<int>(c));
            continue;
          }
        }
        // A fan, straight from the data: each triangle needs only the first and the
        // previous index.
        const auto fail = [&](const std::string& problem) {
          return InputError(path_, RowName(element, row) + ": " + problem);
        };
        if (n < 3) throw fail(TooFewIndices(n));
        const int64_t first = load(items);
        int64_t previous = load(items + item_size);
        if (!valid(first)) throw fail(OutOfRange(first, sink.num_vertices));
        if (!valid(previous)) throw fail(OutOfRange(previous, sink.num_vertices));
        for (uint64_t k = 2; k < n; ++k) {
          const int64_t index = load(items + k * item_size);
          if (!valid(index)) throw fail(OutOfRange(index, sink.num_vertices));
          sink.faces->emplace_back(static_cast<int>(first), static_cast<int>(previous),
                                   static_cast<int>(index));
          previous = index;
        }
      }
    }
  }

  void CheckAtEnd() const {
    if (pos_ != data_.size()) {
      throw InputError(path_, std::to_string(data_.size() - pos_) +
                                  " bytes of unexpected data after the last element "
                                  "(wrong counts in the header?)");
    }
  }

 private:
  // The next `size` bytes; throws if the file ends before.
  const char* Take(size_t size, const ElementDesc& element, uint64_t row) {
    if (size > data_.size() - pos_) {
      throw InputError(path_, "truncated: the file ends inside " + RowName(element, row) + " of " +
                                  std::to_string(element.count));
    }
    const char* p = data_.data() + pos_;
    pos_ += size;
    return p;
  }

  // The triangles that the rows of `element` from here make, up to the first row that
  // reading will reject (which stops reading there; the triangles of its lists that are
  // complete are counted, as reading may add them before it finds the problem).
  uint64_t CountTriangles(const ElementDesc& element) const {
    size_t pos = pos_;
    uint64_t triangles = 0;
    for (uint64_t row = 0; row < element.count; ++row) {
      for (const PropertyDesc& p : element.properties) {
        const size_t size = PlyTypeSize(p.is_list ? p.count_type : p.type);
        if (size > data_.size() - pos) return triangles;
        if (!p.is_list) {
          pos += size;
          continue;
        }
        const double count = LoadAsDouble(p.count_type, data_.data() + pos, swap_);
        pos += size;
        if (count < 0) return triangles;
        const auto n = static_cast<uint64_t>(count);
        const size_t item_size = PlyTypeSize(p.type);
        if (n > (data_.size() - pos) / item_size) return triangles;
        pos += n * item_size;
        if (IsFaceIndexList(element, p) && n >= 3) triangles += n - 2;
      }
    }
    return triangles;
  }

  std::string_view data_;
  size_t pos_;
  bool swap_;
  const fs::path& path_;
};

class AsciiReader {
 public:
  AsciiReader(std::string_view data, size_t pos, size_t line_number, const fs::path& path)
      : data_(data), pos_(pos), line_number_(line_number), path_(path) {}

  // Throws unless the rest of the text can hold `element`: every property of a row takes
  // at least one value, and every value at least one character and a separator. Bounds
  // the count before anything is allocated for it.
  void CheckFits(const ElementDesc& element) const {
    const uint64_t min_values = MinValues(element);
    const uint64_t remaining = data_.size() - pos_;
    if (min_values == 0 || element.count <= (remaining + 1) / 2 / min_values) return;
    throw InputError(path_, "truncated: " + std::to_string(element.count) + " " +
                                std::string(element.name) + " rows need at least " +
                                BytesOf(element.count, min_values) + " values, but only " +
                                std::to_string(remaining) + " bytes of text follow");
  }

  void ReadElement(const ElementDesc& element, const Sink& sink) {
    CheckFits(element);
    if (MinValues(element) == 0) return;  // rows of no properties are blank lines
    if (sink.faces != nullptr) sink.faces->reserve(sink.faces->size() + CountTriangles(element));
    for (uint64_t row = 0; row < element.count; ++row) {
      if (!NextLine()) {
        throw InputError(path_, "truncated: the file ends after " + std::to_string(row) + " of " +
                                    std::to_string(element.count) + " " +
                                    std::string(element.name) + " rows");
      }
      const auto error = [&](const std::string& reason) {
        return InputError(path_, "line " + std::to_string(line_number_) + " (" +
                                     RowName(element, row) + "): " + reason);
      };
      size_t at = 0;  // position in line_
      const auto next_value = [&](const PropertyDesc& p, PlyType type) {
        std::string_view token;
        if (!NextToken(&at, &token)) {
          throw error("too few values: " + std::string(p.name) + " missing");
        }
        double value = 0;
        const std::string problem = ParseAsciiValue(token, type, &value);
        if (!problem.empty()) throw error(std::string(p.name) + ": " + problem);
        return value;
      };
      for (size_t j = 0; j < element.properties.size(); ++j) {
        const PropertyDesc& p = element.properties[j];
        if (!p.is_list) {
          const double value = next_value(p, p.type);
          if (sink.columns[j] != nullptr) sink.columns[j][row] = value;
          continue;
        }
        const double count = next_value(p, p.count_type);
        if (count < 0) {
          throw error("list " + std::string(p.name) + " has negative length " + ToText(count));
        }
        // A list cannot have more items than its line has characters.
        if (count > static_cast<double>(line_.size())) {
          // An integer (count types are), at most 2^32 - 1.
          throw error("list " + std::string(p.name) + " of " +
                      std::to_string(static_cast<uint64_t>(count)) +
                      " items is longer than its line");
        }
        const auto n = static_cast<uint64_t>(count);
        const bool is_face = sink.faces != nullptr && IsFaceIndexList(element, p);
        // The fan is added as the indices are read (it needs only the first and the previous
        // one); a bad index is reported after the whole list has been read, so that a value
        // that is not a number is reported first, wherever it is.
        int64_t first = 0;
        int64_t previous = 0;
        bool have_bad = false;
        int64_t bad = 0;
        for (uint64_t k = 0; k < n; ++k) {
          const double item = next_value(p, p.type);
          if (!is_face || have_bad) continue;
          const auto index = static_cast<int64_t>(item);
          if (index < 0 || index >= sink.num_vertices) {
            have_bad = true;
            bad = index;
            continue;
          }
          if (k == 0) {
            first = index;
          } else if (k >= 2) {
            sink.faces->emplace_back(static_cast<int>(first), static_cast<int>(previous),
                                     static_cast<int>(index));
          }
          previous = index;
        }
        if (is_face && n < 3) throw error(TooFewIndices(n));
        if (have_bad) throw error(OutOfRange(bad, sink.num_vertices));
      }
      std::string_view extra;
      if (NextToken(&at, &extra)) {
        throw error("more values than the element's properties, starting with " + Quoted(extra));
      }
    }
  }

  void CheckAtEnd() {
    if (NextLine()) {
      throw InputError(path_, "line " + std::to_string(line_number_) +
                                  ": unexpected data after the last element: " + Quoted(line_));
    }
  }

 private:
  static bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\r'; }

  static uint64_t MinValues(const ElementDesc& element) {
    uint64_t min_values = 0;
    for (const PropertyDesc& p : element.properties) {
      min_values += IsFaceIndexList(element, p) ? 4 : 1;
    }
    return min_values;
  }

  // The triangles that the rows of `element` from here make, up to the first row that
  // reading will reject. Reading adds the triangles of a list as it goes and may find a
  // problem only after them (a value that is not a number, too few values), so every
  // index present counts, even in the row where counting stops.
  uint64_t CountTriangles(const ElementDesc& element) const {
    AsciiReader scan = *this;
    uint64_t triangles = 0;
    for (uint64_t row = 0; row < element.count; ++row) {
      if (!scan.NextLine()) return triangles;
      size_t at = 0;
      std::string_view token;
      for (const PropertyDesc& p : element.properties) {
        if (!scan.NextToken(&at, &token)) return triangles;
        if (!p.is_list) continue;
        double count = 0;
        if (!ParseAsciiValue(token, p.count_type, &count).empty() || count < 0) return triangles;
        const auto n = static_cast<uint64_t>(count);
        uint64_t present = 0;
        while (present < n && scan.NextToken(&at, &token)) ++present;
        if (IsFaceIndexList(element, p) && present >= 3) triangles += present - 2;
        if (present < n) return triangles;
      }
    }
    return triangles;
  }

  // Advances to the next line with something on it; false at the end of the data.
  bool NextLine() {
    while (pos_ < data_.size()) {
      const size_t newline = data_.find('\n', pos_);
      const size_t end = newline == std::string_view::npos ? data_.size() : newline;
      line_ = data_.substr(pos_, end - pos_);
      pos_ = newline == std::string_view::npos ? data_.size() : newline + 1;
      ++line_number_;
      if (std::any_of(line_.begin(), line_.end(), [](char c) { return !IsSpace(c); })) {
        return true;
      }
    }
    return false;
  }

  bool NextToken(size_t* at, std::string_view* token) const {
    size_t i = *at;
    while (i < line_.size() && IsSpace(line_[i])) ++i;
    const size_t begin = i;
    while (i < line_.size() && !IsSpace(line_[i])) ++i;
    *at = i;
    *token = line_.substr(begin, i - begin);
    return i > begin;
  }

  std::string_view data_;
  size_t pos_;
  size_t line_number_;
  std::string_view line_;
  const fs::path& path_;
};

}  // namespace

PlyMesh ParsePly(std::string_view data, const fs::path& path_for_errors) {
  const fs::path& path = path_for_errors;
  Header header = ply_internal::ParseHeader(data, path);
  PlyMesh mesh;
  mesh.comments = std::move(header.comments);

  int64_t num_vertices = 0;
  for (const ElementDesc& element : header.elements) {
    if (element.name == "vertex") num_vertices = static_cast<int64_t>(element.count);
  }

  BinaryReader binary(data, header.data_offset, NeedsSwap(header.format), path);
  AsciiReader ascii(data, header.data_offset, header.num_lines, path);
  const bool is_ascii = header.format == PlyFormat::kAscii;
  for (const ElementDesc& element : header.elements) {
    Sink sink;
    sink.columns.assign(element.properties.size(), nullptr);
    if (element.name == "vertex") {
      // A count the data cannot hold throws here, before the allocation: every value
      // stored takes at least one byte of the file, so memory stays within a few times
      // the file size whatever the header says.
      if (is_ascii) {
        ascii.CheckFits(element);
      } else {
        binary.CheckFits(element);
      }
      const auto num_scalars = std::count_if(element.properties.begin(), element.properties.end(),
                                             [](const PropertyDesc& p) { return !p.is_list; });
      mesh.vertex_properties.reserve(static_cast<size_t>(num_scalars));
      for (size_t j = 0; j < element.properties.size(); ++j) {
        const PropertyDesc& p = element.properties[j];
        if (p.is_list) continue;
        mesh.vertex_properties.push_back(
            PlyProperty{std::string(p.name), p.type, std::vector<double>(element.count)});
        // The values' buffer stays where it is whatever happens to the vector holding it.
        sink.columns[j] = mesh.vertex_properties.back().values.data();
      }
    } else if (element.name == "face") {
      sink.faces = &mesh.faces;
      sink.num_vertices = num_vertices;
    }
    if (is_ascii) {
      ascii.ReadElement(element, sink);
    } else {
      binary.ReadElement(element, sink);
    }
  }
  if (is_ascii) {
    ascii.CheckAtEnd();
  } else {
    binary.CheckAtEnd();
  }
  return mesh;
}

PlyMesh ReadPly(const fs::path& path) { return ParsePly(ReadFile(path, kMaxMeshFileBytes), path); }

}  // namespace hw::core
