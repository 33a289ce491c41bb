#pragma once

// job.yaml: what the thermographer writes about an inspection — client, site, assets,
// inspector, instrument, conditions, the standard followed, notes — and which files the
// audit uses besides the scan. Read strictly (unknown keys, wrong types, bad dates are
// errors naming the key and line), so a typo never silently drops a line from a client's
// report. README "Audit reports" documents every key with an example.

#include <filesystem>
#include <limits>
#include <string>
#include <vector>

namespace hw::report {

struct JobParty {
  std::string name;     // required for client and site
  std::string address;  // may hold line breaks
  std::string contact;
};

struct JobAsset {
  std::string id;  // required: the asset tag the client uses ("MCC-1")
  std::string name;
  std::string location;
  std::string description;
};

struct JobInspector {
  std::string name;           // required
  std::string qualification;  // "ISO 9712 Level 2 thermographer"
  std::string certificate;    // certificate number
  std::string company;
};

struct JobInstrument {
  std::string model;             // "heatwave rig (Kinect v1 + Optris PI 450)"
  std::string serial;
  std::string calibration_date;  // YYYY-MM-DD, or ""
};

// Inspection conditions. NaN = not recorded. emissivity and reflected_c, when given,
// replace rig.yaml's for the temperature on the model (the on-site values are the right
// ones: reflected temperature changes with the room, emissivity with the surface).
struct JobConditions {
  double ambient_c = std::numeric_limits<double>::quiet_NaN();        // air, °C
  double reflected_c = std::numeric_limits<double>::quiet_NaN();      // reflected apparent, °C
  double emissivity = std::numeric_limits<double>::quiet_NaN();       // (0, 1]
  double load_percent = std::numeric_limits<double>::quiet_NaN();     // of rated load, [0, 200]
  double wind_m_s = std::numeric_limits<double>::quiet_NaN();         // ≥ 0
  double humidity_percent = std::numeric_limits<double>::quiet_NaN(); // relative, [0, 100]
  std::string load;     // free text: "motor at nominal speed"
  std::string weather;  // free text: "indoor, no sun"
};

struct Job {
  std::string title = "Infrared thermography inspection report";
  std::string reference;        // report number, e.g. "HW-2026-0142"
  std::string inspection_date;  // YYYY-MM-DD, required
  // Issue time, "YYYY-MM-DDTHH:MM:SSZ" (UTC): printed, and the PDF's creation date. Default:
  // the inspection date at 00:00:00Z — never the clock, so that the same inputs give the
  // same report bytes.
  std::string issued_utc;
  JobParty client;
  JobParty site;
  std::vector<JobAsset> assets;
  JobInspector inspector;
  JobInstrument instrument;
  JobConditions conditions;
  std::vector<std::string> standards;  // "ASTM E1934", "EN 13187", "ISO 18434-1"
  std::string notes;
  // Files, resolved against the job file's folder; empty = not given.
  std::filesystem::path analyze_config;  // analyze.yaml for the analysis stage
  std::filesystem::path certificate;     // calibration certificate.json
};

// Parses job.yaml text. Throws core::InputError(path_for_errors, reason) naming the key and
// line: unknown key, wrong type, a required key missing (inspection.date, client.name,
// site.name, inspector.name), a malformed date, a value out of range, an unsupported
// version. Relative paths are resolved against path_for_errors' folder.
Job ParseJob(const std::string& yaml_text, const std::filesystem::path& path_for_errors);
// ReadFile (≤ 1 MiB) + ParseJob.
Job ReadJob(const std::filesystem::path& path);

// True for "YYYY-MM-DD" naming a real calendar day (1900–2999).
bool IsIsoDate(const std::string& s);
// True for "YYYY-MM-DDTHH:MM:SSZ" with a real day and time.
bool IsIsoUtcTime(const std::string& s);

}  // namespace hw::report
