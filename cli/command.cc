#include "cli/command.h"

#include <iostream>

#include "core/error.h"
#include "core/output_folder.h"
#include "core/strings.h"

namespace hw::cli {

const std::vector<Command>& Commands() {
  static const std::vector<Command> commands = {
      {"help", RunHelp, "list the commands, or show one command's options"},
      {"demo", RunDemo, "render the bundled demo scan and audit it end to end (model, HTML and PDF report)"},
      {"audit", RunAudit, "the whole job: reconstruct a scan with temperature, analyze it, write the report"},
      {"version", RunVersion, "print the version"},
      {"scan-info", RunScanInfo, "validate a scan folder and summarise its streams"},
      {"synth", RunSynth, "render a synthetic scan or calibration session with ground truth"},
      {"reconstruct", RunReconstruct, "track the depth stream and fuse a coloured 3D model"},
      {"analyze", RunAnalyze, "find and measure hot and cold spots on a model; render it in the four modes"},
      {"compare", RunCompare, "align two models of one asset and map the temperature change; list spot changes"},
      {"report", RunReport, "write the HTML and PDF report of an audit or analysis folder"},
      {"calibrate", RunCalibrate, "calibrate the rig: intrinsics, extrinsics, clock offsets, the whole bench with a certificate (QA verdicts)"},
      {"devices", RunDevices, "list connected RGB-D devices (OpenNI2) and USB thermal cameras with what each supports"},
      {"capture", RunCapture, "record a scan folder from a live rig: OpenNI2 depth and colour, USB radiometric thermal"},
      {"import-oni", RunImportOni, "convert an OpenNI2 recording (.oni) into a scan folder"},
      {"eval-trajectory", RunEvalTrajectory,
       "ATE and RPE of a TUM trajectory against a ground truth"},
  };
  return commands;
}

void AddCommonOptions(CLI::App& app, CommonOptions& options) {
  app.add_flag("-q,--quiet", options.quiet, "no progress bar and no summary");
}

namespace {

// A bool option's value must be true, false, 1 or 0: CLI11 alone reads any number as a bool
// (2 and -1 were accepted). Flags (no value) are untouched.
void CheckBoolValues(CLI::App& app) {
  for (CLI::Option* option : app.get_options()) {
    if (option->get_type_name() == "BOOLEAN" && option->get_expected_min() > 0) {
      option->check(CLI::IsMember({"true", "false", "1", "0"}));
    }
  }
  for (CLI::App* sub : app.get_subcommands({})) CheckBoolValues(*sub);
}

}  // namespace

int Parse(CLI::App& app, int argc, char** argv) {
  CheckBoolValues(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    std::cout << app.help();
    return kExitOk;
  } catch (const CLI::CallForAllHelp&) {
    std::cout << app.help("", CLI::AppFormatMode::All);
    return kExitOk;
  } catch (const CLI::ParseError& e) {
    PrintError(e.what());
    std::cerr << "Run '" << app.get_name() << " --help' for the options.\n";
    return kExitUsage;
  }
  return -1;
}

void ThrowIfInvalid(const std::string& message, const std::string& prefix) {
  if (!message.empty()) throw UsageError(prefix + message);
}

void PrintError(std::string_view message) {
  // Scripts and log scanners read one line per error; a library's multi-line what() or a
  // path holding a '\n' must not split it, nor a control character garble the terminal.
  std::string line = core::OneLineMessage(message);
  while (!line.empty() && line.back() == ' ') line.pop_back();
  std::cerr << "error: " << line << "\n";
}

int RunGuarded(const std::function<int()>& job) {
  try {
    return job();
  } catch (const UsageError& e) {
    PrintError(e.what());
    return kExitUsage;
  } catch (const core::InputError& e) {
    PrintError(e.what());
    return kExitFailure;
  } catch (const core::OutputError& e) {
    PrintError(e.what());
    return kExitFailure;
  } catch (const std::bad_alloc&) {
    PrintError("out of memory");
    return kExitFailure;
  } catch (const std::exception& e) {
    // A library threw something unexpected (OpenCV, yaml-cpp, filesystem): still one line.
    PrintError(e.what());
    return kExitFailure;
  }
}

int RunHelp(int argc, char** argv) {
  CLI::App app("List the commands, or show one command's options.", "heatwave help");
  std::string name;
  app.add_option("command", name, "the command whose options to show");
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  if (!name.empty()) {
    for (const Command& c : Commands()) {
      if (name != c.name) continue;
      // Every command, help included, shows its options as `heatwave <command> --help` does.
      std::string prog = std::string("heatwave ") + c.name;
      char* args[] = {prog.data(), const_cast<char*>("--help")};
      return c.run(2, args);
    }
    PrintError("unknown command '" + name + "'. Run 'heatwave help' for the list.");
    return kExitUsage;
  }
  std::cout << "heatwave — handheld 3D thermography\n\n"
               "Usage: heatwave <command> [options]\n\nCommands:\n";
  // std::cout, not printf: all output goes through one stream, whose errors main() checks.
  for (const Command& c : Commands()) {
    std::cout << core::StringPrintf("  %-16s %s\n", c.name, c.summary);
  }
  std::cout << "\nRun 'heatwave <command> --help' for a command's options.\n"
               "Exit codes: 0 ok, 1 failure (bad input file, failed check, unwritable output), "
               "2 bad usage.\n";
  return kExitOk;
}

int RunVersion(int argc, char** argv) {
  CLI::App app("Print the version of heatwave.", "heatwave version");
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  std::cout << "heatwave " << HW_VERSION << "\n";
  return kExitOk;
}

const std::vector<std::string>& ScanFolderEntries() {
  static const std::vector<std::string> entries = {
      "rig.yaml",    "depth.txt", "rgb.txt", "thermal.txt", "ffc.txt", "groundtruth.txt",
      "target.yaml", "depth",     "rgb",     "thermal",     "truth"};
  return entries;
}

std::unique_ptr<core::OutputFolder> PrepareOutputFolder(const std::filesystem::path& out, bool overwrite,
                                                        const std::string& description,
                                                        const std::vector<std::string>& entries) {
  std::error_code ec;
  if (std::filesystem::exists(out, ec) && !std::filesystem::is_directory(out, ec)) {
    throw UsageError("--out " + out.string() + ": exists and is not a folder");
  }
  auto folder = std::make_unique<core::OutputFolder>(out, description);
  if (folder->IsEmpty()) return folder;
  if (!overwrite) {
    folder->Abandon();
    throw UsageError("--out " + out.string() + ": folder is not empty; pass --overwrite to replace what is in it");
  }
  folder->Remove(entries);
  return folder;
}

}  // namespace hw::cli
