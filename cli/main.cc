// heatwave: the single command-line entry point. Dispatches `heatwave <command> ...` to the
// command table of cli/command.cc, then checks for every command, in this one place, that
// its standard output was written.
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <streambuf>
#include <string>

#include "cli/command.h"
#include "core/interrupt.h"

namespace {

// std::cout's buffer in the executable. It forwards to stdio's stdout, as the default
// synchronised buffer does, so std::cout and stdio output keep their order; and it keeps
// the errno of the first failed write. When a write larger than stdio's buffer fails
// mid-run, glibc drops the data and a later fflush succeeds on the empty buffer, so only
// ferror(stdout) would remain, without the reason.
class StdoutBuffer final : public std::streambuf {
 public:
  int first_errno() const { return first_errno_; }

 protected:
  int_type overflow(int_type c) override {
    if (traits_type::eq_int_type(c, traits_type::eof())) return traits_type::not_eof(c);
    const char ch = traits_type::to_char_type(c);
    return xsputn(&ch, 1) == 1 ? c : traits_type::eof();
  }

  std::streamsize xsputn(const char* s, std::streamsize n) override {
    errno = 0;
    const size_t written = std::fwrite(s, 1, static_cast<size_t>(n), stdout);
    if (written < static_cast<size_t>(n)) Record();
    return static_cast<std::streamsize>(written);
  }

  int sync() override {
    errno = 0;
    if (std::fflush(stdout) == 0) return 0;
    Record();
    return -1;
  }

 private:
  void Record() {
    if (first_errno_ == 0) first_errno_ = errno != 0 ? errno : EIO;
  }

  int first_errno_ = 0;
};

int Dispatch(int argc, char** argv) {
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) {
    const int code = hw::cli::RunHelp(1, argv);
    return argc < 2 && code == hw::cli::kExitOk ? hw::cli::kExitUsage : code;
  }
  if (std::strcmp(argv[1], "--version") == 0) return hw::cli::RunVersion(1, argv);
  const std::string name = argv[1];
  for (const auto& command : hw::cli::Commands()) {
    if (name == command.name) {
      std::string prog = "heatwave " + name;
      argv[1] = prog.data();
      return command.run(argc - 1, argv + 1);
    }
  }
  hw::cli::PrintError("unknown command '" + name + "'. Run 'heatwave help' for the list.");
  return hw::cli::kExitUsage;
}

// Output lost to a full disk, a closed descriptor or a failing pipe reader must not pass for
// success: a command that otherwise succeeded exits 1 with one line naming the reason. A
// command that already failed keeps its own exit code and error line (one line per error).
int CheckStandardOutput(int code, const StdoutBuffer& buffer) {
  std::cout.flush();
  errno = 0;
  const bool flush_failed = std::fflush(stdout) != 0;  // stdio output besides std::cout
  const int flush_errno = errno;
  if (std::cout.good() && !flush_failed && !std::ferror(stdout)) return code;
  if (code != hw::cli::kExitOk) return code;
  int error = buffer.first_errno();
  if (error == 0) error = flush_failed && flush_errno != 0 ? flush_errno : EIO;
  hw::cli::PrintError(std::string("cannot write standard output: ") + std::strerror(error));
  return hw::cli::kExitFailure;
}

}  // namespace

int main(int argc, char** argv) {
  // SIGINT/SIGTERM remove the temporaries of files being written; SIGXFSZ is ignored so that
  // a file size limit is a write error, not a core dump.
  hw::core::InstallInterruptHandlers();
  // Never deleted: std::cout is flushed once more at exit, after main's locals are gone.
  auto* const buffer = new StdoutBuffer;
  std::cout.rdbuf(buffer);
  return CheckStandardOutput(Dispatch(argc, argv), *buffer);
}
