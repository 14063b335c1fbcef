#include "xgauge/core/file.h"

#include "xgauge/core/error.h"

#include <fstream>

namespace xgauge {

std::string readFileContents(const std::filesystem::path& path, uint64_t max_bytes,
                             std::string_view what) {
  const SourceLocation where = SourceLocation::inFile(path.string());
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status))
    throw Error(ec && ec != std::errc::no_such_file_or_directory ? "cannot access the file: " + ec.message()
                                                                : "file does not exist",
                where);
  if (std::filesystem::is_directory(status)) throw Error("is a folder, not a file", where);
  if (!std::filesystem::is_regular_file(status))
    throw Error("is not a regular file (a device, pipe or socket)", where);
  const uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) throw Error("cannot read the file size: " + ec.message(), where);
  if (size > max_bytes)
    throw Error(fmt::format("the file holds {} bytes; {} of more than {} bytes is not accepted", size,
                            what, max_bytes),
                where);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("cannot open the file", where);
  std::string bytes(static_cast<size_t>(size), '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(size));
  if (static_cast<uintmax_t>(in.gcount()) != size) throw Error("cannot read the file", where);
  return bytes;
}

}  // namespace xgauge
