#pragma once

// The thermal half of `heatwave reconstruct` (cli/reconstruct.cc): building the fusion from
// the scan and options, the model's temperature properties, the evaluation against a
// synthetic scan's truth, and the thermal parts of reconstruct.json and the summary.

#include <memory>
#include <string>
#include <vector>

#include "cli/reconstruct.h"
#include "core/ply.h"
#include "core/scan.h"
#include "reconstruct/thermal_fusion.h"

namespace hw::cli {

// The fusion for this scan, or nullptr (with a warning appended) when the scan has no
// thermal camera or frames, or options.thermal is false (no warning). Throws core::InputError
// for a bad emissivity file or truth mesh.
std::unique_ptr<reconstruct::ThermalFusion> MakeThermalFusion(const ReconstructCommandOptions& options,
                                                              const core::Scan& scan,
                                                              std::vector<std::string>& warnings,
                                                              std::string& emissivity_source);

// Fills the frame counts, timings and sizes of `result` from the fusion and the run.
void SummarizeThermal(const reconstruct::ThermalFusion& fusion, const reconstruct::ScanReconstruction& run,
                      const core::Scan& scan, ThermalCommandResult& result);

// Adds temperature_c, temperature_emissivity (emissivity.At each of `positions`, the model's
// vertices, where observed; NaN elsewhere), temperature_apparent_c, temperature_confidence,
// temperature_views, temperature_std_c, temperature_footprint_m and temperature_view_x/_y/_z
// (per vertex of `ply`, in that order) from `t`.
void AddTemperatureProperties(const reconstruct::PointTemperatures& t, const std::vector<Eigen::Vector3f>& positions,
                              const reconstruct::EmissivityMap& emissivity, core::PlyMesh& ply);

// Every method's error at the model vertices (already in the truth's frame) against truth.
void EvaluateThermalMethods(const reconstruct::ThermalFusion& fusion,
                            const std::vector<Eigen::Vector3f>& model_vertices_in_model,
                            const std::vector<Eigen::Vector3f>& model_vertices_in_truth,
                            const std::vector<Eigen::Vector3i>& faces,
                            const reconstruct::TemperatureTruth& truth, ThermalCommandResult& result);

// reconstruct.json's "thermal" object (settings, summary, evaluation, per-frame records).
std::string ThermalJson(const reconstruct::ThermalFusion& fusion, const ThermalCommandResult& result);

// The summary's thermal lines.
std::string FormatThermalSummary(const ThermalCommandResult& result);

}  // namespace hw::cli
