#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

// CLI11 2.1's string helpers trip GCC 12's -Wnull-dereference (a false positive through
// libstdc++'s inlined std::string): silence it for this third-party header only.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wnull-dereference"
#include <CLI/CLI.hpp>
#pragma GCC diagnostic pop

namespace hw::core {
class OutputFolder;
}

namespace hw::cli {

// Exit codes of every heatwave command.
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;   // the job failed: bad input file, failed check, ...
inline constexpr int kExitUsage = 2;     // bad command line or invalid options

// One entry of the command table: `heatwave <name> ...` calls run(argc, argv) with argv[0]
// set to "heatwave <name>".
struct Command {
  const char* name;
  int (*run)(int argc, char** argv);
  const char* summary;
};

// The command table, in the order `heatwave help` lists it.
const std::vector<Command>& Commands();

// Options every command has.
struct CommonOptions {
  bool quiet = false;  // no progress bar, no summary; errors still go to stderr
};

// Adds --quiet to `app`.
void AddCommonOptions(CLI::App& app, CommonOptions& options);

// Parses argv with `app`. Returns -1 when parsing succeeded and the command should run;
// otherwise the exit code to return: 0 after --help, kExitUsage after a bad command line
// (the message has been printed to stderr with a hint to use --help).
int Parse(CLI::App& app, int argc, char** argv);

// Prints "error: <message>" on stderr as exactly one line, whatever the message holds:
// '\n', '\r' and '\t' become spaces, other control characters '?' (trailing spaces are
// dropped). Every error line of every command goes through here.
void PrintError(std::string_view message);

// Runs `job`, turning the errors of bad inputs and outputs into one clear line on stderr
// ("error: <path>: <reason>", through PrintError) and kExitFailure; a failed options
// Check() message passed as hw::cli::UsageError gives kExitUsage. Returns job's exit code
// otherwise.
int RunGuarded(const std::function<int()>& job);

// Thrown by a command when its options fail their Check(): exit code 2.
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Throws UsageError(prefix + message) when message is not empty (an options Check()).
void ThrowIfInvalid(const std::string& message, const std::string& prefix = "");

// The commands; each parses its options and calls a typed function tests call directly.
// What a scan folder holds (scan-format.md, plus the sessions' target.yaml): what
// --overwrite removes. Anything else in the folder is left alone.
const std::vector<std::string>& ScanFolderEntries();

// Takes the output folder for this run (one run at a time: core/output_folder.h), refuses
// a non-empty one unless overwrite (UsageError), and with overwrite removes `entries` of the
// earlier output — every frame folder whole, indexed or not — so that no stale frame or
// truth file survives. The folder stays marked incomplete until Commit(). `description`
// names the run ("heatwave capture").
std::unique_ptr<core::OutputFolder> PrepareOutputFolder(const std::filesystem::path& out, bool overwrite,
                                                        const std::string& description,
                                                        const std::vector<std::string>& entries = ScanFolderEntries());

int RunHelp(int argc, char** argv);
int RunVersion(int argc, char** argv);
int RunScanInfo(int argc, char** argv);
int RunSynth(int argc, char** argv);
int RunReconstruct(int argc, char** argv);
int RunAnalyze(int argc, char** argv);
int RunCompare(int argc, char** argv);
int RunAudit(int argc, char** argv);
int RunReport(int argc, char** argv);
int RunDemo(int argc, char** argv);
int RunCalibrate(int argc, char** argv);
int RunEvalTrajectory(int argc, char** argv);
int RunDevices(int argc, char** argv);
int RunCapture(int argc, char** argv);
int RunImportOni(int argc, char** argv);

}  // namespace hw::cli
