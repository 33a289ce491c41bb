// `heatwave calibrate bench` end to end on a bench session (fixtures/bench_session.h): the
// wall time of the whole run and of its part after the target detection (the issue's
// figure: a 20-view bench run completes in under 5 s after detection), per part, best of
// --repeat runs, plus the CPU time of the process.
//
//   bench_calibrate_bench_speed --session DIR [--render] [--views 20] [--repeat 3] [--out DIR]
//
// --render: synthesize the full-size bench session (20 views per target part: 640 x 480
// colour, 320 x 240 thermal; 90 depth stills of a wall; 6 s latency recording) into
// --session first (minutes).
// Outputs go to --out (default: <session>-bench-out), replaced on every run.

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "bench/bench_timing.h"
#include "cli/calibrate_bench.h"
#include "fixtures/bench_session.h"

namespace {

namespace fs = std::filesystem;

[[noreturn]] void Usage(const char* message) {
  std::fprintf(stderr, "%s\nusage: bench_calibrate_bench_speed --session DIR [--render] [--views 20] [--repeat 3] [--out DIR]\n",
               message);
  std::exit(2);
}

}  // namespace

int main(int argc, char** argv) {
  fs::path session, out;
  bool render = false;
  int views = 20, repeat = 3;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) Usage(("missing value after " + a).c_str());
      return argv[++i];
    };
    if (a == "--session") session = next();
    else if (a == "--out") out = next();
    else if (a == "--render") render = true;
    else if (a == "--views") views = std::atoi(next().c_str());
    else if (a == "--repeat") repeat = std::atoi(next().c_str());
    else Usage(("unknown argument " + a).c_str());
  }
  if (session.empty()) Usage("--session is required");
  if (repeat < 1) Usage("--repeat: must be >= 1");
  if (out.empty()) out = session.string() + "-bench-out";
  if (render) {
    hw::fixtures::BenchSessionOptions o = hw::fixtures::BenchSessionOptions::Preset(false);
    o.views = views;
    if (const std::string problem = o.Check(); !problem.empty()) Usage(problem.c_str());
    const hw::fixtures::BenchSessionSummary s = hw::fixtures::SynthesizeBenchSession(o, session);
    std::printf("rendered %s in %.1f s\n", session.c_str(), s.seconds);
  }
  double best_total = 1e300, best_after = 1e300;
  for (int r = 0; r < repeat; ++r) {
    hw::cli::BenchCommandOptions o;
    o.session = session;
    o.out_folder = out;
    o.overwrite = true;
    const double cpu0 = hw::bench::CpuMs();
    const hw::cli::BenchResult result = hw::cli::RunBench(o, true);
    const double cpu = (hw::bench::CpuMs() - cpu0) / 1e3;
    std::printf("run %d: %s, total %.2f s, detection %.2f s, after detection %.2f s (CPU %.2f s)\n", r + 1,
                result.certificate.verdict.c_str(), result.seconds, result.detect_seconds,
                result.seconds - result.detect_seconds, cpu);
    for (const hw::report::CertificatePart& p : result.certificate.parts) {
      std::printf("  %-20s %-7s %.2f s\n", p.id.c_str(), hw::report::PartStatusName(p.status).c_str(), p.seconds);
    }
    best_total = std::min(best_total, result.seconds);
    best_after = std::min(best_after, result.seconds - result.detect_seconds);
  }
  std::printf("best of %d: total %.2f s, after detection %.2f s (target < 5 s)\n", repeat, best_total, best_after);
  return 0;
}
