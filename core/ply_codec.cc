// PLY scalar types and number text (core/ply_codec.h), and the public type functions of
// core/ply.h.

#include "core/ply_codec.h"

#include <charconv>
#include <cstdlib>
#include <system_error>

#include "core/ply.h"

namespace hw::core {
namespace ply_internal {

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

bool IsValidName(std::string_view name) {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u > 0x20 && u != 0x7f;
  });
}

}  // namespace ply_internal

using ply_internal::Convert;
using ply_internal::Dispatch;
using ply_internal::Info;
using ply_internal::kTypes;
using ply_internal::TypeInfo;

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

}  // namespace hw::core
