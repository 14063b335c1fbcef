// xgauge's process settings, for a program that runs the front door's calls
// (xgauge/xgauge.h and beside it) as the CLI does: the messages' verbosity,
// progress bars, worker threads and the largest radiograph read. Needs only
// the C++ standard library.
//
//   int main(int argc, char** argv) {
//     xgauge::PrepareProcess();  // first, before any thread
//     ...parse arguments...
//     xgauge::RuntimeOptions runtime;
//     runtime.threads = 4;
//     const xgauge::RuntimeScope scope(runtime);
//     ...front door calls...
//   }
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace xgauge {

// How a front door call other than measure and calibrate ended.
enum class RunTermination {
  kDone,     // the outputs are written (the summary says what)
  kFailure,  // the inputs could not be used, or an output not written: message says why
};
const char* RunTerminationToString(RunTermination type);  // "done", "failure"

// Once, first thing in main, before any worker thread exists and before the
// work allocates: an interrupted run (Ctrl-C, SIGTERM) removes the outputs
// it had not finished, and large image buffers stay in the heap.
void PrepareProcess();

enum class LogLevel {
  kQuiet,    // errors only (a result's warnings stay in its result.json and report)
  kNormal,   // also what each step did
  kVerbose,  // also debug messages
};

// The default of RuntimeOptions::max_image_bytes: what a 16384 x 16384
// radiograph needs (1088 MiB).
inline constexpr std::uint64_t kDefaultMaxImageBytes =
    std::uint64_t{16384} * 16384 * 4 + (std::uint64_t{64} << 20);

struct RuntimeOptions {
  LogLevel log_level = LogLevel::kNormal;  // the messages on stderr
  bool progress = true;                    // progress bars (on a terminal only)
  int threads = 0;                         // worker threads; 0: every core
  // Radiograph files (any format) that would need more memory than this to
  // read are refused.
  std::uint64_t max_image_bytes = kDefaultMaxImageBytes;
};

// Applies the options while it lives (the thread count until it ends; the
// rest stay set). One at a time per process.
class RuntimeScope {
 public:
  explicit RuntimeScope(const RuntimeOptions& options);
  ~RuntimeScope();
  RuntimeScope(const RuntimeScope&) = delete;
  RuntimeScope& operator=(const RuntimeScope&) = delete;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// A message on stderr beside the library's own, in their format.
enum class Severity { kInfo, kWarning, kError };
void LogMessage(Severity severity, const std::string& message);

// The name of `known` nearest to a misspelled `name` (a swap of neighbours
// counting as one edit), within two edits; "" when none is that near. The
// library's own "did you mean" for keys, offered to a caller's names
// (commands, options).
std::string NearestName(const std::string& name, const std::vector<std::string>& known);

}  // namespace xgauge
