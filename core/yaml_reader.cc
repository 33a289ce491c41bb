#include "core/yaml_reader.h"

#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/parser.h>

#include <array>
#include <cassert>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <system_error>
#include <utility>

#include "core/error.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;

std::string LineSuffix(const YAML::Mark& mark) {
  if (mark.is_null() || mark.line < 0) return "";
  return " (line " + std::to_string(mark.line + 1) + ")";
}

std::string Join(const std::string& prefix, const std::string& key) {
  return prefix.empty() ? key : prefix + "." + key;
}

// YAML's spellings of infinity and not-a-number (.inf, -.Inf, .NaN, ...) and C's (inf, nan).
bool IsNonFiniteWord(std::string_view text) {
  if (!text.empty() && (text[0] == '+' || text[0] == '-')) text.remove_prefix(1);
  if (!text.empty() && text[0] == '.') text.remove_prefix(1);
  std::string lower;
  for (const char c : text) lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return lower == "inf" || lower == "infinity" || lower == "nan";
}

// from_chars takes "-3" but not "+3", which YAML allows.
std::string_view WithoutPlusSign(std::string_view text) {
  if (text.size() >= 2 && text[0] == '+' && text[1] != '-' && text[1] != '+') {
    text.remove_prefix(1);
  }
  return text;
}

std::string ShortestText(double value) {
  std::array<char, 64> buffer{};
  const auto [end, ec] = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  assert(ec == std::errc());
  (void)ec;
  return std::string(buffer.data(), end);
}

// Records where each document starts and refuses nesting deeper than kMaxYamlNesting while
// the parser walks the text; ignores everything else.
class DocumentWalker : public YAML::EventHandler {
 public:
  explicit DocumentWalker(const fs::path& path) : path_(path) {}
  std::vector<YAML::Mark> marks;

  void OnDocumentStart(const YAML::Mark& mark) override { marks.push_back(mark); }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                const std::string&) override {}
  void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {
    Enter(mark);
  }
  void OnSequenceEnd() override { --depth_; }
  void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {
    Enter(mark);
  }
  void OnMapEnd() override { --depth_; }

 private:
  void Enter(const YAML::Mark& mark) {
    // Thrown from inside the parser, which unwinds cleanly (it throws itself).
    if (++depth_ > kMaxYamlNesting) {
      ThrowInputError(path_, "line " + std::to_string(mark.line + 1) +
                                 ": YAML nesting deeper than " + std::to_string(kMaxYamlNesting) +
                                 " levels of mappings and lists");
    }
  }

  const fs::path& path_;
  int depth_ = 0;
};

// The mark of the node at `key_path` ("cameras.depth.fx", "distortion[4]") below `node`, or
// of the deepest node on the way that the file has. Read-only walk: yaml-cpp's Node
// assignment would rebind the tree, so no Node is ever assigned here.
YAML::Mark MarkAt(const YAML::Node& node, std::string_view key_path) {
  if (key_path.empty()) return node.Mark();
  if (key_path[0] == '[') {
    const size_t close = key_path.find(']');
    if (close == std::string_view::npos || !node.IsSequence()) return node.Mark();
    size_t index = 0;
    const auto [end, ec] = std::from_chars(key_path.data() + 1, key_path.data() + close, index);
    if (ec != std::errc() || end != key_path.data() + close) return node.Mark();
    std::string_view rest = key_path.substr(close + 1);
    if (!rest.empty() && rest[0] == '.') rest.remove_prefix(1);
    size_t i = 0;
    for (const YAML::Node& element : node) {
      if (i++ == index) return MarkAt(element, rest);
    }
    return node.Mark();
  }
  const size_t stop = key_path.find_first_of(".[");
  const std::string_view name = key_path.substr(0, stop);
  std::string_view rest = stop == std::string_view::npos ? "" : key_path.substr(stop);
  if (!rest.empty() && rest[0] == '.') rest.remove_prefix(1);
  if (node.IsMap()) {
    for (const auto& item : node) {
      if (item.first.IsScalar() && item.first.Scalar() == name) return MarkAt(item.second, rest);
    }
  }
  return node.Mark();
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Text.

std::string PrepareConfigText(std::string_view text, const fs::path& path_for_errors) {
  // FF FE is also how a UTF-32LE mark starts.
  if (text.substr(0, 2) == "\xFF\xFE" || text.substr(0, 2) == "\xFE\xFF") {
    ThrowInputError(path_for_errors,
                    "starts with a UTF-16 or UTF-32 byte order mark: save the file as UTF-8");
  }
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
  std::string out;
  out.reserve(text.size());
  int line = 1;
  int column = 1;  // of the next character; UTF-8 continuation bytes do not start one
  for (size_t i = 0; i < text.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c == '\r' || c == '\n') {
      if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
      out += '\n';
      ++line;
      column = 1;
      continue;
    }
    if ((c < 0x20 && c != '\t') || c == 0x7f) {
      std::array<char, 48> what{};
      if (c == 0) {
        std::snprintf(what.data(), what.size(), "NUL byte");
      } else {
        std::snprintf(what.data(), what.size(), "control character 0x%02X", c);
      }
      ThrowInputError(path_for_errors, std::string(what.data()) + " at line " +
                                           std::to_string(line) + ", column " +
                                           std::to_string(column));
    }
    out += static_cast<char>(c);
    if ((c & 0xC0) != 0x80) ++column;
  }
  return out;
}

// ---------------------------------------------------------------------------------------
// Messages.

std::string OneLine(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char ch : text) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c == '\n') {
      out += "\\n";
    } else if (c == '\r') {
      out += "\\r";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c < 0x20 || c == 0x7f) {
      std::array<char, 8> escaped{};
      std::snprintf(escaped.data(), escaped.size(), "\\x%02X", c);
      out += escaped.data();
    } else {
      out += ch;
    }
  }
  return out;
}

std::string Printable(std::string_view text) {
  constexpr size_t kMaxLength = 40;
  const std::string out = OneLine(text.substr(0, kMaxLength));
  return text.size() > kMaxLength ? out + "..." : out;
}

void ThrowInputError(const fs::path& path, const std::string& reason) {
  throw InputError(path, OneLine(reason));
}

std::string MessageNumber(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  std::string text = ShortestText(value);
  // "1e+300" -> "1e300", "1e-06" -> "1e-6": still valid numbers, easier to read.
  const size_t e = text.find('e');
  if (e != std::string::npos) {
    std::string exponent = text.substr(e + 1);
    const bool negative = !exponent.empty() && exponent[0] == '-';
    if (!exponent.empty() && (exponent[0] == '+' || exponent[0] == '-')) exponent.erase(0, 1);
    while (exponent.size() > 1 && exponent[0] == '0') exponent.erase(0, 1);
    text = text.substr(0, e + 1) + (negative ? "-" : "") + exponent;
  }
  return text;
}

std::string RoundedNumber(double value) {
  std::array<char, 32> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "%.10g", value);
  return buffer.data();
}

std::string RangeProblem(const std::string& key, double value, double lo, double hi,
                         const std::string& unit) {
  if (!std::isfinite(value)) return key + ": must be finite, got " + MessageNumber(value);
  if (value >= lo && value <= hi) return "";
  return key + ": must be in [" + MessageNumber(lo) + ", " + MessageNumber(hi) + "]" +
         (unit.empty() ? "" : " " + unit) + ", got " + MessageNumber(value);
}

std::string FormatYamlDouble(double value) {
  if (std::isnan(value)) return ".nan";
  if (std::isinf(value)) return value > 0 ? ".inf" : "-.inf";
  std::string text = ShortestText(value);
  const size_t exponent = text.find('e');
  if (text.find('.') == std::string::npos) {
    text.insert(exponent == std::string::npos ? text.size() : exponent, ".0");
  }
  return text;
}

std::string FormatYamlList(const double* values, size_t count) {
  std::string text = "[";
  for (size_t i = 0; i < count; ++i) text += (i > 0 ? ", " : "") + FormatYamlDouble(values[i]);
  return text + "]";
}

std::string Describe(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Null:
      return "nothing";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Map:
      return "a mapping";
    case YAML::NodeType::Scalar:
      // Plain scalars are YAML's numbers and names; quoted ones are strings.
      if (node.Tag() == "?") return "'" + Printable(node.Scalar()) + "'";
      return "string \"" + Printable(node.Scalar()) + "\"";
    case YAML::NodeType::Undefined:
      break;
  }
  return "nothing";
}

// ---------------------------------------------------------------------------------------
// YamlReader

void YamlReader::Fail(const std::string& key, const std::string& problem,
                      const YAML::Node& node) const {
  Fail(key, problem, node.Mark());
}

void YamlReader::Fail(const std::string& key, const std::string& problem,
                      const YAML::Mark& mark) const {
  ThrowInputError(path_, key + ": " + problem + LineSuffix(mark));
}

YAML::Node YamlReader::LoadMapping(const std::string& raw_text) const {
  const std::string text = PrepareConfigText(raw_text, path_);
  YAML::Node root;
  try {
    // Not YAML::LoadAll: yaml-cpp 0.7 loops forever, allocating until bad_alloc, on a
    // document it cannot get past (one starting with ',': yaml-cpp issue #1040, fixed
    // upstream in 2024 by PR #1319). Walk at most three documents with the event parser
    // instead, catching the parser when it makes no progress, then load the first.
    std::istringstream stream(text);
    YAML::Parser parser(stream);
    DocumentWalker walker(path_);
    for (int i = 0; i < 3 && parser.HandleNextDocument(walker); ++i) {
    }
    const std::vector<YAML::Mark>& marks = walker.marks;
    for (size_t i = 1; i < marks.size(); ++i) {
      if (marks[i].pos != marks[i - 1].pos) continue;
      const size_t pos = static_cast<size_t>(marks[i].pos);
      const unsigned char c = pos < text.size() ? static_cast<unsigned char>(text[pos]) : ' ';
      const std::string what =
          std::isgraph(c) ? std::string("'") + static_cast<char>(c) + "'" : "character";
      ThrowInputError(path_, "line " + std::to_string(marks[i].line + 1) +
                                 ": YAML syntax error: unexpected " + what);
    }
    if (marks.size() > 1) {
      ThrowInputError(path_, "more than one YAML document (the second starts on line " +
                                 std::to_string(marks[1].line + 1) + ")");
    }
    root = YAML::Load(text);
  } catch (const YAML::DeepRecursion& e) {
    // The walker stops far earlier; kept in case a yaml-cpp build limits nesting lower
    // (0.7 throws this at 500 nested nodes, scalars included, as "bad file").
    ThrowInputError(path_, "line " + std::to_string(e.mark.line + 1) +
                               ": YAML nesting deeper than the parser's limit of " +
                               std::to_string(e.depth()) + " nested nodes");
  } catch (const YAML::Exception& e) {
    const std::string line =
        e.mark.is_null() ? "" : "line " + std::to_string(e.mark.line + 1) + ": ";
    ThrowInputError(path_, line + "YAML syntax error: " + e.msg);
  }
  if (root.IsNull()) ThrowInputError(path_, "empty file");
  if (!root.IsMap()) {
    ThrowInputError(path_, "expected a mapping of keys at the top level, got " + Describe(root) +
                               LineSuffix(root.Mark()));
  }
  return root;
}

void YamlReader::FailCheck(const YAML::Node& node, const std::string& prefix,
                           const std::string& message) const {
  const size_t colon = message.find(": ");
  const std::string what = message.substr(0, colon);
  const std::string problem = colon == std::string::npos ? "" : message.substr(colon + 2);
  Fail(Join(prefix, what), problem, MarkAt(node, what));
}

std::string YamlReader::Fields::Path(const std::string& name) const { return Join(key_, name); }

const YAML::Node& YamlReader::Fields::Required(const std::string& name) const {
  const auto it = values_.find(name);
  if (it == values_.end()) reader_.Fail(Path(name), "missing required key", node_);
  return it->second;
}

const YAML::Node& YamlReader::Fields::NodeFor(const std::string& name) const {
  const auto it = values_.find(name);
  return it == values_.end() ? node_ : it->second;
}

YamlReader::Fields YamlReader::Mapping(const YAML::Node& node, const std::string& key,
                                       const std::set<std::string>& allowed) const {
  const std::string where = key.empty() ? "top level" : key;
  if (!node.IsMap()) Fail(where, "must be a mapping of keys, got " + Describe(node), node);
  Fields fields(*this, key, node);
  for (const auto& item : node) {
    if (!item.first.IsScalar()) {
      Fail(where, "keys must be plain names, got " + Describe(item.first), item.first);
    }
    const std::string& name = item.first.Scalar();
    if (allowed.count(name) == 0) {
      Fail(where, "unknown key '" + Printable(name) + "'", item.first);
    }
    if (!fields.values_.emplace(name, item.second).second) {
      Fail(where, "duplicate key '" + Printable(name) + "'", item.first);
    }
  }
  return fields;
}

double YamlReader::Number(const YAML::Node& node, const std::string& key) const {
  // Only plain scalars are numbers: "525" in quotes is a string.
  if (!node.IsScalar() || node.Tag() != "?") {
    Fail(key, "must be a number, got " + Describe(node), node);
  }
  const std::string_view text = WithoutPlusSign(node.Scalar());
  double value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec == std::errc::result_out_of_range) {
    Fail(key, "number out of range, got " + Describe(node), node);
  }
  if (IsNonFiniteWord(text) || (ec == std::errc() && !std::isfinite(value))) {
    Fail(key, "must be finite, got " + Describe(node), node);
  }
  if (ec != std::errc() || end != text.data() + text.size() || text.empty()) {
    Fail(key, "must be a number, got " + Describe(node), node);
  }
  return value;
}

int YamlReader::Integer(const YAML::Node& node, const std::string& key) const {
  if (!node.IsScalar() || node.Tag() != "?") {
    Fail(key, "must be an integer, got " + Describe(node), node);
  }
  const std::string_view text = WithoutPlusSign(node.Scalar());
  int value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec == std::errc::result_out_of_range) {
    Fail(key, "integer out of range, got " + Describe(node), node);
  }
  if (ec != std::errc() || end != text.data() + text.size() || text.empty()) {
    Fail(key, "must be an integer, got " + Describe(node), node);
  }
  return value;
}

std::string YamlReader::String(const YAML::Node& node, const std::string& key) const {
  if (!node.IsScalar()) Fail(key, "must be a name, got " + Describe(node), node);
  return node.Scalar();
}

std::vector<double> YamlReader::NumberList(const YAML::Node& node, const std::string& key,
                                           int size) const {
  const std::string expected =
      size < 0 ? "a list of numbers" : "a list of " + std::to_string(size) + " numbers";
  if (!node.IsSequence()) Fail(key, "must be " + expected + ", got " + Describe(node), node);
  if (size >= 0 && node.size() != static_cast<size_t>(size)) {
    Fail(key, "must be " + expected + ", got " + std::to_string(node.size()), node);
  }
  std::vector<double> values;
  for (const YAML::Node& element : node) {
    values.push_back(Number(element, key + "[" + std::to_string(values.size()) + "]"));
  }
  return values;
}

void YamlReader::CheckVersion(const YAML::Node& root, int supported) const {
  for (const auto& item : root) {
    if (item.first.IsScalar() && item.first.Scalar() == "version") {
      if (const int number = Integer(item.second, "version"); number != supported) {
        Fail("version",
             "unsupported version " + std::to_string(number) + " (this reader knows version " +
                 std::to_string(supported) + ")",
             item.second);
      }
    }
  }
}

}  // namespace hw::core
