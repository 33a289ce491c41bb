#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace hw::core {

// `s` as a JSON string literal, quotes included, that a strict RFC 8259 parser accepts.
// Every string a command puts into JSON goes through here, because much of it is paths and
// Linux paths are bytes, not text:
// - valid UTF-8 passes through unchanged (°C, µm, any language);
// - '"' and '\' are backslash-escaped; control characters (U+0000-U+001F, and DEL) become
//   \u00XX;
// - every byte that is not part of a valid UTF-8 sequence (a stray continuation byte, an
//   overlong form, an encoded surrogate, a code point past U+10FFFF, a truncated sequence)
//   becomes U+FFFD, one per byte. The name is then not byte-exact, but the report parses;
//   the text reports print paths as they are.
std::string JsonString(std::string_view s);

// The shortest text that reads back as the same double; "null" for NaN and inf (JSON has
// neither).
std::string JsonNumber(double value);

// "key": value pairs joined into one object, in insertion order. Keys go through JsonString.
class JsonObject {
 public:
  JsonObject& Add(const std::string& key, const std::string& raw_value) {
    body_ += (body_.empty() ? "" : ", ") + JsonString(key) + ": " + raw_value;
    return *this;
  }
  JsonObject& Number(const std::string& key, double value) { return Add(key, JsonNumber(value)); }
  JsonObject& Int(const std::string& key, int64_t value) { return Add(key, std::to_string(value)); }
  JsonObject& Bool(const std::string& key, bool value) { return Add(key, value ? "true" : "false"); }
  JsonObject& String(const std::string& key, const std::string& value) {
    return Add(key, JsonString(value));
  }
  std::string str() const { return "{" + body_ + "}"; }

 private:
  std::string body_;
};

// Raw JSON values as an array, one per line indented by `indent` + 2 spaces ("[]" when empty).
std::string JsonArray(const std::vector<std::string>& items, const std::string& indent = "");

}  // namespace hw::core
