// heatwave demo: renders the bundled synthetic plant-room scan and audits it end to end —
// the README's main command. The scan is not stored in git: it is rendered
// deterministically (seed 1) from the "equipment" scene (fixtures/scenes.h), with its
// ground truth in scan/truth/ to check the report against.
#include <iostream>
#include <memory>

#include "analyze/analyze_config.h"
#include "cli/audit.h"
#include "cli/command.h"
#include "core/atomic_file.h"
#include "core/option_check.h"
#include "core/output_folder.h"
#include "core/progress.h"
#include "core/strings.h"
#include "fixtures/synth_scan.h"
#include "report/job.h"

namespace hw::cli {
namespace {

namespace fs = std::filesystem;

struct DemoOptions {
  fs::path out_folder = "heatwave-demo";
  bool overwrite = false;
  int num_threads = 0;
  double duration_s = 1.0;  // of the rendered scan: 30 depth frames, ~25 thermal frames
  report::ReportWriteOptions report;

  std::string Check() const {
    if (!(duration_s >= 0.5 && duration_s <= 60)) return core::OptionFail("--duration", duration_s, "in [0.5, 60] s");
    if (num_threads < 0 || num_threads > 256) return core::OptionFail("--threads", num_threads, "in [0, 256]");
    return report.Check();
  }
};

}  // namespace

std::string DemoAnalyzeYaml() {
  return "# analyze.yaml of the demo (README, \"analyze.yaml\"). The model is in the first depth\n"
         "# camera's frame: image up is its -y (the rig was held level). Fewer views than the\n"
         "# defaults keep the demo quick.\n"
         "version: 1\n"
         "images:\n"
         "  up: [0, -1, 0]\n"
         "  overviews: 2\n"
         "  max_closeups: 6\n";
}

std::string DemoJobYaml() {
  return "# job.yaml of the demo (README, \"Audit reports\"): what the thermographer writes about\n"
         "# the inspection. Everything here is printed in the report as text.\n"
         "version: 1\n"
         "title: Infrared thermography inspection report\n"
         "reference: HW-DEMO-0001\n"
         "issued: 2026-12-01T16:00:00Z      # the PDF's creation date: same inputs, same bytes\n"
         "client:\n"
         "  name: Example Manufacturing Ltd\n"
         "  address: \"12 Foundry Road\\nSpringfield\"\n"
         "  contact: Facilities manager\n"
         "site:\n"
         "  name: Plant room B\n"
         "  address: Building 4, ground floor\n"
         "assets:\n"
         "  - {id: MCC-3, name: Motor control cabinet, location: North wall, description: 400 V distribution}\n"
         "  - {id: P-11, name: Heating flow and return pipes, location: East wall}\n"
         "  - {id: M-2, name: Circulation pump motor, location: \"Floor, centre\"}\n"
         "inspection:\n"
         "  date: 2026-12-01\n"
         "  inspector:\n"
         "    name: A. Thermographer\n"
         "    qualification: ISO 9712 Level 2 thermographer\n"
         "    certificate: TH-0000\n"
         "    company: heatwave demo\n"
         "  instrument: {model: heatwave synthetic rig (RGB-D + 320x240 LWIR), serial: SYNTH-1}\n"
         "  standards: [ISO 18434-1, ASTM E1934]\n"
         "conditions:\n"
         "  ambient_c: 20\n"
         "  load_percent: 70\n"
         "  load: cabinet energised, pump running\n"
         "  weather: indoor, no solar load\n"
         "notes: |\n"
         "  Synthetic demonstration scan rendered by heatwave (scene \"equipment\", seed 1); its\n"
         "  ground truth is in scan/truth/. Emissivity and reflected temperature are the rig's.\n"
         "analyze_config: analyze.yaml\n";
}

int RunDemo(int argc, char** argv) {
  CLI::App app("Render the bundled demo scan (a plant room with hot spots) and audit it: model, images, "
               "report.html and report.pdf.",
               "heatwave demo");
  DemoOptions o;
  CommonOptions common;
  AddCommonOptions(app, common);
  app.add_option("--out", o.out_folder, "demo folder: job.yaml, analyze.yaml, scan/, audit/")->capture_default_str();
  app.add_flag("--overwrite", o.overwrite, "replace an earlier demo in --out");
  app.add_option("--threads", o.num_threads, "worker threads, 0 = all cores")->capture_default_str();
  app.add_option("--duration", o.duration_s, "length of the rendered scan, s")->capture_default_str();
  app.add_flag_callback("--no-3d", [&o] { o.report.model_view = false; }, "report.html without the 3D view");
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  return RunGuarded([&] {
    ThrowIfInvalid(o.Check());
    // The bundled files parse (a bug otherwise): checked before minutes of rendering.
    report::ParseJob(DemoJobYaml(), o.out_folder / "job.yaml");
    analyze::ParseAnalyzeConfig(DemoAnalyzeYaml(), o.out_folder / "analyze.yaml");
    const fs::path scan = o.out_folder / "scan";
    {
      core::OutputFolder folder(o.out_folder, "heatwave demo");
      if (!folder.IsEmpty()) {
        if (!o.overwrite) {
          folder.Abandon();
          throw UsageError("--out " + o.out_folder.string() + ": folder is not empty; pass --overwrite to replace the demo");
        }
        folder.Remove({"scan", "audit", "job.yaml", "analyze.yaml"});
      }
      core::WriteFileAtomically(o.out_folder / "job.yaml", DemoJobYaml());
      core::WriteFileAtomically(o.out_folder / "analyze.yaml", DemoAnalyzeYaml());
      fixtures::SynthScanOptions s = fixtures::SynthScanOptions::Full("equipment");
      s.seed = 1;
      s.duration_s = o.duration_s;
      ThrowIfInvalid(s.Check());
      core::ProgressStage stage("[0/3]");
      std::unique_ptr<core::ProgressBar> bar;
      fixtures::SynthesizeScan(s, scan, [&](int done, int total) {
        if (!bar) bar = std::make_unique<core::ProgressBar>("render demo scan", total, "frames", common.quiet);
        bar->Set(done);
      });
      bar.reset();
      folder.Commit();
    }
    AuditCommandOptions a;
    a.scan_folder = scan;
    a.job_path = o.out_folder / "job.yaml";
    a.out_folder = o.out_folder / "audit";
    a.num_threads = o.num_threads;
    a.report = o.report;
    const AuditResult result = AuditCommand(a, common.quiet);
    if (!common.quiet) {
      std::cout << FormatAuditSummary(result)
                << core::StringPrintf("Demo       scan %s (ground truth in truth/), job %s\n"
                                      "Open       %s in a browser, %s in a PDF viewer\n",
                                      scan.c_str(), a.job_path.c_str(), result.report.html_path.c_str(),
                                      result.report.pdf_path.c_str())
                << std::flush;
    }
    return kExitOk;
  });
}

}  // namespace hw::cli
