#include "core/ply.h"

#include <algorithm>
#include <bit>
#include <cassert>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <string>
#include <system_error>
#include <type_traits>
#include <utility>

#include "core/atomic_file.h"
#include "core/error.h"

namespace hw::core {

namespace fs = std::filesystem;

namespace {

constexpr std::string_view kHeatwaveComment = "written by heatwave";

// ---------------------------------------------------------------------------------------
// Types

struct TypeInfo {
  PlyType type;
  std::string_view name;   // written
  std::string_view alias;  // also accepted on read
  size_t size;
};

constexpr std::array<TypeInfo, 8> kTypes = {{
    {PlyType::kInt8, "char", "int8", 1},
    {PlyType::kUInt8, "uchar", "uint8", 1},
    {PlyType::kInt16, "short", "int16", 2},
    {PlyType::kUInt16, "ushort", "uint16", 2},
    {PlyType::kInt32, "int", "int32", 4},
    {PlyType::kUInt32, "uint", "uint32", 4},
    {PlyType::kFloat32, "float", "float32", 4},
    {PlyType::kFloat64, "double", "float64", 8},
}};

const TypeInfo& Info(PlyType type) {
  const auto index = static_cast<size_t>(type);
  assert(index < kTypes.size());
  return kTypes[index];
}

// Calls f(T{}) with T the C++ type of `type`.
template <typename F>
decltype(auto) Dispatch(PlyType type, F&& f) {
  switch (type) {
    case PlyType::kInt8:
      return f(int8_t{});
    case PlyType::kUInt8:
      return f(uint8_t{});
    case PlyType::kInt16:
      return f(int16_t{});
    case PlyType::kUInt16:
      return f(uint16_t{});
    case PlyType::kInt32:
      return f(int32_t{});
    case PlyType::kUInt32:
      return f(uint32_t{});
    case PlyType::kFloat32:
      return f(float{});
    case PlyType::kFloat64:
      return f(double{});
  }
  assert(false && "bad PlyType");
  return f(double{});
}

// Largest double that still rounds to a finite float (FLT_MAX plus half an ulp is a tie,
// which rounds to even: infinity).
constexpr double kFloatOverflow = 0x1.ffffffp+127;

template <typename T>
T Convert(double value) {
  if constexpr (std::is_same_v<T, double>) {
    return value;
  } else if constexpr (std::is_same_v<T, float>) {
    // Out-of-range double-to-float casts are undefined behaviour: saturate to infinity as
    // IEEE rounding would.
    if (value >= kFloatOverflow) return std::numeric_limits<float>::infinity();
    if (value <= -kFloatOverflow) return -std::numeric_limits<float>::infinity();
    return static_cast<float>(value);
  } else {
    if (std::isnan(value)) return T{0};
    const double rounded = std::round(value);
    // Every limit of an integer type up to 32 bits is exact in double.
    if (rounded <= static_cast<double>(std::numeric_limits<T>::min())) {
      return std::numeric_limits<T>::min();
    }
    if (rounded >= static_cast<double>(std::numeric_limits<T>::max())) {
      return std::numeric_limits<T>::max();
    }
    return static_cast<T>(rounded);
  }
}

// ---------------------------------------------------------------------------------------
// Byte order

template <size_t N>
struct UIntOfSize;
template <>
struct UIntOfSize<2> {
  using Type = uint16_t;
  static Type Swap(Type v) { return __builtin_bswap16(v); }
};
template <>
struct UIntOfSize<4> {
  using Type = uint32_t;
  static Type Swap(Type v) { return __builtin_bswap32(v); }
};
template <>
struct UIntOfSize<8> {
  using Type = uint64_t;
  static Type Swap(Type v) { return __builtin_bswap64(v); }
};

template <typename T, bool kSwap>
inline T Load(const char* p) {
  T value;
  if constexpr (kSwap && sizeof(T) > 1) {
    using U = UIntOfSize<sizeof(T)>;
    typename U::Type bits;
    std::memcpy(&bits, p, sizeof(bits));
    bits = U::Swap(bits);
    std::memcpy(&value, &bits, sizeof(value));
  } else {
    std::memcpy(&value, p, sizeof(value));
  }
  return value;
}

template <typename T, bool kSwap>
inline void Store(T value, char* p) {
  if constexpr (kSwap && sizeof(T) > 1) {
    using U = UIntOfSize<sizeof(T)>;
    typename U::Type bits;
    std::memcpy(&bits, &value, sizeof(bits));
    bits = U::Swap(bits);
    std::memcpy(p, &bits, sizeof(bits));
  } else {
    std::memcpy(p, &value, sizeof(value));
  }
}

// Whether a file in `format` needs its bytes swapped on this machine.
bool NeedsSwap(PlyFormat format) {
  static_assert(std::endian::native == std::endian::little ||
                std::endian::native == std::endian::big);
  const bool file_big = format == PlyFormat::kBinaryBigEndian;
  return file_big != (std::endian::native == std::endian::big);
}

double LoadAsDouble(PlyType type, const char* p, bool swap) {
  return Dispatch(type, [&](auto tag) -> double {
    using T = decltype(tag);
    return static_cast<double>(swap ? Load<T, true>(p) : Load<T, false>(p));
  });
}

// Decodes one column of a table of fixed-size rows.
template <typename T, bool kSwap>
void DecodeColumn(const char* first, size_t stride, size_t n, double* out) {
  for (size_t i = 0; i < n; ++i) out[i] = static_cast<double>(Load<T, kSwap>(first + i * stride));
}

template <typename T, bool kSwap>
void EncodeColumn(const double* in, size_t n, char* first, size_t stride) {
  for (size_t i = 0; i < n; ++i) Store<T, kSwap>(Convert<T>(in[i]), first + i * stride);
}

// ---------------------------------------------------------------------------------------
// Text helpers

// Splits on spaces and tabs.
std::vector<std::string_view> SplitFields(std::string_view line) {
  std::vector<std::string_view> fields;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const size_t begin = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > begin) fields.push_back(line.substr(begin, i - begin));
  }
  return fields;
}

// Keeps messages one short printable line even for binary garbage.
std::string Quoted(std::string_view text) {
  std::string out = "'";
  for (const char c : text.substr(0, 40)) {
    const auto u = static_cast<unsigned char>(c);
    out += (u >= 0x20 && u < 0x7f) ? c : '?';
  }
  if (text.size() > 40) out += "...";
  return out + "'";
}

bool ParseUInt64(std::string_view text, uint64_t* value) {
  if (text.empty() || text.front() < '0' || text.front() > '9') return false;
  const auto result = std::from_chars(text.data(), text.data() + text.size(), *value);
  return result.ec == std::errc() && result.ptr == text.data() + text.size();
}

std::string ToText(double value) {
  std::array<char, 64> buffer{};
  const auto result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  assert(result.ec == std::errc());
  return std::string(buffer.data(), result.ptr);
}

// Parses a PLY ASCII number into what `type` holds. Returns "" or why it is not valid.
// Integer types need an integer in range ("255", also "255.0" or "2.55e2", which some
// writers emit); float parses directly as float (no double rounding); tiny values
// underflow to zero or a denormal, values too large for the type are errors.
std::string ParseAsciiValue(std::string_view token, PlyType type, double* value) {
  std::string_view text = token;
  // from_chars rejects a leading '+', C's strtod (and so other writers) accepts it.
  if (text.size() > 1 && text[0] == '+' && text[1] != '-' && text[1] != '+') text.remove_prefix(1);
  const char* begin = text.data();
  const char* end = text.data() + text.size();
  if (type == PlyType::kFloat32) {
    float f = 0;
    const auto result = std::from_chars(begin, end, f);
    if (result.ec == std::errc() && result.ptr == end) {
      *value = static_cast<double>(f);
      return "";
    }
    if (result.ec == std::errc::result_out_of_range && result.ptr == end) {
      // Underflow (out of range towards zero) is a valid tiny value; overflow is not.
      const double d = std::strtod(std::string(text).c_str(), nullptr);
      if (std::fabs(d) < 1.0) {
        *value = static_cast<double>(static_cast<float>(d));
        return "";
      }
      return Quoted(token) + " is out of range for float";
    }
    return "not a number: " + Quoted(token);
  }
  double d = 0;
  const auto result = std::from_chars(begin, end, d);
  if (result.ec == std::errc::result_out_of_range && result.ptr == end) {
    d = std::strtod(std::string(text).c_str(), nullptr);
    if (std::fabs(d) >= 1.0) {
      return Quoted(token) + " is out of range for " + std::string(PlyTypeName(type));
    }
  } else if (result.ec != std::errc() || result.ptr != end) {
    return "not a number: " + Quoted(token);
  }
  if (PlyTypeIsInteger(type)) {
    if (!std::isfinite(d) || d != std::floor(d)) {
      return "expected an integer (" + std::string(PlyTypeName(type)) + "), got " + Quoted(token);
    }
    if (PlyRepresentable(type, d) != d) {
      return Quoted(token) + " is out of range for " + std::string(PlyTypeName(type));
    }
  }
  *value = d;
  return "";
}

// Appends the shortest text that reads back to `value` converted to `type`.
void AppendAsciiValue(PlyType type, double value, std::string* out) {
  std::array<char, 64> buffer{};
  char* const first = buffer.data();
  char* const last = buffer.data() + buffer.size();
  std::to_chars_result result{};
  switch (type) {
    case PlyType::kFloat32:
      result = std::to_chars(first, last, Convert<float>(value));
      break;
    case PlyType::kFloat64:
      result = std::to_chars(first, last, value);
      break;
    default:
      result = std::to_chars(first, last, static_cast<int64_t>(PlyRepresentable(type, value)));
      break;
  }
  assert(result.ec == std::errc());
  out->append(first, result.ptr);
}

// ---------------------------------------------------------------------------------------
// Header

struct PropertyDesc {
  std::string name;
  PlyType type = PlyType::kFloat32;  // the item type of a list
  bool is_list = false;
  PlyType count_type = PlyType::kUInt8;
};

struct ElementDesc {
  std::string name;
  uint64_t count = 0;
  std::vector<PropertyDesc> properties;
};

struct Header {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<ElementDesc> elements;
  std::vector<std::string> comments;
  size_t data_offset = 0;  // first byte after the end_header line
  size_t num_lines = 0;    // lines up to and including end_header
};

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
  const auto error = [&](size_t line, const std::string& reason) {
    return InputError(path, "line " + std::to_string(line) + ": " + reason);
  };
  if (!data.starts_with("ply\n") && !data.starts_with("ply\r\n")) {
    throw InputError(path, "not a PLY file: the first line is not 'ply'");
  }
  Header header;
  bool have_format = false;
  size_t pos = data.find('\n') + 1;
  size_t line_number = 1;
  while (true) {
    const size_t end = data.find('\n', pos);
    if (end == std::string_view::npos) {
      throw InputError(
          path, "no end_header line (header ends at line " + std::to_string(line_number) + ")");
    }
    std::string_view line = data.substr(pos, end - pos);
    pos = end + 1;
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
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
      element.name = std::string(fields[1]);
      if (!ParseUInt64(fields[2], &element.count)) {
        throw error(line_number, "element " + Quoted(fields[1]) +
                                     ": count is not a non-negative integer: " + Quoted(fields[2]));
      }
      for (const ElementDesc& other : header.elements) {
        if (other.name == element.name) {
          throw error(line_number, "duplicate element " + Quoted(element.name));
        }
      }
      header.elements.push_back(std::move(element));
    } else if (keyword == "property") {
      if (header.elements.empty()) throw error(line_number, "property before any element");
      ElementDesc& element = header.elements.back();
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
        property.name = std::string(fields[4]);
      } else {
        if (fields.size() != 3) {
          throw error(line_number, "expected 'property <type> <name>', got " + Quoted(line));
        }
        const std::optional<PlyType> type = ParsePlyType(fields[1]);
        if (!type) throw error(line_number, "unknown property type " + Quoted(fields[1]));
        property.type = *type;
        property.name = std::string(fields[2]);
      }
      for (const PropertyDesc& other : element.properties) {
        if (other.name == property.name) {
          throw error(line_number, "duplicate property " + Quoted(property.name) + " in element " +
                                       element.name);
        }
      }
      if (element.name == "face" && !property.is_list &&
          (property.name == "vertex_indices" || property.name == "vertex_index")) {
        throw error(line_number, "face property " + property.name + " must be a list");
      }
      if (IsFaceIndexList(element, property) && !PlyTypeIsInteger(property.type)) {
        throw error(line_number, "vertex indices must be of an integer type, got " +
                                     std::string(PlyTypeName(property.type)));
      }
      element.properties.push_back(std::move(property));
    } else if (keyword == "end_header") {
      if (fields.size() != 1) throw error(line_number, "text after end_header");
      if (!have_format) throw error(line_number, "end_header before the format line");
      break;
    } else {
      throw error(line_number, "unknown header keyword " + Quoted(keyword));
    }
  }
  header.data_offset = pos;
  header.num_lines = line_number;

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

// ---------------------------------------------------------------------------------------
// Body

// What reading an element fills in.
struct Sink {
  // Per property of the element: the column its values go to, or null to skip.
  std::vector<double*> columns;
  std::vector<Eigen::Vector3i>* faces = nullptr;  // for face: triangles go here
  int64_t num_vertices = 0;                       // for face: indices must be below
};

// Appends the fan triangulation of polygon `indices`; "" or what is wrong with it.
std::string AddPolygon(const std::vector<int64_t>& indices, int64_t num_vertices,
                       std::vector<Eigen::Vector3i>* faces) {
  if (indices.size() < 3) {
    return std::to_string(indices.size()) + " vertex indices, a face needs at least 3";
  }
  for (const int64_t index : indices) {
    if (index < 0 || index >= num_vertices) {
      return "vertex index " + std::to_string(index) + " out of range (" +
             std::to_string(num_vertices) + " vertices)";
    }
  }
  for (size_t k = 1; k + 1 < indices.size(); ++k) {
    faces->emplace_back(static_cast<int>(indices[0]), static_cast<int>(indices[k]),
                        static_cast<int>(indices[k + 1]));
  }
  return "";
}

std::string BytesOf(uint64_t count, size_t row_bytes) {
  if (row_bytes != 0 && count > std::numeric_limits<uint64_t>::max() / row_bytes) {
    return std::to_string(count) + " x " + std::to_string(row_bytes);
  }
  return std::to_string(count * row_bytes);
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
                                BytesOf(element.count, min_row) + " bytes of " + element.name +
                                " data, got " + std::to_string(remaining));
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
    if (sink.faces != nullptr) sink.faces->reserve(sink.faces->size() + element.count);
    const auto num_vertices = static_cast<uint64_t>(sink.num_vertices);
    std::vector<int64_t> polygon;
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
          throw InputError(path_, element.name + " " + std::to_string(row) + ": list " + p.name +
                                      " has negative length " + ToText(count));
        }
        const auto n = static_cast<uint64_t>(count);
        const size_t item_size = PlyTypeSize(p.type);
        if (n > (data_.size() - pos_) / item_size) {
          throw InputError(path_, "truncated: " + element.name + " " + std::to_string(row) +
                                      ": list " + p.name + " of " + std::to_string(n) +
                                      " items needs " + BytesOf(n, item_size) + " bytes, got " +
                                      std::to_string(data_.size() - pos_));
        }
        const char* items = Take(n * item_size, element, row);
        const IndexLoader load = index_loaders[j];
        if (load == nullptr) continue;
        if (n == 3) {  // the common case, without the polygon buffer
          const int64_t a = load(items);
          const int64_t b = load(items + item_size);
          const int64_t c = load(items + 2 * item_size);
          // Negative indices wrap to huge unsigned values: one comparison each.
          if (static_cast<uint64_t>(a) < num_vertices && static_cast<uint64_t>(b) < num_vertices &&
              static_cast<uint64_t>(c) < num_vertices) {
            sink.faces->emplace_back(static_cast<int>(a), static_cast<int>(b), static_cast<int>(c));
            continue;
          }
        }
        polygon.clear();
        for (uint64_t k = 0; k < n; ++k) polygon.push_back(load(items + k * item_size));
        const std::string problem = AddPolygon(polygon, sink.num_vertices, sink.faces);
        if (!problem.empty()) {
          throw InputError(path_, element.name + " " + std::to_string(row) + ": " + problem);
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
      throw InputError(path_, "truncated: the file ends inside " + element.name + " " +
                                  std::to_string(row) + " of " + std::to_string(element.count));
    }
    const char* p = data_.data() + pos_;
    pos_ += size;
    return p;
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
    throw InputError(path_, "truncated: " + std::to_string(element.count) + " " + element.name +
                                " rows need at least " + BytesOf(element.count, min_values) +
                                " values, but only " + std::to_string(remaining) +
                                " bytes of text follow");
  }

  void ReadElement(const ElementDesc& element, const Sink& sink) {
    CheckFits(element);
    if (MinValues(element) == 0) return;  // rows of no properties are blank lines
    if (sink.faces != nullptr) sink.faces->reserve(sink.faces->size() + element.count);
    std::vector<int64_t> polygon;
    for (uint64_t row = 0; row < element.count; ++row) {
      if (!NextLine()) {
        throw InputError(path_, "truncated: the file ends after " + std::to_string(row) + " of " +
                                    std::to_string(element.count) + " " + element.name + " rows");
      }
      const auto error = [&](const std::string& reason) {
        return InputError(path_, "line " + std::to_string(line_number_) + " (" + element.name +
                                     " " + std::to_string(row) + "): " + reason);
      };
      size_t at = 0;  // position in line_
      const auto next_value = [&](const PropertyDesc& p, PlyType type) {
        std::string_view token;
        if (!NextToken(&at, &token)) {
          throw error("too few values: " + p.name + " missing");
        }
        double value = 0;
        const std::string problem = ParseAsciiValue(token, type, &value);
        if (!problem.empty()) throw error(p.name + ": " + problem);
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
          throw error("list " + p.name + " has negative length " + ToText(count));
        }
        // A list cannot have more items than its line has characters.
        if (count > static_cast<double>(line_.size())) {
          throw error("list " + p.name + " of " + ToText(count) + " items is longer than its line");
        }
        const auto n = static_cast<uint64_t>(count);
        const bool is_face = sink.faces != nullptr && IsFaceIndexList(element, p);
        polygon.clear();
        for (uint64_t k = 0; k < n; ++k) {
          const double item = next_value(p, p.type);
          if (is_face) polygon.push_back(static_cast<int64_t>(item));
        }
        if (is_face) {
          const std::string problem = AddPolygon(polygon, sink.num_vertices, sink.faces);
          if (!problem.empty()) throw error(problem);
        }
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

// ---------------------------------------------------------------------------------------
// Mesh helpers

bool IsValidName(std::string_view name) {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u > 0x20 && u != 0x7f;
  });
}

// Sets the properties `names` to `columns` (replacing or adding them; new ones go to the
// front when `at_front`), asserting the size matches the properties not being set.
void SetColumns(PlyMesh& mesh, const std::vector<std::string_view>& names,
                std::vector<std::vector<double>> columns, PlyType type, bool at_front) {
  assert(names.size() == columns.size() && !names.empty());
  const size_t n = columns[0].size();
  for (const auto& column : columns) assert(column.size() == n);
  for (const PlyProperty& p : mesh.vertex_properties) {
    if (std::find(names.begin(), names.end(), p.name) == names.end()) {
      assert(p.values.size() == n && "property size differs from the mesh's vertex count");
    }
  }
  size_t insert_at = 0;
  for (size_t k = 0; k < names.size(); ++k) {
    assert(IsValidName(names[k]));
    if (PlyProperty* existing = mesh.Find(names[k])) {
      existing->type = type;
      existing->values = std::move(columns[k]);
      continue;
    }
    PlyProperty property{std::string(names[k]), type, std::move(columns[k])};
    if (at_front) {
      mesh.vertex_properties.insert(mesh.vertex_properties.begin() + insert_at++,
                                    std::move(property));
    } else {
      mesh.vertex_properties.push_back(std::move(property));
    }
  }
}

std::vector<Eigen::Vector3d> GetTriple(const PlyMesh& mesh, std::string_view a, std::string_view b,
                                       std::string_view c) {
  const std::vector<double>& xs = mesh.Get(a).values;
  const std::vector<double>& ys = mesh.Get(b).values;
  const std::vector<double>& zs = mesh.Get(c).values;
  assert(xs.size() == ys.size() && xs.size() == zs.size());
  std::vector<Eigen::Vector3d> out(xs.size());
  for (size_t i = 0; i < xs.size(); ++i) out[i] = Eigen::Vector3d(xs[i], ys[i], zs[i]);
  return out;
}

void SetTriple(PlyMesh& mesh, std::string_view a, std::string_view b, std::string_view c,
               const std::vector<Eigen::Vector3d>& data, PlyType type, bool at_front) {
  std::vector<std::vector<double>> columns(3, std::vector<double>(data.size()));
  for (size_t i = 0; i < data.size(); ++i) {
    for (int k = 0; k < 3; ++k) columns[k][i] = data[i][k];
  }
  SetColumns(mesh, {a, b, c}, std::move(columns), type, at_front);
}

uint8_t ColorByte(const PlyProperty& property, size_t i) {
  double v = property.values[i];
  if (!PlyTypeIsInteger(property.type)) v *= 255.0;
  if (std::isnan(v)) return 0;
  return static_cast<uint8_t>(std::clamp(std::round(v), 0.0, 255.0));
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Public: types

std::string_view PlyTypeName(PlyType type) { return Info(type).name; }

std::optional<PlyType> ParsePlyType(std::string_view name) {
  for (const TypeInfo& info : kTypes) {
    if (name == info.name || name == info.alias) return info.type;
  }
  return std::nullopt;
}

size_t PlyTypeSize(PlyType type) { return Info(type).size; }

bool PlyTypeIsInteger(PlyType type) {
  return type != PlyType::kFloat32 && type != PlyType::kFloat64;
}

double PlyRepresentable(PlyType type, double value) {
  return Dispatch(
      type, [&](auto tag) -> double { return static_cast<double>(Convert<decltype(tag)>(value)); });
}

// ---------------------------------------------------------------------------------------
// Public: PlyMesh

size_t PlyMesh::NumVertices() const {
  return vertex_properties.empty() ? 0 : vertex_properties.front().values.size();
}

const PlyProperty* PlyMesh::Find(std::string_view name) const {
  for (const PlyProperty& p : vertex_properties) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

PlyProperty* PlyMesh::Find(std::string_view name) {
  for (PlyProperty& p : vertex_properties) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

const PlyProperty& PlyMesh::Get(std::string_view name) const {
  const PlyProperty* p = Find(name);
  if (p == nullptr) {
    std::fprintf(stderr, "PlyMesh::Get: no property '%.*s'\n", static_cast<int>(name.size()),
                 name.data());
  }
  assert(p != nullptr);
  return *p;
}

PlyProperty& PlyMesh::Get(std::string_view name) {
  return const_cast<PlyProperty&>(std::as_const(*this).Get(name));
}

void PlyMesh::AddProperty(std::string name, PlyType type, std::vector<double> values) {
  assert(IsValidName(name));
  assert(Find(name) == nullptr && "AddProperty: name already used");
  assert((vertex_properties.empty() || values.size() == NumVertices()) &&
         "AddProperty: size differs from the mesh's vertex count");
  vertex_properties.push_back(PlyProperty{std::move(name), type, std::move(values)});
}

void PlyMesh::SetProperty(std::string name, PlyType type, std::vector<double> values) {
  std::vector<std::vector<double>> columns;
  columns.push_back(std::move(values));
  SetColumns(*this, {name}, std::move(columns), type, /*at_front=*/false);
}

bool PlyMesh::RemoveProperty(std::string_view name) {
  const auto it = std::find_if(vertex_properties.begin(), vertex_properties.end(),
                               [&](const PlyProperty& p) { return p.name == name; });
  if (it == vertex_properties.end()) return false;
  vertex_properties.erase(it);
  return true;
}

bool PlyMesh::HasPositions() const { return Find("x") && Find("y") && Find("z"); }

std::vector<Eigen::Vector3d> PlyMesh::Positions() const { return GetTriple(*this, "x", "y", "z"); }

void PlyMesh::SetPositions(const std::vector<Eigen::Vector3d>& positions, PlyType type) {
  SetTriple(*this, "x", "y", "z", positions, type, /*at_front=*/true);
}

bool PlyMesh::HasNormals() const { return Find("nx") && Find("ny") && Find("nz"); }

std::vector<Eigen::Vector3d> PlyMesh::Normals() const { return GetTriple(*this, "nx", "ny", "nz"); }

void PlyMesh::SetNormals(const std::vector<Eigen::Vector3d>& normals, PlyType type) {
  SetTriple(*this, "nx", "ny", "nz", normals, type, /*at_front=*/false);
}

bool PlyMesh::HasColors() const { return Find("red") && Find("green") && Find("blue"); }

std::vector<Rgb8> PlyMesh::Colors() const {
  const PlyProperty& r = Get("red");
  const PlyProperty& g = Get("green");
  const PlyProperty& b = Get("blue");
  std::vector<Rgb8> out(r.values.size());
  for (size_t i = 0; i < out.size(); ++i) {
    out[i] = Rgb8(ColorByte(r, i), ColorByte(g, i), ColorByte(b, i));
  }
  return out;
}

std::vector<Rgba8> PlyMesh::ColorsWithAlpha() const {
  const std::vector<Rgb8> rgb = Colors();
  const PlyProperty* a = Find("alpha");
  std::vector<Rgba8> out(rgb.size());
  for (size_t i = 0; i < out.size(); ++i) {
    out[i] = Rgba8(rgb[i][0], rgb[i][1], rgb[i][2], a ? ColorByte(*a, i) : uint8_t{255});
  }
  return out;
}

void PlyMesh::SetColors(const std::vector<Rgb8>& colors) {
  RemoveProperty("alpha");
  std::vector<std::vector<double>> columns(3, std::vector<double>(colors.size()));
  for (size_t i = 0; i < colors.size(); ++i) {
    for (int k = 0; k < 3; ++k) columns[k][i] = colors[i][k];
  }
  SetColumns(*this, {"red", "green", "blue"}, std::move(columns), PlyType::kUInt8, false);
}

void PlyMesh::SetColorsWithAlpha(const std::vector<Rgba8>& colors) {
  std::vector<std::vector<double>> columns(4, std::vector<double>(colors.size()));
  for (size_t i = 0; i < colors.size(); ++i) {
    for (int k = 0; k < 4; ++k) columns[k][i] = colors[i][k];
  }
  SetColumns(*this, {"red", "green", "blue", "alpha"}, std::move(columns), PlyType::kUInt8, false);
}

std::string PlyMesh::Check() const {
  const size_t n = NumVertices();
  for (size_t j = 0; j < vertex_properties.size(); ++j) {
    const PlyProperty& p = vertex_properties[j];
    if (!IsValidName(p.name)) return "property " + Quoted(p.name) + ": invalid PLY name";
    if (static_cast<size_t>(p.type) >= kTypes.size()) return "property " + p.name + ": bad type";
    if (p.values.size() != n) {
      return "property " + p.name + " has " + std::to_string(p.values.size()) +
             " values, property " + vertex_properties[0].name + " has " + std::to_string(n);
    }
    for (size_t k = 0; k < j; ++k) {
      if (vertex_properties[k].name == p.name) return "duplicate property " + p.name;
    }
  }
  if (n > static_cast<size_t>(INT_MAX)) return std::to_string(n) + " vertices, more than INT_MAX";
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      if (faces[f][k] < 0 || static_cast<size_t>(faces[f][k]) >= n) {
        return "face " + std::to_string(f) + ": vertex index " + std::to_string(faces[f][k]) +
               " out of range (" + std::to_string(n) + " vertices)";
      }
    }
  }
  for (const std::string& comment : comments) {
    if (comment.find_first_of("\r\n") != std::string::npos) {
      return "comment " + Quoted(comment) + " contains a line break";
    }
  }
  return "";
}

// ---------------------------------------------------------------------------------------
// Public: reading

PlyMesh ParsePly(std::string_view data, const fs::path& path_for_errors) {
  const fs::path& path = path_for_errors;
  const Header header = ParseHeader(data, path);
  PlyMesh mesh;
  mesh.comments = header.comments;

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
      // Columns are sized only once the reader has checked the count against the data.
      std::vector<size_t> property_of_column;
      for (size_t j = 0; j < element.properties.size(); ++j) {
        if (element.properties[j].is_list) continue;
        mesh.vertex_properties.push_back(
            PlyProperty{element.properties[j].name, element.properties[j].type, {}});
        property_of_column.push_back(j);
      }
      // A count the data cannot hold throws here, before the allocation: every value
      // stored takes at least one byte of the file, so memory stays within a few times
      // the file size whatever the header says.
      if (is_ascii) {
        ascii.CheckFits(element);
      } else {
        binary.CheckFits(element);
      }
      for (size_t c = 0; c < property_of_column.size(); ++c) {
        mesh.vertex_properties[c].values.resize(element.count);
        sink.columns[property_of_column[c]] = mesh.vertex_properties[c].values.data();
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

PlyMesh ReadPly(const fs::path& path) { return ParsePly(ReadFile(path), path); }

// ---------------------------------------------------------------------------------------
// Public: writing

std::string SerializePly(const PlyMesh& mesh, PlyFormat format) {
  const std::string problem = mesh.Check();
  if (!problem.empty()) std::fprintf(stderr, "SerializePly: invalid mesh: %s\n", problem.c_str());
  assert(problem.empty() && "SerializePly: invalid mesh (see PlyMesh::Check)");

  const size_t n = mesh.NumVertices();
  const size_t num_faces = mesh.faces.size();
  std::string header =
      "ply\nformat " + FormatName(format) + " 1.0\ncomment " + std::string(kHeatwaveComment) + "\n";
  for (const std::string& comment : mesh.comments) {
    if (comment != kHeatwaveComment) header += "comment " + comment + "\n";
  }
  header += "element vertex " + std::to_string(n) + "\n";
  for (const PlyProperty& p : mesh.vertex_properties) {
    header += "property " + std::string(PlyTypeName(p.type)) + " " + p.name + "\n";
  }
  header += "element face " + std::to_string(num_faces) + "\n";
  header += "property list uchar int vertex_indices\nend_header\n";

  if (format == PlyFormat::kAscii) {
    std::string out = std::move(header);
    out.reserve(out.size() + n * mesh.vertex_properties.size() * 12 + num_faces * 24);
    for (size_t i = 0; i < n; ++i) {
      for (size_t j = 0; j < mesh.vertex_properties.size(); ++j) {
        if (j > 0) out += ' ';
        AppendAsciiValue(mesh.vertex_properties[j].type, mesh.vertex_properties[j].values[i], &out);
      }
      out += '\n';
    }
    for (const Eigen::Vector3i& face : mesh.faces) {
      out += '3';
      for (int k = 0; k < 3; ++k) {
        out += ' ';
        AppendAsciiValue(PlyType::kInt32, face[k], &out);
      }
      out += '\n';
    }
    return out;
  }

  const bool swap = NeedsSwap(format);
  size_t stride = 0;
  for (const PlyProperty& p : mesh.vertex_properties) stride += PlyTypeSize(p.type);
  constexpr size_t kFaceBytes = 1 + 3 * sizeof(int32_t);
  std::string out(header.size() + n * stride + num_faces * kFaceBytes, '\0');
  std::memcpy(out.data(), header.data(), header.size());
  char* const vertex_data = out.data() + header.size();
  size_t offset = 0;
  for (const PlyProperty& p : mesh.vertex_properties) {
    Dispatch(p.type, [&](auto tag) {
      using T = decltype(tag);
      if (swap) {
        EncodeColumn<T, true>(p.values.data(), n, vertex_data + offset, stride);
      } else {
        EncodeColumn<T, false>(p.values.data(), n, vertex_data + offset, stride);
      }
    });
    offset += PlyTypeSize(p.type);
  }
  char* face_data = vertex_data + n * stride;
  for (const Eigen::Vector3i& face : mesh.faces) {
    *face_data++ = 3;
    for (int k = 0; k < 3; ++k) {
      if (swap) {
        Store<int32_t, true>(face[k], face_data);
      } else {
        Store<int32_t, false>(face[k], face_data);
      }
      face_data += sizeof(int32_t);
    }
  }
  assert(face_data == out.data() + out.size());
  return out;
}

void WritePly(const fs::path& path, const PlyMesh& mesh, PlyFormat format) {
  WriteFileAtomically(path, SerializePly(mesh, format));
}

}  // namespace hw::core
