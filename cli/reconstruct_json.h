#pragma once

// reconstruct.json: the report `heatwave reconstruct` writes beside its model.

#include <string>

#include "cli/reconstruct.h"
#include "core/frame_clock.h"
#include "core/scan.h"
#include "reconstruct/reconstruction.h"
#include "reconstruct/thermal_fusion.h"

namespace hw::cli {

// Model vertices farther than this from the true surface count as outliers, not errors.
inline constexpr double kSurfaceSearchM = 0.05;

// The whole report: settings, input (with each stream's frame clock), counts, timings,
// memory, mesh, the evaluation against ground truth, thermal fusion (`thermal` non-null) and
// every frame. Strict JSON, one trailing newline.
std::string ReconstructReportJson(const ReconstructCommandOptions& options, const core::Scan& scan,
                                  const ReconstructCommandResult& r,
                                  const reconstruct::Reconstruction& reconstruction,
                                  const reconstruct::ScanReconstruction& run,
                                  const reconstruct::ThermalFusion* thermal);

// One stream's frame clock (core::StampFit without its times) as a JSON object: also what
// `heatwave scan-info --json` prints per stream.
std::string StampFitJson(const core::StampFit& fit);

}  // namespace hw::cli
