#pragma once

// Strict reading of heatwave's configuration files (rig.yaml, target.yaml) on yaml-cpp, and
// the text and message helpers they share with the .cameramodel reader. Internal to
// hw_core_rig: the public interface is rig.h and cameramodel_io.h.

#include <yaml-cpp/yaml.h>

#include <cstddef>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace hw::core {

// ---------------------------------------------------------------------------------------
// Text of a configuration file, before any parser sees it.

// Deeper nesting of YAML mappings and lists is refused (rig.yaml needs 4: top level,
// cameras, depth, distortion): a clear message instead of yaml-cpp 0.7's own limit of 500
// nested nodes, which it reports as "bad file".
inline constexpr int kMaxYamlNesting = 32;

// Makes the raw bytes of a configuration file (rig.yaml, target.yaml, .cameramodel) ready
// for its parser, the same way for every reader, so that line numbers in messages are the
// ones an editor shows:
// - a UTF-8 byte order mark at the start is dropped (Windows editors write one);
// - CRLF and lone CR line ends become LF (yaml-cpp 0.7 takes CRLF but reads a CR-only file
//   as one line; libmrcal takes neither a BOM nor CR-only);
// - a NUL byte or another control character (below 0x20 but tab, LF, CR; and DEL) is an
//   InputError "NUL byte at line 3, column 7" (column in characters), as is a UTF-16/32
//   byte order mark: yaml-cpp would otherwise report an escape error with the raw byte in it.
std::string PrepareConfigText(std::string_view text, const std::filesystem::path& path_for_errors);

// ---------------------------------------------------------------------------------------
// Messages. Every InputError of the config readers is thrown through ThrowInputError, so
// that what() is one line whatever the file holds.

// `text` on one line: LF, CR, tab and other control characters escaped ("\n", "\r", "\t",
// "\x01").
std::string OneLine(std::string_view text);
// `text` for quoting a value in a message: OneLine, cut after 40 characters ("...").
std::string Printable(std::string_view text);

[[noreturn]] void ThrowInputError(const std::filesystem::path& path, const std::string& reason);

// Shortest text that reads back to the same double, exponent without '+' or leading zeros
// ("1e300", "1e-320", "0.01", "nan", "inf"): user-given values in messages.
std::string MessageNumber(double value);
// 10 significant digits: computed values in messages (a quaternion's norm).
std::string RoundedNumber(double value);

// "" when value is in [lo, hi], else "<key>: must be in [lo, hi] <unit>, got <value>"
// ("must be finite" for NaN and inf).
std::string RangeProblem(const std::string& key, double value, double lo, double hi,
                         const std::string& unit);

// Shortest text that reads back to the same double, spelled as a YAML float that every
// YAML reader takes for one (with a '.': "1.0e-05", "525.0").
std::string FormatYamlDouble(double value);
std::string FormatYamlList(const double* values, size_t count);

// ---------------------------------------------------------------------------------------
// Strict YAML reading: every accessor names the key path and the line on failure.

class YamlReader {
 public:
  explicit YamlReader(std::filesystem::path path) : path_(std::move(path)) {}

  [[noreturn]] void Fail(const std::string& key, const std::string& problem,
                         const YAML::Node& node) const;
  [[noreturn]] void Fail(const std::string& key, const std::string& problem,
                         const YAML::Mark& mark) const;

  // The single YAML document of `text` (raw file bytes: PrepareConfigText is applied here)
  // as a mapping.
  YAML::Node LoadMapping(const std::string& text) const;

  // Fails when the mapping's `version` key is present and not `supported`, before any other
  // key is looked at: a newer file is reported as such, not by its first unknown key.
  void CheckVersion(const YAML::Node& root, int supported) const;

  // Maps a Check() message about the mapping `node`, e.g. "cameras.depth.fx: must be ...",
  // to "<prefix>.cameras.depth.fx: must be ... (line N)", N the line of that key's value
  // (or of the deepest enclosing node present in the file).
  [[noreturn]] void FailCheck(const YAML::Node& node, const std::string& prefix,
                              const std::string& message) const;

  // The keys of a mapping, each checked against `allowed`, with no duplicates.
  class Fields {
   public:
    Fields(const YamlReader& reader, std::string key, YAML::Node node)
        : reader_(reader), key_(std::move(key)), node_(std::move(node)) {}

    const std::string& key() const { return key_; }
    const YAML::Node& node() const { return node_; }
    bool Has(const std::string& name) const { return values_.count(name) > 0; }
    std::string Path(const std::string& name) const;

    const YAML::Node& Required(const std::string& name) const;
    // The node of `name` or, when absent, of the whole mapping: where to point a message.
    const YAML::Node& NodeFor(const std::string& name) const;

    // Maps "fx: must be > 0, got -3" (a Check() message about field "fx" of this mapping)
    // to "<key>.fx: must be > 0, got -3 (line N)".
    [[noreturn]] void FailCheck(const std::string& message) const {
      reader_.FailCheck(node_, key_, message);
    }

   private:
    friend class YamlReader;
    const YamlReader& reader_;
    std::string key_;
    YAML::Node node_;
    std::map<std::string, YAML::Node> values_;
  };

  Fields Mapping(const YAML::Node& node, const std::string& key,
                 const std::set<std::string>& allowed) const;
  double Number(const YAML::Node& node, const std::string& key) const;
  int Integer(const YAML::Node& node, const std::string& key) const;
  std::string String(const YAML::Node& node, const std::string& key) const;
  // A list of numbers; of exactly `size` elements unless size is negative.
  std::vector<double> NumberList(const YAML::Node& node, const std::string& key,
                                 int size = -1) const;

 private:
  std::filesystem::path path_;
};

// "nothing", "a list", "a mapping", "'plain'" or "string \"quoted\"", for messages.
std::string Describe(const YAML::Node& node);

}  // namespace hw::core
