#include "xgauge/core/atomic_file.h"

#include "xgauge/core/error.h"
#include "xgauge/core/output.h"

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <unistd.h>

namespace xgauge {

AtomicFile::AtomicFile(std::filesystem::path target) : target_(std::move(target)) {
  static std::atomic<unsigned> counter{0};
  const auto folder = target_.has_parent_path() ? target_.parent_path() : ".";
  if (!std::filesystem::is_directory(folder))
    throw Error("output folder does not exist", SourceLocation::inFile(folder.string()));
  temp_ = folder / fmt::format(".{}.{}.{}.tmp", target_.filename().string(), ::getpid(),
                               counter.fetch_add(1));
  registerTemporary(temp_);
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    std::error_code ignored;
    std::filesystem::remove(temp_, ignored);
    unregisterTemporary(temp_);
  }
}

void AtomicFile::commit() {
  if (OutputTransaction::holdBack(temp_, target_)) {
    committed_ = true;
    return;
  }
  std::error_code ec;
  std::filesystem::rename(temp_, target_, ec);
  if (ec)
    throw Error(fmt::format("cannot move finished file into place: {}", ec.message()),
                SourceLocation::inFile(target_.string()));
  unregisterTemporary(temp_);
  committed_ = true;
}

void writeFileAtomically(const std::filesystem::path& path, std::string_view contents) {
  AtomicFile file(path);
  {
    std::ofstream out(file.tempPath(), std::ios::binary | std::ios::trunc);
    if (!out)
      throw Error(fmt::format("cannot create the file: {}", std::strerror(errno)),
                  SourceLocation::inFile(path.string()));
    out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
    out.flush();
    if (!out)
      throw Error(fmt::format("cannot write the file: {}", std::strerror(errno)),
                  SourceLocation::inFile(path.string()));
  }
  file.commit();
}

}  // namespace xgauge
