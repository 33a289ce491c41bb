#include "report/job.h"

#include <cmath>
#include <cstdio>

#include "core/atomic_file.h"
#include "core/yaml_reader.h"

namespace hw::report {
namespace {

using core::YamlReader;
using Fields = YamlReader::Fields;

// A free-text field: any scalar (a serial number written as 12345 is text too).
std::string Text(const YamlReader& reader, const Fields& f, const std::string& name) {
  if (!f.Has(name)) return "";
  return reader.String(f.Required(name), f.Path(name));
}

std::string RequiredText(const YamlReader& reader, const Fields& f, const std::string& name) {
  const std::string s = reader.String(f.Required(name), f.Path(name));
  if (s.find_first_not_of(" \t\n") == std::string::npos) reader.Fail(f.Path(name), "must not be empty", f.Required(name));
  return s;
}

// An optional number in [lo, hi]; NaN when absent.
double Number(const YamlReader& reader, const Fields& f, const std::string& name, double lo, double hi,
              const std::string& unit) {
  if (!f.Has(name)) return std::nan("");
  const double v = reader.Number(f.Required(name), f.Path(name));
  if (const std::string p = core::RangeProblem(f.Path(name), v, lo, hi, unit); !p.empty()) {
    reader.Fail(f.Path(name), p.substr(p.find(": ") + 2), f.Required(name));
  }
  return v;
}

std::string Date(const YamlReader& reader, const Fields& f, const std::string& name, bool required) {
  if (!required && !f.Has(name)) return "";
  const std::string s = reader.String(f.Required(name), f.Path(name));
  if (!IsIsoDate(s)) reader.Fail(f.Path(name), "must be a date YYYY-MM-DD, got '" + core::Printable(s) + "'", f.Required(name));
  return s;
}

JobParty Party(const YamlReader& reader, const YAML::Node& node, const std::string& key) {
  const Fields f = reader.Mapping(node, key, {"name", "address", "contact"});
  JobParty p;
  p.name = RequiredText(reader, f, "name");
  p.address = Text(reader, f, "address");
  p.contact = Text(reader, f, "contact");
  return p;
}

void ParseInspection(const YamlReader& reader, const YAML::Node& node, Job* job) {
  const Fields f = reader.Mapping(node, "inspection", {"date", "inspector", "instrument", "standards"});
  job->inspection_date = Date(reader, f, "date", true);
  {
    const Fields g = reader.Mapping(f.Required("inspector"), f.Path("inspector"),
                                    {"name", "qualification", "certificate", "company"});
    job->inspector.name = RequiredText(reader, g, "name");
    job->inspector.qualification = Text(reader, g, "qualification");
    job->inspector.certificate = Text(reader, g, "certificate");
    job->inspector.company = Text(reader, g, "company");
  }
  if (f.Has("instrument")) {
    const Fields g = reader.Mapping(f.Required("instrument"), f.Path("instrument"),
                                    {"model", "serial", "calibration_date"});
    job->instrument.model = Text(reader, g, "model");
    job->instrument.serial = Text(reader, g, "serial");
    job->instrument.calibration_date = Date(reader, g, "calibration_date", false);
  }
  if (f.Has("standards")) {
    const YAML::Node& list = f.Required("standards");
    if (!list.IsSequence()) {
      reader.Fail(f.Path("standards"), "must be a list of names, got " + core::Describe(list), list);
    }
    for (const YAML::Node& s : list) job->standards.push_back(reader.String(s, f.Path("standards")));
  }
}

void ParseConditions(const YamlReader& reader, const YAML::Node& node, JobConditions* c) {
  const Fields f = reader.Mapping(node, "conditions",
                                  {"ambient_c", "reflected_c", "emissivity", "load_percent", "load", "weather",
                                   "wind_m_s", "humidity_percent"});
  c->ambient_c = Number(reader, f, "ambient_c", -90, 100, "°C");
  c->reflected_c = Number(reader, f, "reflected_c", -200, 3000, "°C");
  c->emissivity = Number(reader, f, "emissivity", 0.01, 1, "");
  c->load_percent = Number(reader, f, "load_percent", 0, 200, "%");
  c->wind_m_s = Number(reader, f, "wind_m_s", 0, 100, "m/s");
  c->humidity_percent = Number(reader, f, "humidity_percent", 0, 100, "%");
  c->load = Text(reader, f, "load");
  c->weather = Text(reader, f, "weather");
}

std::filesystem::path FilePath(const YamlReader& reader, const Fields& f, const std::string& name,
                               const std::filesystem::path& job_path) {
  if (!f.Has(name)) return {};
  const std::string s = RequiredText(reader, f, name);
  const std::filesystem::path p(s);
  return p.is_absolute() ? p : job_path.parent_path() / p;
}

}  // namespace

bool IsIsoDate(const std::string& s) {
  int y = 0, m = 0, d = 0;
  char tail = 0;
  if (s.size() != 10 || s[4] != '-' || s[7] != '-') return false;
  if (std::sscanf(s.c_str(), "%4d-%2d-%2d%c", &y, &m, &d, &tail) != 3) return false;
  for (size_t i : {0, 1, 2, 3, 5, 6, 8, 9}) {
    if (s[i] < '0' || s[i] > '9') return false;
  }
  if (y < 1900 || y > 2999 || m < 1 || m > 12 || d < 1) return false;
  static constexpr int kDays[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  const bool leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
  return d <= kDays[m - 1] + (m == 2 && leap ? 1 : 0);
}

bool IsIsoUtcTime(const std::string& s) {
  if (s.size() != 20 || s[10] != 'T' || s[13] != ':' || s[16] != ':' || s[19] != 'Z') return false;
  if (!IsIsoDate(s.substr(0, 10))) return false;
  for (size_t i : {11, 12, 14, 15, 17, 18}) {
    if (s[i] < '0' || s[i] > '9') return false;
  }
  const int h = std::stoi(s.substr(11, 2)), mi = std::stoi(s.substr(14, 2)), se = std::stoi(s.substr(17, 2));
  return h < 24 && mi < 60 && se < 60;
}

Job ParseJob(const std::string& yaml_text, const std::filesystem::path& path_for_errors) {
  const YamlReader reader(path_for_errors);
  const YAML::Node root = reader.LoadMapping(yaml_text);
  reader.CheckVersion(root, 1);
  const Fields top = reader.Mapping(root, "",
                                    {"version", "title", "reference", "issued", "client", "site", "assets",
                                     "inspection", "conditions", "notes", "analyze_config", "certificate"});
  Job job;
  if (top.Has("title")) job.title = RequiredText(reader, top, "title");
  job.reference = Text(reader, top, "reference");
  job.client = Party(reader, top.Required("client"), "client");
  job.site = Party(reader, top.Required("site"), "site");
  ParseInspection(reader, top.Required("inspection"), &job);
  if (top.Has("issued")) {
    job.issued_utc = reader.String(top.Required("issued"), "issued");
    if (!IsIsoUtcTime(job.issued_utc)) {
      reader.Fail("issued", "must be a UTC time YYYY-MM-DDTHH:MM:SSZ, got '" + core::Printable(job.issued_utc) + "'",
                  top.Required("issued"));
    }
  } else {
    job.issued_utc = job.inspection_date + "T00:00:00Z";
  }
  if (top.Has("assets")) {
    const YAML::Node& list = top.Required("assets");
    if (!list.IsSequence()) reader.Fail("assets", "must be a list of assets, got " + core::Describe(list), list);
    size_t i = 0;
    for (const YAML::Node& node : list) {
      const std::string key = "assets[" + std::to_string(i++) + "]";
      const Fields f = reader.Mapping(node, key, {"id", "name", "location", "description"});
      JobAsset a;
      a.id = RequiredText(reader, f, "id");
      a.name = Text(reader, f, "name");
      a.location = Text(reader, f, "location");
      a.description = Text(reader, f, "description");
      job.assets.push_back(a);
    }
  }
  if (top.Has("conditions")) ParseConditions(reader, top.Required("conditions"), &job.conditions);
  job.notes = Text(reader, top, "notes");
  job.analyze_config = FilePath(reader, top, "analyze_config", path_for_errors);
  job.certificate = FilePath(reader, top, "certificate", path_for_errors);
  return job;
}

Job ReadJob(const std::filesystem::path& path) {
  return ParseJob(core::ReadFile(path, core::kMaxConfigFileBytes), path);
}

}  // namespace hw::report
