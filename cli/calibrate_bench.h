#pragma once

// heatwave calibrate bench: the whole calibration of a rig from one session folder — the
// thermal and colour intrinsics, the depth camera's distortion, the extrinsics, the clock
// offsets — each part by its own command's typed function (cli/calibrate.h,
// cli/calibrate_depth.h, cli/calibrate_extrinsics.h, cli/calibrate_latency.h) into
// DIR/<part>/, chained through rig.yaml (each part starts from the rig the previous one
// wrote), then DIR/rig.yaml and the certificate (report/certificate.h):
// certificate.{json,html,pdf}.
//
// Session folder (fixtures/bench_session.h writes a synthetic one):
//   SESSION/session.yaml        optional: rig_serial, depth_serial, rgb_serial,
//                               thermal_serial, operator (strings), version 1
//   SESSION/rig.yaml            the nominal rig to start from; when absent, the first
//                               part's scan rig.yaml
//   SESSION/truth/rig.yaml      optional (synthetic sessions): the true rig, compared in
//                               the certificate's fixture check (not QA)
//   SESSION/intrinsics-thermal/ scan folder: thermal stream of a square_grid, target.yaml
//   SESSION/intrinsics-rgb/     scan folder: rgb stream of a chessboard/aprilgrid, target.yaml
//   SESSION/depth/              scan folder: depth (and rgb) stills of a flat wall seen
//                               from near to far (heatwave synth --session depth-wall);
//                               its rig.yaml carries depth_correction, which the
//                               extrinsics part applies to every depth frame
//   SESSION/extrinsics/         scan folder: depth, rgb, thermal stills of a square_grid
//                               heated mask seen by all three, target.yaml
//   SESSION/latency/            scan folder: depth, rgb, thermal of a waved hot object
// A session without one of these folders (e.g. one written before the depth part existed)
// is refused naming it; with --partial the other parts run and the verdict is INCOMPLETE
// (without depth/, the extrinsics use the depth frames uncorrected and rig.yaml has no
// depth_correction, unless the nominal rig had one).

#include <filesystem>
#include <string>
#include <vector>

#include "cli/command.h"
#include "core/rig.h"
#include "report/certificate.h"

namespace hw::cli {

struct BenchCommandOptions {
  std::filesystem::path session;       // session folder (layout above)
  std::filesystem::path out_folder;    // DIR
  std::filesystem::path profile_path;  // qa.yaml for the intrinsics parts; "" = defaults
  double max_latency_sigma_ms = 2.0;   // QA of the latency part: each offset's σ at most, ms, (0, 1000]
  double max_rotation_sigma_deg = 0.1;   // QA of the extrinsics: largest per-axis rotation 1σ, deg, (0, 90]
  double max_translation_sigma_mm = 2.0; // QA of the extrinsics: largest per-axis translation 1σ, mm, (0, 1000]
  // QA of the depth part (DepthCommandOptions): every correction node's 1σ as depth at 3 m
  // at most this, mm, (0, 1000]; at least this fraction of the nodes covered, [0, 1].
  double max_depth_sigma_mm = 2.0;
  double min_depth_coverage = 0.9;
  bool partial = false;   // run the parts that are there when some are missing (verdict INCOMPLETE)
  bool overwrite = false; // replace an earlier bench run in out_folder

  // "" or "--flag: must be ..., got ...".
  std::string Check() const;
};

struct BenchResult {
  report::Certificate certificate;  // what certificate.{json,html,pdf} say
  core::Rig rig;                    // DIR/rig.yaml
  bool pass = false;                // certificate.verdict == "PASS"
  std::vector<std::string> written; // relative to out_folder
  double seconds = 0;               // wall time of the run
  double detect_seconds = 0;        // of which reading images, detecting targets, tracking the latency blob
};

// The part folders in bench order ("intrinsics-thermal", "intrinsics-rgb", "depth",
// "extrinsics", "latency").
std::vector<std::string> BenchPartFolders();

// Runs the bench. Throws core::InputError when the session folder is missing or has no
// rig, when a part's sub-folder is missing and not options.partial (naming every missing
// one; nothing is written), for an unreadable qa.yaml or session.yaml; UsageError for a
// non-empty out_folder without overwrite. A part that cannot be computed (its command's
// InputError) is recorded in the certificate as ERROR with the message — never a number —
// and the verdict is FAIL. A failed check is not an error: result.pass.
BenchResult RunBench(const BenchCommandOptions& options, bool quiet);

// The one-screen summary: each part's verdict and failed checks, the rig's key numbers,
// the verdict, the files.
std::string FormatBenchSummary(const BenchResult& result, const std::filesystem::path& out_folder);

// `heatwave calibrate bench SESSION --out DIR ...`, registered on the calibrate app as
// LatencySubcommand is.
class BenchSubcommand {
 public:
  explicit BenchSubcommand(CLI::App& calibrate);
  bool Chosen() const;
  int Run();

 private:
  CLI::App* app_ = nullptr;
  BenchCommandOptions options_;
  CommonOptions common_;
};

}  // namespace hw::cli
