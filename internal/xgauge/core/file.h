// Reading a whole input file into memory, with the checks a hostile path
// needs first: it must be a regular file (not /dev/zero, a FIFO or a
// folder) no larger than the caller's limit.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace xgauge {

// The file's bytes. Throws Error naming the file when it is missing, not a
// regular file, larger than `max_bytes` (saying so, with `what`, e.g. "a JSON
// file"), or cannot be read.
std::string readFileContents(const std::filesystem::path& path, uint64_t max_bytes,
                             std::string_view what);

}  // namespace xgauge
