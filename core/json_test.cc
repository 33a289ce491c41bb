#include "core/json.h"

#include <cstdint>
#include <limits>
#include <string>

#include <gtest/gtest.h>

namespace hw::core {
namespace {

using namespace std::string_literals;

const std::string kReplacement = "\xEF\xBF\xBD";  // U+FFFD in UTF-8

// The UTF-8 encoding of any code point up to 0x10FFFF, surrogates included (to build the
// invalid forms too).
std::string Encode(uint32_t cp) {
  std::string s;
  if (cp < 0x80) {
    s += static_cast<char>(cp);
  } else if (cp < 0x800) {
    s += static_cast<char>(0xC0 | (cp >> 6));
    s += static_cast<char>(0x80 | (cp & 0x3F));
  } else if (cp < 0x10000) {
    s += static_cast<char>(0xE0 | (cp >> 12));
    s += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    s += static_cast<char>(0x80 | (cp & 0x3F));
  } else {
    s += static_cast<char>(0xF0 | (cp >> 18));
    s += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
    s += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    s += static_cast<char>(0x80 | (cp & 0x3F));
  }
  return s;
}

size_t Count(const std::string& s, const std::string& part) {
  size_t n = 0;
  for (size_t i = s.find(part); i != std::string::npos; i = s.find(part, i + part.size())) ++n;
  return n;
}

TEST(JsonString, QuotesAndEscapes) {
  EXPECT_EQ(JsonString(""), "\"\"");
  EXPECT_EQ(JsonString("scan/rig.yaml"), "\"scan/rig.yaml\"");
  EXPECT_EQ(JsonString("a\"b\\c"), "\"a\\\"b\\\\c\"");
  EXPECT_EQ(JsonString("a\nb\tc\x01\x1f\x7f"), "\"a\\u000ab\\u0009c\\u0001\\u001f\\u007f\"");
  EXPECT_EQ(JsonString("nul\0here"s), "\"nul\\u0000here\"");
}

TEST(JsonString, ValidUtf8PassesThrough) {
  EXPECT_EQ(JsonString("35 °C, 7.5–14 µm, 𝄞"), "\"35 °C, 7.5–14 µm, 𝄞\"");
  // Every scalar value from U+0080 to U+10FFFF (surrogates are not scalar values).
  for (uint32_t cp = 0x80; cp <= 0x10FFFF; ++cp) {
    if (cp >= 0xD800 && cp <= 0xDFFF) continue;
    const std::string s = Encode(cp);
    ASSERT_EQ(JsonString(s), "\"" + s + "\"") << std::hex << cp;
  }
}

TEST(JsonString, EachInvalidByteBecomesReplacementCharacter) {
  const auto replaced = [](int bytes, const std::string& tail = "") {
    std::string out = "\"";
    for (int i = 0; i < bytes; ++i) out += kReplacement;
    return out + tail + "\"";
  };
  EXPECT_EQ(JsonString("\xff\xfe"), replaced(2));
  EXPECT_EQ(JsonString("\x80"), replaced(1));                      // stray continuation byte
  EXPECT_EQ(JsonString("\xC0\xAF"), replaced(2));                  // overlong '/'
  EXPECT_EQ(JsonString("\xC1\xBF"), replaced(2));                  // overlong
  EXPECT_EQ(JsonString("\xE0\x80\xAF"), replaced(3));              // overlong, 3 bytes
  EXPECT_EQ(JsonString("\xF0\x80\x80\xAF"), replaced(4));          // overlong, 4 bytes
  EXPECT_EQ(JsonString("\xF4\x90\x80\x80"), replaced(4));          // U+110000
  EXPECT_EQ(JsonString("\xF5\x80\x80\x80"), replaced(4));          // past U+10FFFF
  EXPECT_EQ(JsonString("\xE2\x82"), replaced(2));                  // truncated at the end
  EXPECT_EQ(JsonString("\xE2\x82" "A"), replaced(2, "A"));         // truncated mid-string
  EXPECT_EQ(JsonString("\xF0\x9D\x84" "\n"), replaced(3, "\\u000a"));
  EXPECT_EQ(JsonString("a\xff" "b\xc3\xa9"), "\"a" + kReplacement + "b\xc3\xa9\"");
  // UTF-16 surrogates encoded in UTF-8 (CESU-8, WTF-8) are not UTF-8.
  for (uint32_t cp = 0xD800; cp <= 0xDFFF; ++cp) {
    ASSERT_EQ(JsonString(Encode(cp)), replaced(3)) << std::hex << cp;
  }
}

TEST(JsonString, OutputIsAlwaysStrictJson) {
  // Every 1- and 2-byte string: the output is quotes around valid UTF-8 with no raw
  // control character.
  for (int a = 0; a < 256; ++a) {
    for (int b = -1; b < 256; ++b) {
      std::string s(1, static_cast<char>(a));
      if (b >= 0) s += static_cast<char>(b);
      const std::string out = JsonString(s);
      ASSERT_GE(out.size(), 2u);
      ASSERT_EQ(out.front(), '"');
      ASSERT_EQ(out.back(), '"');
      for (const char c : out) {
        const auto u = static_cast<unsigned char>(c);
        ASSERT_TRUE(u >= 0x20 && u != 0x7f) << a << " " << b;
      }
      // Valid UTF-8 all through: escaping the output again replaces nothing more.
      const std::string inner = out.substr(1, out.size() - 2);
      ASSERT_EQ(Count(JsonString(inner), kReplacement), Count(inner, kReplacement)) << a << " " << b;
    }
  }
}

TEST(JsonNumber, ShortestRoundTripAndNullForNonFinite) {
  EXPECT_EQ(JsonNumber(0.1), "0.1");
  EXPECT_EQ(JsonNumber(-2), "-2");
  EXPECT_EQ(std::stod(JsonNumber(1.0 / 3)), 1.0 / 3);
  EXPECT_EQ(JsonNumber(std::numeric_limits<double>::quiet_NaN()), "null");
  EXPECT_EQ(JsonNumber(-std::numeric_limits<double>::infinity()), "null");
}

TEST(JsonObject, KeysEscapedInInsertionOrder) {
  JsonObject o;
  o.Int("n", 3).Bool("ok", true).String("p\"ath", "a\nb").Number("x", 0.5);
  EXPECT_EQ(o.str(), R"({"n": 3, "ok": true, "p\"ath": "a\u000ab", "x": 0.5})");
  EXPECT_EQ(JsonArray({}), "[]");
  EXPECT_EQ(JsonArray({"1", "2"}), "[\n  1,\n  2\n]");
}

}  // namespace
}  // namespace hw::core
