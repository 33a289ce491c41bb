#include "report/job.h"

#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "core/error.h"

namespace hw::report {
namespace {

const std::string kMinimal =
    "version: 1\n"
    "client: {name: ACME Ltd}\n"
    "site: {name: Plant room 2}\n"
    "inspection:\n"
    "  date: 2026-11-30\n"
    "  inspector: {name: A. Inspector}\n";

std::string ErrorOf(const std::string& text) {
  try {
    ParseJob(text, "/jobs/job.yaml");
  } catch (const core::InputError& e) {
    return e.what();
  }
  return "";
}

TEST(JobTest, MinimalJobTakesDefaults) {
  const Job job = ParseJob(kMinimal, "/jobs/job.yaml");
  EXPECT_EQ(job.client.name, "ACME Ltd");
  EXPECT_EQ(job.site.name, "Plant room 2");
  EXPECT_EQ(job.inspection_date, "2026-11-30");
  EXPECT_EQ(job.issued_utc, "2026-11-30T00:00:00Z");  // never the clock
  EXPECT_EQ(job.title, "Infrared thermography inspection report");
  EXPECT_TRUE(std::isnan(job.conditions.emissivity));
  EXPECT_TRUE(job.analyze_config.empty());
}

TEST(JobTest, FullJobReadsEveryKey) {
  const std::string text =
      "version: 1\n"
      "title: Annual electrical survey\n"
      "reference: HW-2026-0142\n"
      "issued: 2026-12-01T09:30:00Z\n"
      "client: {name: ACME Ltd, address: \"1 Industrial Way\\nSpringfield\", contact: J. Smith}\n"
      "site: {name: Plant room 2, address: Building 4}\n"
      "assets:\n"
      "  - {id: MCC-1, name: Motor control cabinet, location: North wall, description: 400 V}\n"
      "  - {id: 12345}\n"
      "inspection:\n"
      "  date: 2026-11-30\n"
      "  inspector: {name: A. Inspector, qualification: ISO 9712 Level 2, certificate: TH-881, company: Heat Ltd}\n"
      "  instrument: {model: heatwave rig, serial: 0042, calibration_date: 2026-06-01}\n"
      "  standards: [ASTM E1934, ISO 18434-1]\n"
      "conditions:\n"
      "  ambient_c: 21.5\n"
      "  reflected_c: 20.4\n"
      "  emissivity: 0.93\n"
      "  load_percent: 80\n"
      "  load: motor at nominal speed\n"
      "  weather: indoor\n"
      "  wind_m_s: 0\n"
      "  humidity_percent: 45\n"
      "notes: |\n"
      "  Door 3 was locked.\n"
      "  Second line.\n"
      "analyze_config: configs/analyze.yaml\n";
  const Job job = ParseJob(text, "/jobs/job.yaml");
  EXPECT_EQ(job.title, "Annual electrical survey");
  EXPECT_EQ(job.reference, "HW-2026-0142");
  EXPECT_EQ(job.issued_utc, "2026-12-01T09:30:00Z");
  EXPECT_EQ(job.client.address, "1 Industrial Way\nSpringfield");
  ASSERT_EQ(job.assets.size(), 2u);
  EXPECT_EQ(job.assets[0].location, "North wall");
  EXPECT_EQ(job.assets[1].id, "12345");  // a number written as an id is text
  EXPECT_EQ(job.instrument.serial, "0042");
  EXPECT_EQ(job.instrument.calibration_date, "2026-06-01");
  ASSERT_EQ(job.standards.size(), 2u);
  EXPECT_EQ(job.standards[1], "ISO 18434-1");
  EXPECT_DOUBLE_EQ(job.conditions.ambient_c, 21.5);
  EXPECT_DOUBLE_EQ(job.conditions.reflected_c, 20.4);
  EXPECT_DOUBLE_EQ(job.conditions.emissivity, 0.93);
  EXPECT_DOUBLE_EQ(job.conditions.load_percent, 80);
  EXPECT_EQ(job.conditions.load, "motor at nominal speed");
  EXPECT_DOUBLE_EQ(job.conditions.humidity_percent, 45);
  EXPECT_EQ(job.notes, "Door 3 was locked.\nSecond line.\n");
  EXPECT_EQ(job.analyze_config, std::filesystem::path("/jobs/configs/analyze.yaml"));
}

TEST(JobTest, ErrorsNameTheKeyAndLine) {
  EXPECT_EQ(ErrorOf(kMinimal + "colour: red\n"), "/jobs/job.yaml: top level: unknown key 'colour' (line 7)");
  EXPECT_EQ(ErrorOf(kMinimal + "conditions: {emissivity: high}\n"),
            "/jobs/job.yaml: conditions.emissivity: must be a number, got 'high' (line 7)");
  EXPECT_EQ(ErrorOf(kMinimal + "conditions: {emissivity: 1.5}\n"),
            "/jobs/job.yaml: conditions.emissivity: must be in [0.01, 1], got 1.5 (line 7)");
  EXPECT_EQ(ErrorOf(kMinimal + "assets: {id: 3}\n"), "/jobs/job.yaml: assets: must be a list of assets, got a mapping (line 7)");
  EXPECT_EQ(ErrorOf("version: 1\nsite: {name: S}\n"
                    "inspection: {date: 2026-11-30, inspector: {name: I}}\n"),
            "/jobs/job.yaml: client: missing required key (line 1)");
  EXPECT_NE(ErrorOf("version: 1\nclient: {name: C}\nsite: {name: S}\n"
                    "inspection: {date: 2026-02-30, inspector: {name: I}}\n")
                .find("inspection.date: must be a date YYYY-MM-DD, got '2026-02-30'"),
            std::string::npos);
  EXPECT_NE(ErrorOf(kMinimal + "issued: 2026-12-01 10:00\n").find("issued: must be a UTC time"), std::string::npos);
  EXPECT_NE(ErrorOf("version: 1\nclient: {name: \"  \"}\nsite: {name: S}\n"
                    "inspection: {date: 2026-11-30, inspector: {name: I}}\n")
                .find("client.name: must not be empty"),
            std::string::npos);
  EXPECT_NE(ErrorOf("version: 2\n").find("version"), std::string::npos);
  EXPECT_NE(ErrorOf(kMinimal + "notes: [a, b]\n").find("notes: must be a name, got a list"), std::string::npos);
}

TEST(JobTest, Dates) {
  EXPECT_TRUE(IsIsoDate("2024-02-29"));
  EXPECT_FALSE(IsIsoDate("2023-02-29"));
  EXPECT_FALSE(IsIsoDate("2026-13-01"));
  EXPECT_FALSE(IsIsoDate("2026-1-01"));
  EXPECT_FALSE(IsIsoDate("2026-01-0a"));
  EXPECT_TRUE(IsIsoUtcTime("2026-12-01T23:59:59Z"));
  EXPECT_FALSE(IsIsoUtcTime("2026-12-01T24:00:00Z"));
  EXPECT_FALSE(IsIsoUtcTime("2026-12-01T10:00:00+01:00"));
}

}  // namespace
}  // namespace hw::report
