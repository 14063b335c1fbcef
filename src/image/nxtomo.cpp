#include "xgauge/image/nxtomo.h"

#include "frames.h"
#include "xgauge/core/atomic_file.h"
#include "xgauge/core/digest.h"
#include "xgauge/core/error.h"

#include <hdf5.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cstdio>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <mutex>
#include <optional>
#include <vector>

namespace xgauge {
namespace {

namespace fs = std::filesystem;

constexpr const char* kDataPath = "/entry/data/data";
constexpr const char* kDetectorDataPath = "/entry/instrument/detector/data";
constexpr const char* kImageKeyPath = "/entry/instrument/detector/image_key";
constexpr const char* kAnglePath = "/entry/sample/rotation_angle";
constexpr double kAngleTolerance = 1e-6;

// libhdf5 is called from one thread at a time: Debian builds it thread-safe,
// but a build without that option would not be, and reads are not the hot
// path.
std::mutex& hdf5Mutex() {
  static std::mutex mutex;
  return mutex;
}

// An HDF5 identifier closed by `close` when it goes out of scope.
template <herr_t (*close)(hid_t)>
class Handle {
 public:
  explicit Handle(hid_t id = H5I_INVALID_HID) : id_(id) {}
  ~Handle() {
    if (id_ >= 0) close(id_);
  }
  Handle(Handle&& other) noexcept : id_(other.id_) { other.id_ = H5I_INVALID_HID; }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  Handle& operator=(Handle&&) = delete;
  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }

 private:
  hid_t id_;
};
using File = Handle<H5Fclose>;
using Dataset = Handle<H5Dclose>;
using Space = Handle<H5Sclose>;
using Type = Handle<H5Tclose>;
using Group = Handle<H5Gclose>;
using Attribute = Handle<H5Aclose>;
using PropertyList = Handle<H5Pclose>;

herr_t collectMessage(unsigned n, const H5E_error2_t* error, void* data) {
  auto& text = *static_cast<std::string*>(data);
  if (n < 3 && error->desc != nullptr) {
    if (!text.empty()) text += "; ";
    text += error->desc;
  }
  return 0;
}

// " (libhdf5: ...)" from the current thread's error stack, which it clears;
// or nothing.
std::string hdf5Says() {
  std::string text;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, collectMessage, &text);
  H5Eclear2(H5E_DEFAULT);
  return text.empty() ? std::string() : " (libhdf5: " + text + ")";
}

// Whether every link of `path` exists (H5Lexists needs the parents).
bool pathExists(hid_t file, const std::string& path) {
  for (size_t slash = path.find('/', 1);; slash = path.find('/', slash + 1)) {
    const std::string prefix = path.substr(0, slash);
    if (H5Lexists(file, prefix.c_str(), H5P_DEFAULT) <= 0) return false;
    if (slash == std::string::npos) return true;
    if (H5Oexists_by_name(file, prefix.c_str(), H5P_DEFAULT) <= 0) return false;
  }
}

struct Selection {
  enum Kind { kOnlyProjection, kProjection, kAngle, kDark, kFlat } kind = kOnlyProjection;
  int64_t index = 0;
  double angle = 0.0;
  std::string text;
};

Selection parseSelector(std::string_view selector, const SourceLocation& where) {
  Selection s;
  s.text = std::string(selector);
  if (selector.empty()) return s;
  if (selector == "dark") return s.kind = Selection::kDark, s;
  if (selector == "flat") return s.kind = Selection::kFlat, s;
  const auto value_of = [&](std::string_view key) -> std::optional<std::string_view> {
    if (selector.substr(0, key.size()) == key) return selector.substr(key.size());
    return std::nullopt;
  };
  if (const auto value = value_of("projection=")) {
    const auto [end, error] =
        std::from_chars(value->data(), value->data() + value->size(), s.index);
    if (error != std::errc() || end != value->data() + value->size() || s.index < 0)
      failAt(where, "#{}: expected projection=N with N a whole number from 0", selector);
    return s.kind = Selection::kProjection, s;
  }
  if (const auto value = value_of("angle=")) {
    const auto [end, error] =
        std::from_chars(value->data(), value->data() + value->size(), s.angle);
    if (error != std::errc() || end != value->data() + value->size() || !std::isfinite(s.angle))
      failAt(where, "#{}: expected angle=A with A a number", selector);
    return s.kind = Selection::kAngle, s;
  }
  failAt(where, "unknown frame selector '#{}': projection=N, angle=A, dark or flat", selector);
}

Dataset openDataset(hid_t file, const std::string& path, const SourceLocation& where) {
  if (!pathExists(file, path)) {
    H5Eclear2(H5E_DEFAULT);
    failAt(where, "no dataset {}: an NXtomo file holds {}, {} and {}", path, kDataPath,
           kImageKeyPath, kAnglePath);
  }
  Dataset dataset(H5Dopen2(file, path.c_str(), H5P_DEFAULT));
  if (!dataset.valid()) failAt(where, "{} is not a readable dataset{}", path, hdf5Says());
  return dataset;
}

// The dataset's dimensions; refuses another rank.
std::vector<hsize_t> dimensionsOf(hid_t dataset, int rank, const std::string& path,
                                  const SourceLocation& where) {
  const Space space(H5Dget_space(dataset));
  if (!space.valid()) failAt(where, "{}: no dataspace{}", path, hdf5Says());
  const int got = H5Sget_simple_extent_ndims(space.get());
  if (got != rank)
    failAt(where, "{} has {} dimensions; expected {}", path, got < 0 ? 0 : got, rank);
  std::vector<hsize_t> dims(static_cast<size_t>(rank));
  if (H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr) != rank)
    failAt(where, "{}: cannot read its dimensions{}", path, hdf5Says());
  return dims;
}

enum class Sample { kUInt8, kUInt16, kUInt32, kFloat32, kFloat64 };

Sample sampleOf(hid_t dataset, const SourceLocation& where) {
  const Type type(H5Dget_type(dataset));
  if (!type.valid()) failAt(where, "{}: no type{}", kDataPath, hdf5Says());
  const H5T_class_t type_class = H5Tget_class(type.get());
  const size_t size = H5Tget_size(type.get());
  if (type_class == H5T_INTEGER && H5Tget_sign(type.get()) == H5T_SGN_NONE) {
    if (size == 1) return Sample::kUInt8;
    if (size == 2) return Sample::kUInt16;
    if (size == 4) return Sample::kUInt32;
  }
  if (type_class == H5T_FLOAT && size == 4) return Sample::kFloat32;
  if (type_class == H5T_FLOAT && size == 8) return Sample::kFloat64;
  const char* kind =
      type_class == H5T_INTEGER
          ? (H5Tget_sign(type.get()) == H5T_SGN_NONE ? "unsigned integer" : "signed integer")
      : type_class == H5T_FLOAT ? "float"
                                : "non-numeric";
  failAt(where,
         "{} holds {}-byte {} samples (supported: 8-, 16- or 32-bit unsigned integer, 32- or "
         "64-bit float)",
         kDataPath, size, kind);
}

hid_t memoryType(Sample sample) {
  switch (sample) {
    case Sample::kUInt8:
      return H5T_NATIVE_UINT8;
    case Sample::kUInt16:
      return H5T_NATIVE_UINT16;
    case Sample::kUInt32:
      return H5T_NATIVE_UINT32;
    case Sample::kFloat32:
      return H5T_NATIVE_FLOAT;
    case Sample::kFloat64:
      return H5T_NATIVE_DOUBLE;
  }
  return H5T_NATIVE_FLOAT;
}

size_t bytesOf(Sample sample) {
  switch (sample) {
    case Sample::kUInt8:
      return 1;
    case Sample::kUInt16:
      return 2;
    case Sample::kUInt32:
    case Sample::kFloat32:
      return 4;
    case Sample::kFloat64:
      return 8;
  }
  return 4;
}

// A one-dimensional dataset of `frames` values, read as `memory_type`.
template <typename T>
std::vector<T> readVector(hid_t file, const std::string& path, hsize_t frames, hid_t memory_type,
                          const SourceLocation& where) {
  const Dataset dataset = openDataset(file, path, where);
  const auto dims = dimensionsOf(dataset.get(), 1, path, where);
  if (dims[0] != frames)
    failAt(where, "{} holds {} values but {} holds {} frames: one value per frame", path, dims[0],
           kDataPath, frames);
  const Type type(H5Dget_type(dataset.get()));
  const H5T_class_t type_class = type.valid() ? H5Tget_class(type.get()) : H5T_NO_CLASS;
  if (type_class != H5T_INTEGER && type_class != H5T_FLOAT)
    failAt(where, "{} holds non-numeric values", path);
  std::vector<T> values(static_cast<size_t>(frames));
  if (H5Dread(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0)
    failAt(where, "cannot read {}{}", path, hdf5Says());
  return values;
}

// The frames `selection` names, in file order.
std::vector<hsize_t> selectFrames(hid_t file, const Selection& selection, hsize_t frames,
                                  uint64_t memory_limit, const SourceLocation& where) {
  if (frames > memory_limit / sizeof(int))
    failAt(where, "{} declares {} frames: their image keys alone exceed the memory limit",
           kDataPath, frames);
  const std::vector<int> keys = readVector<int>(file, kImageKeyPath, frames, H5T_NATIVE_INT, where);
  std::vector<hsize_t> projections, flats, darks;
  for (hsize_t i = 0; i < frames; ++i) {
    const int key = keys[static_cast<size_t>(i)];
    if (key == 0) projections.push_back(i);
    if (key == 1) flats.push_back(i);
    if (key == 2) darks.push_back(i);
    if (key < 0 || key > 3)
      failAt(where, "{}[{}] = {}: expected 0 (projection), 1 (flat), 2 (dark) or 3 (invalid)",
             kImageKeyPath, i, key);
  }
  const std::string holds =
      fmt::format("the file holds {} projection(s), {} flat(s) and {} dark(s)", projections.size(),
                  flats.size(), darks.size());
  switch (selection.kind) {
    case Selection::kOnlyProjection:
      if (projections.size() != 1)
        failAt(where, "{}: name one with #projection=N, #angle=A, #dark or #flat", holds);
      return projections;
    case Selection::kProjection:
      if (static_cast<uint64_t>(selection.index) >= projections.size())
        failAt(where, "#{}: {} (counted from 0)", selection.text, holds);
      return {projections[static_cast<size_t>(selection.index)]};
    case Selection::kDark:
      if (darks.empty()) failAt(where, "#dark: {}", holds);
      return darks;
    case Selection::kFlat:
      if (flats.empty()) failAt(where, "#flat: {}", holds);
      return flats;
    case Selection::kAngle: {
      const std::vector<double> angles =
          readVector<double>(file, kAnglePath, frames, H5T_NATIVE_DOUBLE, where);
      std::vector<hsize_t> found;
      for (hsize_t i : projections)
        if (std::abs(angles[static_cast<size_t>(i)] - selection.angle) <= kAngleTolerance)
          found.push_back(i);
      if (found.empty())
        failAt(where, "#{}: no projection at rotation angle {} ({})", selection.text,
               selection.angle, holds);
      if (found.size() > 1)
        failAt(where,
               "#{}: {} projections (frames {} and {}) at rotation angle {}: use "
               "#projection=N",
               selection.text, found.size(), found[0], found[1], selection.angle);
      return found;
    }
  }
  return {};
}

template <typename T>
Image readFrame(hid_t dataset, hid_t file_space, hsize_t frame, hsize_t rows, hsize_t columns,
                std::vector<unsigned char>& buffer, const std::string& label,
                const SourceLocation& where) {
  const hsize_t start[3] = {frame, 0, 0}, count[3] = {1, rows, columns};
  if (H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, count, nullptr) < 0)
    failAt(where, "cannot select frame {}{}", frame, hdf5Says());
  const hsize_t memory_dims[2] = {rows, columns};
  const Space memory_space(H5Screate_simple(2, memory_dims, nullptr));
  if (H5Dread(dataset,
              memoryType(std::is_same_v<T, uint8_t>    ? Sample::kUInt8
                         : std::is_same_v<T, uint16_t> ? Sample::kUInt16
                         : std::is_same_v<T, uint32_t> ? Sample::kUInt32
                         : std::is_same_v<T, float>    ? Sample::kFloat32
                                                       : Sample::kFloat64),
              memory_space.get(), file_space, H5P_DEFAULT, buffer.data()) < 0)
    failAt(where, "cannot read frame {} of {}{}", frame, kDataPath, hdf5Says());
  const int w = static_cast<int>(columns), h = static_cast<int>(rows);
  Image image(w, h);
  frames::SampleConverter<T> converter;
  converter.frame_label = label;
  for (int y = 0; y < h; ++y)
    converter.convert(buffer.data() + size_t(y) * size_t(w) * sizeof(T), image.row(y), w, 0, y, w);
  converter.check(where);
  return image;
}

struct FileIdentity {
  dev_t device = 0;
  ino_t inode = 0;
  off_t size = 0;
  timespec modified{};
  bool operator==(const FileIdentity& o) const {
    return device == o.device && inode == o.inode && size == o.size &&
           modified.tv_sec == o.modified.tv_sec && modified.tv_nsec == o.modified.tv_nsec;
  }
};

FileIdentity identityOf(const fs::path& path, const SourceLocation& where) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0)
    failAt(where, "cannot access the file: {}", std::strerror(errno));
  return {info.st_dev, info.st_ino, info.st_size, info.st_mtim};
}

std::string fileDigest(const fs::path& path, const SourceLocation& where) {
  std::ifstream in(path, std::ios::binary);
  if (!in) failAt(where, "cannot open the file: {}", std::strerror(errno));
  Sha256 hash;
  std::vector<char> buffer(size_t{1} << 20);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    if (in.gcount() > 0) hash.update(buffer.data(), static_cast<size_t>(in.gcount()));
  }
  if (in.bad()) failAt(where, "cannot read the file");
  return hash.hex();
}

}  // namespace

Image readNxTomoInProcess(const fs::path& path, std::string_view selector, std::string* sha256,
                          const ExpectedImageSize* expected, int* frames_averaged, bool lock) {
  const SourceLocation where = SourceLocation::inFile(
      selector.empty() ? path.string() : path.string() + "#" + std::string(selector));
  const Selection selection = parseSelector(selector, where);
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) failAt(where, "file does not exist or is not a file");
  const FileIdentity before = identityOf(path, where);
  std::string digest;
  if (sha256) digest = fileDigest(path, where);

  std::unique_lock<std::mutex> guard(hdf5Mutex(), std::defer_lock);
  if (lock) guard.lock();
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // nothing printed; messages go into errors
  H5Eclear2(H5E_DEFAULT);
  if (H5Fis_hdf5(path.c_str()) <= 0) failAt(where, "not an HDF5 file{}", hdf5Says());
  const File file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT));
  if (!file.valid()) failAt(where, "cannot open the HDF5 file{}", hdf5Says());

  const Dataset data = openDataset(file.get(), kDataPath, where);
  const auto dims = dimensionsOf(data.get(), 3, kDataPath, where);
  const hsize_t frames = dims[0], rows = dims[1], columns = dims[2];
  if (frames == 0 || rows == 0 || columns == 0)
    failAt(where, "{} is empty ({} x {} x {})", kDataPath, frames, rows, columns);
  if (rows > uint64_t{std::numeric_limits<int>::max()} ||
      columns > uint64_t{std::numeric_limits<int>::max()})
    failAt(where, "{} declares frames of {}x{} pixels: too large", kDataPath, columns, rows);
  if (expected && (columns != uint64_t(expected->width) || rows != uint64_t(expected->height)))
    failAt(where, "is {}x{} pixels but {} is {}x{}", columns, rows, expected->what, expected->width,
           expected->height);
  const Sample sample = sampleOf(data.get(), where);
  const size_t sample_bytes = bytesOf(sample);

  // What the file stores must be able to hold what it declares.
  const double declared_bytes = static_cast<double>(frames) * static_cast<double>(rows) *
                                static_cast<double>(columns) * static_cast<double>(sample_bytes);
  const double stored_bytes = static_cast<double>(H5Dget_storage_size(data.get()));
  const PropertyList creation(H5Dget_create_plist(data.get()));
  const bool filtered = creation.valid() && H5Pget_nfilters(creation.get()) > 0;
  H5Eclear2(H5E_DEFAULT);
  // As for TIFF: no codec packs a noisy radiograph 4096-fold.
  const double expansion = filtered ? 4096.0 : 1.0;
  const auto file_bytes = static_cast<double>(before.size);
  if (stored_bytes > file_bytes || declared_bytes > expansion * stored_bytes)
    failAt(where,
           "{} declares {} x {} x {} samples of {} bytes but stores {:.0f} bytes: it was never "
           "written, is truncated or corrupt",
           kDataPath, frames, rows, columns, sample_bytes, stored_bytes);

  const std::vector<hsize_t> chosen =
      selectFrames(file.get(), selection, frames, tiffMemoryLimit(), where);
  // First without the buffer, so that its size below cannot overflow.
  frames::checkMemory(where, columns, rows, chosen.size(), 0);
  frames::checkMemory(where, columns, rows, chosen.size(), rows * columns * sample_bytes);

  const Space file_space(H5Dget_space(data.get()));
  std::vector<unsigned char> buffer(static_cast<size_t>(rows * columns * sample_bytes));
  frames::FrameMean mean;
  for (hsize_t frame : chosen) {
    const std::string label =
        chosen.size() > 1 ? fmt::format(" of frame {} ({})", frame, selection.text) : "";
    const hid_t d = data.get(), s = file_space.get();
    switch (sample) {
      case Sample::kUInt8:
        mean.add(readFrame<uint8_t>(d, s, frame, rows, columns, buffer, label, where));
        break;
      case Sample::kUInt16:
        mean.add(readFrame<uint16_t>(d, s, frame, rows, columns, buffer, label, where));
        break;
      case Sample::kUInt32:
        mean.add(readFrame<uint32_t>(d, s, frame, rows, columns, buffer, label, where));
        break;
      case Sample::kFloat32:
        mean.add(readFrame<float>(d, s, frame, rows, columns, buffer, label, where));
        break;
      case Sample::kFloat64:
        mean.add(readFrame<double>(d, s, frame, rows, columns, buffer, label, where));
        break;
    }
  }
  if (sha256) {
    if (!(identityOf(path, where) == before))
      failAt(where, "the file changed while it was read; read it again");
    *sha256 = digest;
  }
  if (frames_averaged) *frames_averaged = mean.count();
  return mean.take();
}

namespace {

// The child's answer on the pipe: a status byte, then the error's text, or
// the digest, the frame count, the size and the pixels.
bool writeAll(int fd, const void* data, size_t size) {
  const auto* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n, size -= static_cast<size_t>(n);
  }
  return true;
}
bool readAll(int fd, void* data, size_t size) {
  auto* p = static_cast<char*>(data);
  while (size > 0) {
    const ssize_t n = ::read(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n, size -= static_cast<size_t>(n);
  }
  return true;
}
template <typename T>
bool writeValue(int fd, const T& v) {
  return writeAll(fd, &v, sizeof v);
}
bool writeString(int fd, const std::string& text) {
  return writeValue(fd, uint64_t{text.size()}) && writeAll(fd, text.data(), text.size());
}
bool readString(int fd, std::string& text, uint64_t limit) {
  uint64_t n = 0;
  if (!readAll(fd, &n, sizeof n) || n > limit) return false;
  text.resize(static_cast<size_t>(n));
  return readAll(fd, text.data(), text.size());
}

[[noreturn]] void childReads(int fd, const fs::path& path, std::string_view selector, bool digest,
                             const ExpectedImageSize* expected) {
  try {
    std::string sha;
    int frames = 0;
    const Image image =
        readNxTomoInProcess(path, selector, digest ? &sha : nullptr, expected, &frames, false);
    const bool ok = writeValue(fd, char{1}) && writeString(fd, sha) && writeValue(fd, frames) &&
                    writeValue(fd, image.width()) && writeValue(fd, image.height()) &&
                    writeAll(fd, image.pixels().data(), image.size() * sizeof(float));
    ::_exit(ok ? 0 : 3);
  } catch (const Error& e) {
    ::_exit(writeValue(fd, char{0}) && writeString(fd, e.what()) ? 0 : 3);
  } catch (...) {
    ::_exit(4);
  }
}

// The child's address space capped at what it has (the parent's, copied on
// write) plus the largest image a read may return and a margin for
// libhdf5's own metadata: a crafted header that declares a 2 GB metadata
// block (scripts/fuzz.sh found one) then fails its malloc, which libhdf5
// reports, instead of growing the process.
void capChildMemory() {
  long pages = 0;
  if (std::FILE* statm = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(statm, "%ld", &pages) != 1) pages = 0;
    std::fclose(statm);
  }
  if (pages <= 0) return;
  constexpr uint64_t kMetadataMargin = uint64_t{256} << 20;
  const uint64_t now =
      static_cast<uint64_t>(pages) * static_cast<uint64_t>(::sysconf(_SC_PAGESIZE));
  const rlimit cap{now + tiffMemoryLimit() + kMetadataMargin,
                   now + tiffMemoryLimit() + kMetadataMargin};
  ::setrlimit(RLIMIT_AS, &cap);
}

}  // namespace

// libhdf5 1.10 (Debian 12) can crash on a crafted file (scripts/fuzz.sh
// found a null write in H5G__stab_lookup) before any check of ours can
// refuse it, so the file is read in a child process: a crash there is the
// file's error, not the program's end. No maintained library offers this
// isolation for libhdf5; it costs one fork per NXtomo read.
Image readNxTomo(const fs::path& path, std::string_view selector, std::string* sha256,
                 const ExpectedImageSize* expected, int* frames_averaged) {
  const SourceLocation where = SourceLocation::inFile(
      selector.empty() ? path.string() : path.string() + "#" + std::string(selector));
  // No other thread is inside libhdf5 while the child is made, and none
  // holds the lock the child would need.
  const std::lock_guard lock(hdf5Mutex());
  int fds[2];
  if (::pipe(fds) != 0) failAt(where, "cannot read the file: pipe: {}", std::strerror(errno));
  const pid_t child = ::fork();
  if (child < 0) {
    ::close(fds[0]), ::close(fds[1]);
    failAt(where, "cannot read the file: fork: {}", std::strerror(errno));
  }
  if (child == 0) {
    ::close(fds[0]);
    capChildMemory();
    childReads(fds[1], path, selector, sha256 != nullptr, expected);
  }
  ::close(fds[1]);
  char status = -1;
  std::string text;
  int frames = 0, width = 0, height = 0;
  Image image;
  bool complete = readAll(fds[0], &status, 1);
  if (complete && status == 0) {
    complete = readString(fds[0], text, 1 << 20);
  } else if (complete && status == 1) {
    complete = readString(fds[0], text, 256) && readAll(fds[0], &frames, sizeof frames) &&
               readAll(fds[0], &width, sizeof width) && readAll(fds[0], &height, sizeof height) &&
               width > 0 && height > 0 &&
               uint64_t(width) * uint64_t(height) * sizeof(float) <= tiffMemoryLimit();
    if (complete) {
      image = Image(width, height);
      complete = readAll(fds[0], image.pixels().data(), image.size() * sizeof(float));
    }
  }
  ::close(fds[0]);
  int wait_status = 0;
  while (::waitpid(child, &wait_status, 0) < 0 && errno == EINTR) {
  }
  if (WIFSIGNALED(wait_status))
    failAt(where,
           "libhdf5 crashed reading the file (signal {}): it is corrupt or not what it claims "
           "to be",
           WTERMSIG(wait_status));
  if (!complete || !WIFEXITED(wait_status) || WEXITSTATUS(wait_status) != 0)
    failAt(where, "the file could not be read (the reading process ended with status {})",
           WIFEXITED(wait_status) ? WEXITSTATUS(wait_status) : -1);
  if (status == 0) throw Error(text);  // the child's error, its location included
  if (sha256) *sha256 = text;
  if (frames_averaged) *frames_averaged = frames;
  return image;
}

namespace {

void writeStringAttribute(hid_t object, const char* name, const std::string& value,
                          const SourceLocation& where) {
  const Type type(H5Tcopy(H5T_C_S1));
  H5Tset_size(type.get(), value.size());
  H5Tset_strpad(type.get(), H5T_STR_NULLPAD);
  const Space space(H5Screate(H5S_SCALAR));
  const Attribute attribute(
      H5Acreate2(object, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT));
  if (!attribute.valid() || H5Awrite(attribute.get(), type.get(), value.data()) < 0)
    failAt(where, "cannot write the attribute {}{}", name, hdf5Says());
}

Group createGroup(hid_t parent, const char* name, const char* nx_class, hid_t creation,
                  const SourceLocation& where) {
  Group group(H5Gcreate2(parent, name, H5P_DEFAULT, creation, H5P_DEFAULT));
  if (!group.valid()) failAt(where, "cannot create the group {}{}", name, hdf5Says());
  writeStringAttribute(group.get(), "NX_class", nx_class, where);
  return group;
}

// A one-dimensional dataset of `values` stored as `file_type`.
template <typename T>
void writeVector(hid_t parent, const char* name, const std::vector<T>& values, hid_t file_type,
                 hid_t memory_type, hid_t creation, const SourceLocation& where,
                 const char* units = nullptr) {
  const hsize_t dims[1] = {values.size()};
  const Space space(H5Screate_simple(1, dims, nullptr));
  const Dataset dataset(
      H5Dcreate2(parent, name, file_type, space.get(), H5P_DEFAULT, creation, H5P_DEFAULT));
  if (!dataset.valid() ||
      H5Dwrite(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0)
    failAt(where, "cannot write the dataset {}{}", name, hdf5Says());
  if (units) writeStringAttribute(dataset.get(), "units", units, where);
}

}  // namespace

void writeNxTomo(const fs::path& path, std::span<const NxTomoFrame> frames, TiffFormat format) {
  const SourceLocation where = SourceLocation::inFile(path.string());
  if (frames.empty()) throw Error("cannot write an NXtomo file without frames", where);
  const Image& first = *frames.front().image;
  if (first.empty()) throw Error("cannot write an empty image", where);
  for (size_t f = 0; f < frames.size(); ++f) {
    const Image& image = *frames[f].image;
    if (image.width() != first.width() || image.height() != first.height())
      failAt(where, "frame {} is {}x{} pixels but frame 0 is {}x{}", f, image.width(),
             image.height(), first.width(), first.height());
    if (frames[f].image_key < 0 || frames[f].image_key > 2)
      failAt(where, "frame {}: image_key {}; expected 0, 1 or 2", f, frames[f].image_key);
    for (int y = 0; y < image.height(); ++y)
      for (int x = 0; x < image.width(); ++x)
        if (!std::isfinite(image(x, y)))
          failAt(where,
                 "cannot write pixel ({}, {}) of frame {} = {}: radiographs hold finite values", x,
                 y, f, image(x, y));
  }
  const bool as_uint16 = format == TiffFormat::kUInt16;

  AtomicFile out(path);
  {
    const std::lock_guard lock(hdf5Mutex());
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    H5Eclear2(H5E_DEFAULT);
    // No modification times in the objects' headers: the same frames give
    // the same bytes.
    const PropertyList dataset_creation(H5Pcreate(H5P_DATASET_CREATE));
    const PropertyList group_creation(H5Pcreate(H5P_GROUP_CREATE));
    H5Pset_obj_track_times(dataset_creation.get(), false);
    H5Pset_obj_track_times(group_creation.get(), false);
    const File file(H5Fcreate(out.tempPath().c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT));
    if (!file.valid()) failAt(where, "cannot create the HDF5 file{}", hdf5Says());
    const hid_t gc = group_creation.get(), dc = dataset_creation.get();
    const Group entry = createGroup(file.get(), "entry", "NXentry", gc, where);
    {
      const Type type(H5Tcopy(H5T_C_S1));
      const std::string definition = "NXtomo";
      H5Tset_size(type.get(), definition.size());
      const Space space(H5Screate(H5S_SCALAR));
      const Dataset dataset(H5Dcreate2(entry.get(), "definition", type.get(), space.get(),
                                       H5P_DEFAULT, dc, H5P_DEFAULT));
      if (!dataset.valid() ||
          H5Dwrite(dataset.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, definition.data()) < 0)
        failAt(where, "cannot write /entry/definition{}", hdf5Says());
    }
    const Group instrument = createGroup(entry.get(), "instrument", "NXinstrument", gc, where);
    const Group detector = createGroup(instrument.get(), "detector", "NXdetector", gc, where);
    const Group sample = createGroup(entry.get(), "sample", "NXsample", gc, where);
    const Group data_group = createGroup(entry.get(), "data", "NXdata", gc, where);
    writeStringAttribute(data_group.get(), "signal", "data", where);

    const auto rows = static_cast<hsize_t>(first.height()),
               columns = static_cast<hsize_t>(first.width());
    const hsize_t dims[3] = {frames.size(), rows, columns};
    const Space space(H5Screate_simple(3, dims, nullptr));
    const Dataset data(H5Dcreate2(detector.get(), "data",
                                  as_uint16 ? H5T_STD_U16LE : H5T_IEEE_F32LE, space.get(),
                                  H5P_DEFAULT, dc, H5P_DEFAULT));
    if (!data.valid()) failAt(where, "cannot create {}{}", kDetectorDataPath, hdf5Says());
    // Frame by frame, through a hyperslab of the file space.
    const Space file_space(H5Dget_space(data.get()));
    const hsize_t frame_dims[2] = {rows, columns};
    const Space memory_space(H5Screate_simple(2, frame_dims, nullptr));
    std::vector<uint16_t> quantized(static_cast<size_t>(rows * columns));
    for (size_t f = 0; f < frames.size(); ++f) {
      const hsize_t start[3] = {f, 0, 0}, count[3] = {1, rows, columns};
      H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr);
      const auto pixels = frames[f].image->pixels();
      herr_t status = 0;
      if (as_uint16) {
        for (size_t i = 0; i < pixels.size(); ++i)
          quantized[i] = static_cast<uint16_t>(
              std::lround(std::clamp(static_cast<double>(pixels[i]), 0.0, 65535.0)));
        status = H5Dwrite(data.get(), H5T_NATIVE_UINT16, memory_space.get(), file_space.get(),
                          H5P_DEFAULT, quantized.data());
      } else {
        status = H5Dwrite(data.get(), H5T_NATIVE_FLOAT, memory_space.get(), file_space.get(),
                          H5P_DEFAULT, pixels.data());
      }
      if (status < 0) failAt(where, "cannot write frame {}{}", f, hdf5Says());
    }
    if (H5Lcreate_hard(detector.get(), "data", data_group.get(), "data", H5P_DEFAULT, H5P_DEFAULT) <
        0)
      failAt(where, "cannot link {} to {}{}", kDataPath, kDetectorDataPath, hdf5Says());

    std::vector<int32_t> keys;
    std::vector<double> angles;
    for (const NxTomoFrame& frame : frames) {
      keys.push_back(frame.image_key);
      angles.push_back(frame.rotation_angle_deg);
    }
    writeVector(detector.get(), "image_key", keys, H5T_STD_I32LE, H5T_NATIVE_INT32, dc, where);
    writeVector(sample.get(), "rotation_angle", angles, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, dc,
                where, "degree");
    if (H5Fflush(file.get(), H5F_SCOPE_GLOBAL) < 0)
      failAt(where, "cannot finish the HDF5 file (disk full?){}", hdf5Says());
  }
  out.commit();
}

}  // namespace xgauge
