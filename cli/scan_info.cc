#include "cli/command.h"
namespace hw::cli {
// placeholder: being written
int RunScanInfo(int, char**) { return kExitFailure; }
}  // namespace hw::cli
