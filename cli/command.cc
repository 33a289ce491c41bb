#include "cli/command.h"

#include <cstdio>
#include <iostream>

#include "core/error.h"

namespace hw::cli {

const std::vector<Command>& Commands() {
  static const std::vector<Command> commands = {
      {"help", RunHelp, "list the commands, or show one command's options"},
      {"version", RunVersion, "print the version"},
      {"scan-info", RunScanInfo, "validate a scan folder and summarise its streams"},
      {"synth", RunSynth, "render a synthetic scan or calibration session with ground truth"},
  };
  return commands;
}

void AddCommonOptions(CLI::App& app, CommonOptions& options) {
  app.add_flag("-q,--quiet", options.quiet, "no progress bar and no summary");
}

int Parse(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    std::cout << app.help();
    return kExitOk;
  } catch (const CLI::CallForAllHelp&) {
    std::cout << app.help("", CLI::AppFormatMode::All);
    return kExitOk;
  } catch (const CLI::ParseError& e) {
    std::cerr << "error: " << e.what() << "\n"
              << "Run '" << app.get_name() << " --help' for the options.\n";
    return kExitUsage;
  }
  return -1;
}

void ThrowIfInvalid(const std::string& message, const std::string& prefix) {
  if (!message.empty()) throw UsageError(prefix + message);
}

int RunGuarded(const std::function<int()>& job) {
  try {
    return job();
  } catch (const UsageError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitUsage;
  } catch (const core::InputError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitFailure;
  } catch (const core::OutputError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitFailure;
  } catch (const std::bad_alloc&) {
    std::cerr << "error: out of memory\n";
    return kExitFailure;
  } catch (const std::exception& e) {
    // A library threw something unexpected (OpenCV, yaml-cpp, filesystem): still one line.
    std::cerr << "error: " << e.what() << "\n";
    return kExitFailure;
  }
}

int RunHelp(int argc, char** argv) {
  if (argc >= 2) {
    const std::string name = argv[1];
    for (const Command& c : Commands()) {
      if (name == c.name && name != "help") {
        std::string prog = std::string("heatwave ") + c.name;
        char* args[] = {prog.data(), const_cast<char*>("--help")};
        return c.run(2, args);
      }
    }
    std::cerr << "error: unknown command '" << name << "'. Run 'heatwave help' for the list.\n";
    return kExitUsage;
  }
  std::cout << "heatwave — handheld 3D thermography\n\n"
               "Usage: heatwave <command> [options]\n\nCommands:\n";
  for (const Command& c : Commands()) std::printf("  %-12s %s\n", c.name, c.summary);
  std::cout << "\nRun 'heatwave <command> --help' for a command's options.\n"
               "Exit codes: 0 ok, 1 failure (bad input file, failed check), 2 bad usage.\n";
  return kExitOk;
}

int RunVersion(int argc, char** argv) {
  CLI::App app("Print the version of heatwave.", "heatwave version");
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  std::cout << "heatwave " << HW_VERSION << "\n";
  return kExitOk;
}

}  // namespace hw::cli
