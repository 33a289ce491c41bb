#pragma once

// Test support for report/ tests: a real analysis (analyze::Analyze on a plate with a hot
// disc, small images) to build reports from, and a job.

#include <cmath>
#include <filesystem>
#include <string>

#include "analyze/analyzer.h"
#include "analyze/test_scene.h"
#include "core/ply.h"
#include "report/job.h"

namespace hw::report::test {

struct PlateAnalysis {
  std::filesystem::path model_ply, analyze_json;
  analyze::AnalyzeResult result;
};

// analyze::test::HotDiscPlate written to folder/model.ply and analysed into
// folder/analysis with 160 × 120 images (one overview and the close-up).
// footprint_m: when finite, the plate carries it as temperature_footprint_m (a thermal
// pixel's size on the surface, as reconstruct writes it). view_from: when finite, every
// vertex carries the view vector to it (temperature_view_x/_y/_z: seen from there), and
// operator_max_c is the reflection check's (the disc peaks at 50 °C).
inline PlateAnalysis MakePlateAnalysis(const std::filesystem::path& folder, double footprint_m = std::nan(""),
                                       const Eigen::Vector3d& view_from = Eigen::Vector3d::Constant(std::nan("")),
                                       double operator_max_c = 37) {
  core::PlyMesh ply = analyze::test::HotDiscPlate();
  if (std::isfinite(footprint_m)) {
    ply.AddProperty("temperature_footprint_m", core::PlyType::kFloat32, std::vector<double>(ply.NumVertices(), footprint_m));
  }
  if (view_from.allFinite()) {
    const std::vector<Eigen::Vector3d> points = ply.Positions();
    for (int axis = 0; axis < 3; ++axis) {
      std::vector<double> component;
      for (const Eigen::Vector3d& p : points) component.push_back(view_from[axis] - p[axis]);
      ply.AddProperty(std::string("temperature_view_") + "xyz"[axis], core::PlyType::kFloat32, component);
    }
  }
  std::filesystem::create_directories(folder);
  PlateAnalysis out;
  out.model_ply = folder / "model.ply";
  core::WritePly(out.model_ply, ply);
  analyze::AnalyzeInputs inputs;
  inputs.model_path = out.model_ply;
  inputs.config.width = 160;
  inputs.config.height = 120;
  inputs.config.samples_per_pixel = 1;
  inputs.config.overviews = 1;
  inputs.config.legends = false;  // as heatwave audit: the report draws the colour bars
  inputs.num_threads = 2;
  inputs.config.reflections.operator_max_c = operator_max_c;
  const analyze::ThermalMesh mesh = analyze::ReadThermalMesh(out.model_ply);
  out.result = analyze::Analyze(mesh, inputs, folder / "analysis", nullptr);
  out.analyze_json = folder / "analysis" / "analyze.json";
  return out;
}

inline Job TestJob() {
  Job job;
  job.title = "Infrared thermography inspection report";
  job.reference = "HW-TEST-7";
  job.inspection_date = "2026-11-30";
  job.issued_utc = "2026-12-01T09:30:00Z";
  job.client = {"ACME Ltd", "1 Industrial Way\nSpringfield", "J. Smith"};
  job.site = {"Plant room 2", "Building 4", ""};
  job.assets = {{"MCC-1", "Motor control cabinet", "North wall", "400 V, 3 phase"}};
  job.inspector = {"A. Inspector", "ISO 9712 Level 2 thermographer", "TH-881", "Heat Ltd"};
  job.instrument = {"heatwave rig", "0042", "2026-06-01"};
  job.conditions.ambient_c = 21.5;
  job.conditions.emissivity = 0.95;
  job.standards = {"ISO 18434-1"};
  job.notes = "Door 3 was locked.";
  return job;
}

}  // namespace hw::report::test
