// heatwave: the single command-line entry point. Dispatches `heatwave <command> ...` to the
// command table of cli/command.cc.
#include <cstring>
#include <iostream>
#include <string>

#include "cli/command.h"

int main(int argc, char** argv) {
  using hw::cli::Commands;
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) {
    hw::cli::RunHelp(1, argv);
    return argc < 2 ? hw::cli::kExitUsage : hw::cli::kExitOk;
  }
  if (std::strcmp(argv[1], "--version") == 0) return hw::cli::RunVersion(1, argv);
  const std::string name = argv[1];
  for (const auto& command : Commands()) {
    if (name == command.name) {
      std::string prog = "heatwave " + name;
      argv[1] = prog.data();
      return command.run(argc - 1, argv + 1);
    }
  }
  std::cerr << "error: unknown command '" << name << "'. Run 'heatwave help' for the list.\n";
  return hw::cli::kExitUsage;
}
