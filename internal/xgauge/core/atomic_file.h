// Atomic output files: write to a temporary file in the target's folder, then
// rename it into place. A reader never sees a half-written file, and a failure
// (an exception before commit()) leaves no output file behind.
#pragma once

#include <filesystem>
#include <string_view>

namespace xgauge {

class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path target);
  ~AtomicFile();  // removes the temporary file unless committed
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  // Where to write; lives next to the target.
  const std::filesystem::path& tempPath() const { return temp_; }
  const std::filesystem::path& target() const { return target_; }
  // Renames the temporary file onto the target. Throws Error on failure.
  void commit();

 private:
  std::filesystem::path target_;
  std::filesystem::path temp_;
  bool committed_ = false;
};

// Writes `contents` to `path` through an AtomicFile.
void writeFileAtomically(const std::filesystem::path& path, std::string_view contents);

}  // namespace xgauge
