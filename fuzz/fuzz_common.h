// Helpers shared by the libFuzzer targets in this folder (see docs/fuzzing.md).
//
// The readers under test take a path, so each input is written to a file in a
// per-process scratch folder: xgauge-fuzz-<pid> under $XGAUGE_FUZZ_TMP if set
// (scripts/fuzz.sh sets it and removes it afterwards), else under /dev/shm
// when present, else /tmp. The pid keeps parallel or forked fuzzers apart. The
// folder is removed at a normal exit (a crash leaves it behind).
//
// Only xgauge::Error is an expected outcome of bad input. Any other exception
// is left to escape LLVMFuzzerTestOneInput: std::terminate then aborts inside
// the throw, so libFuzzer reports a crash whose stack shows where it was thrown
// (and libstdc++ prints its type and what()). fuzzAssert() aborts on a broken
// promise of a public header (a reader returned something it documents it
// never returns).
#pragma once

#include <spdlog/spdlog.h>

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

namespace xgauge_fuzz {

inline const std::filesystem::path& scratchDir() {
  // Never destroyed, so the atexit handler can still use it.
  static const std::filesystem::path* const dir = [] {
    std::error_code ec;
    const char* chosen = std::getenv("XGAUGE_FUZZ_TMP");
    const std::filesystem::path base = chosen && *chosen ? std::filesystem::path(chosen)
                                       : std::filesystem::is_directory("/dev/shm", ec)
                                           ? std::filesystem::path("/dev/shm")
                                           : std::filesystem::path("/tmp");
    auto* made = new std::filesystem::path(base / ("xgauge-fuzz-" + std::to_string(::getpid())));
    std::filesystem::create_directories(*made);
    std::atexit([] {
      std::error_code ignored;
      std::filesystem::remove_all(scratchDir(), ignored);
    });
    return made;
  }();
  return *dir;
}

// Writes `data` to scratchDir()/name and returns the path.
inline std::filesystem::path writeScratch(const std::string& name, const uint8_t* data,
                                          size_t size) {
  const std::filesystem::path path = scratchDir() / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  out.close();
  if (!out) {
    std::fprintf(stderr, "fuzz harness: cannot write %s\n", path.c_str());
    std::abort();
  }
  return path;
}

// Warnings (dropped triangles, flipped meshes, ...) would flood the output.
inline void quietLogging() { spdlog::set_level(spdlog::level::off); }

#define FUZZ_ASSERT(cond, what)                                                     \
  do {                                                                              \
    if (!(cond)) {                                                                  \
      std::fprintf(stderr, "fuzz harness: broken promise: %s (%s) at %s:%d\n", what, \
                   #cond, __FILE__, __LINE__);                                      \
      std::abort();                                                                 \
    }                                                                               \
  } while (false)

}  // namespace xgauge_fuzz
