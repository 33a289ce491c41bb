// A person walking through a scan (fixtures/passer.h): reconstruction leaves them out of the
// model (dynamic_mask.h: not integrated in front of the model, carved where seen through) and
// thermal fusion keeps their temperature off the surfaces behind them (the occlusion test).

#include <cstdio>
#include <filesystem>
#include <utility>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/scan.h"
#include "fixtures/passer.h"
#include "reconstruct/reconstruct_test_support.h"
#include "reconstruct/reconstruction.h"
#include "reconstruct/surface_eval.h"
#include "reconstruct/thermal_eval.h"
#include "reconstruct/thermal_fusion.h"

namespace hw::reconstruct {
namespace {

namespace fs = std::filesystem;

// The reconstruction tests' 160×120 scan with its 80×60 thermal stream, 2 s; with `passer`
// a person crossing the view at mid-scan (in 31 of its 58 depth frames).
fs::path Scan(bool passer) {
  fixtures::SynthScanOptions o = test::TestScanOptions("equipment-small", fixtures::MotionKind::kSmooth, 2.0);
  o.write_thermal = true;
  if (!passer) return test::CachedScan("passer-absent", o);
  return fixtures::test::CachedTestData("passer-walks-by", "depth.txt", [&](const fs::path& folder) {
    // Rendered beside the cache folder (held by the cache's run marker, which readers
    // refuse), edited there, then moved in.
    const fs::path scratch = folder.string() + ".render";
    fs::remove_all(scratch);
    fixtures::SynthesizeScan(o, scratch);
    fixtures::AddPasser(core::Scan::Open(scratch), {});
    for (const auto& entry : fs::directory_iterator(scratch)) {
      fs::rename(entry.path(), folder / entry.path().filename());
    }
    fs::remove_all(scratch);
  });
}

struct Outcome {
  int vertices = 0, off_surface = 0;  // mesh vertices, and those > 5 cm from the truth surface
  double rmse_k = 0;                  // offline temperature vs truth (TemperatureErrorStats)
  int64_t masked = 0, carved = 0, occluded_rays = 0;
};

// Fused along groundtruth.txt (the tracker out of the question: its failure with a passer is
// measured on full-size scans in the README), 1 cm voxels as the other reconstruction tests.
Outcome Reconstruct(const fs::path& folder, bool dynamic) {
  const core::Scan scan = core::Scan::Open(folder);
  ReconstructionOptions options;
  options.tsdf.voxel_size_m = 0.01;
  options.tsdf.truncation_m = 0.04;
  options.mesh.min_component_triangles = 20;
  ThermalFusionOptions thermal_options;
  if (!dynamic) {
    options.dynamic.margin_m = options.dynamic.margin_fraction = 0;
    thermal_options.occlusion_margin_m = thermal_options.occlusion_margin_fraction = 0;
  }
  Reconstruction reconstruction(scan.rig(), options);
  ThermalFusion thermal(scan.rig(), thermal_options, EmissivityMap(*scan.rig().thermal_settings),
                        scan.ffc_timestamps_s());
  ScanReconstructionOptions scan_options;
  scan_options.start_at_groundtruth = true;
  scan_options.poses = *scan.groundtruth();
  ReconstructScan(scan, reconstruction, scan_options, nullptr, &thermal);
  const TriangleMesh mesh = reconstruction.ExtractMesh();
  const TemperatureTruth truth = ReadTemperatureTruth(folder / "truth" / "scene.ply");

  Outcome run;
  run.vertices = static_cast<int>(mesh.positions.size());
  std::vector<Eigen::Vector3d> points;
  for (const Eigen::Vector3f& p : mesh.positions) points.push_back(p.cast<double>());
  for (const std::optional<double>& d : PointToMeshDistances(points, truth.vertices, truth.faces, 0.05)) {
    run.off_surface += !d.has_value();
  }
  const PointTemperatures t = thermal.Sample(mesh.positions, ThermalMethod::kOffline);
  const std::vector<double> estimate(t.surface_c.begin(), t.surface_c.end());
  run.rmse_k = CompareTemperatures(mesh.positions, mesh.faces, estimate, truth, {}).stats.rmse_k;
  for (const FrameRecord& f : reconstruction.frames()) {
    run.masked += f.dynamic_pixels;
    run.carved += f.carved_points;
  }
  for (const ThermalFrameRecord& f : thermal.frames()) run.occluded_rays += f.occluded;
  return run;
}

TEST(DynamicScene, APasserByIsNeitherFusedNorPaintedOnTheSurfacesBehind) {
  const Outcome clean = Reconstruct(Scan(false), true);
  const Outcome with = Reconstruct(Scan(true), true);
  const Outcome without = Reconstruct(Scan(true), false);
  for (const auto& [name, r] : {std::pair{"clean", clean}, {"passer", with}, {"passer, no dynamic handling", without}}) {
    std::printf("%-28s %6d vertices, %6d off the surface; offline RMSE %.3f K; masked %lld, carved %lld, occluded rays %lld\n",
                name, r.vertices, r.off_surface, r.rmse_k, static_cast<long long>(r.masked),
                static_cast<long long>(r.carved), static_cast<long long>(r.occluded_rays));
  }
  // Measured (clean / passer / passer without the handling): off the truth surface 0 / 2367 /
  // 21957 vertices of 34948 / 37386 / 56976; offline RMSE 1.104 / 1.114 / 1.215 K (the
  // camera's ±1–2 K calibration error included). Without the dynamic handling the person's
  // swept body is 39 % of the model and the temperature on the real surfaces 0.11 K worse;
  // with it, 89 % of that body is gone and the temperature within 0.02 K of the clean scan's.
  // The bounds sit about halfway between.
  EXPECT_GT(without.off_surface, 0.25 * without.vertices);
  EXPECT_LT(with.off_surface, 0.2 * without.off_surface);
  EXPECT_LT(with.off_surface, 0.1 * with.vertices);
  EXPECT_LT(with.rmse_k, clean.rmse_k + 0.05);
  EXPECT_GT(without.rmse_k, with.rmse_k + 0.05);
  EXPECT_GT(with.masked, 0);
  EXPECT_GT(with.carved, 0);
  EXPECT_GT(with.occluded_rays, 0);
  // A static scene: nothing taken for something that moved.
  EXPECT_EQ(clean.off_surface, 0);
  EXPECT_EQ(clean.masked, 0);
  EXPECT_EQ(clean.carved, 0);
}

}  // namespace
}  // namespace hw::reconstruct
