#include "xgauge/core/manifest.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/config.h"
#include "xgauge/core/digest.h"
#include "xgauge/core/error.h"

#include <algorithm>
#include <fstream>

namespace xgauge {

namespace {

// SHA-256 of a file read in blocks (part files may be hundreds of MB).
std::string fileSha256(const std::filesystem::path& path, uint64_t* bytes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot read", path.string());
  Sha256 hash;
  std::vector<char> block(1 << 20);
  uint64_t total = 0;
  while (in) {
    in.read(block.data(), static_cast<std::streamsize>(block.size()));
    const auto got = static_cast<size_t>(in.gcount());
    hash.update(block.data(), got);
    total += got;
  }
  if (bytes) *bytes = total;
  return hash.hex();
}

bool plainName(const std::string& name) {
  return !name.empty() && name != "." && name != ".." && name.find('/') == std::string::npos &&
         name != kManifestFileName;
}

}  // namespace

nlohmann::json Manifest::toJson() const {
  nlohmann::json files_json = nlohmann::json::array();
  for (const auto& f : files)
    files_json.push_back({{"name", f.name}, {"sha256", f.sha256}, {"bytes", f.bytes}});
  nlohmann::json out = {{"format", kManifestFormat}, {"part", part}, {"time", time}};
  if (!lot.empty()) out["lot"] = lot;
  if (index >= 0) out["index"] = index;
  out["files"] = files_json;
  return out;
}

std::string Manifest::digest() const {
  std::vector<const ManifestFile*> sorted;
  for (const auto& f : files) sorted.push_back(&f);
  std::sort(sorted.begin(), sorted.end(),
            [](const ManifestFile* a, const ManifestFile* b) { return a->name < b->name; });
  std::string text = "part " + part + "\n";
  for (const auto* f : sorted) text += f->name + " " + f->sha256 + "\n";
  return sha256Hex(text);
}

Manifest writeManifest(const std::filesystem::path& folder, Manifest manifest,
                       const std::vector<std::string>& file_names) {
  manifest.files.clear();
  for (const auto& name : file_names) {
    XG_CHECK(plainName(name), "manifest file name '{}'", name);
    ManifestFile f;
    f.name = name;
    f.sha256 = fileSha256(folder / name, &f.bytes);
    manifest.files.push_back(f);
  }
  writeFileAtomically(folder / kManifestFileName, manifest.toJson().dump(2) + "\n");
  return manifest;
}

PartFolderCheck checkPartFolder(const std::filesystem::path& folder) {
  PartFolderCheck check;
  const auto path = folder / kManifestFileName;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    check.why = path.string() + ": not there yet";
    return check;
  }
  try {
    const ConfigNode root = ConfigNode::loadFile(path);
    if (root.get<std::string>("format") != kManifestFormat)
      root.at("format").fail(std::string("expected \"") + kManifestFormat + "\"");
    Manifest& m = check.manifest;
    m.part = root.get<std::string>("part");
    if (m.part.empty()) root.at("part").fail("the part id must not be empty");
    m.lot = root.get<std::string>("lot", "");
    m.time = root.get<std::string>("time");
    if (auto index = root.find("index")) m.index = index->integer(0, int64_t{1} << 53);
    const ConfigNode files = root.at("files");
    if (files.size() == 0) files.fail("no files");
    for (size_t i = 0; i < files.size(); ++i) {
      const ConfigNode item = files[i];
      ManifestFile f;
      f.name = item.get<std::string>("name");
      if (!plainName(f.name)) item.at("name").fail("expected a file name inside the part folder");
      f.sha256 = item.get<std::string>("sha256");
      if (f.sha256.size() != 64) item.at("sha256").fail("expected 64 hex digits");
      f.bytes = static_cast<uint64_t>(item.at("bytes").integer(0, int64_t{1} << 53));
      m.files.push_back(f);
    }
    root.finish();
  } catch (const Error& e) {
    check.state = PartFolderState::kCorrupt;
    check.why = e.what();
    return check;
  }
  // A file shorter than listed may still be arriving: incomplete, not corrupt.
  for (const auto& f : check.manifest.files) {
    const auto file = folder / f.name;
    const auto size = std::filesystem::file_size(file, ec);
    if (ec || size < f.bytes) {
      check.state = PartFolderState::kIncomplete;
      check.why = fmt::format("{}: {} of {} bytes", file.string(), ec ? 0 : size, f.bytes);
      return check;
    }
    uint64_t bytes = 0;
    std::string digest;
    try {
      digest = fileSha256(file, &bytes);
    } catch (const Error& e) {
      check.state = PartFolderState::kIncomplete;
      check.why = e.what();
      return check;
    }
    if (bytes != f.bytes || digest != f.sha256) {
      check.state = PartFolderState::kCorrupt;
      check.why = fmt::format("{}: SHA-256 {} ({} bytes), the manifest says {} ({} bytes)",
                              file.string(), digest, bytes, f.sha256, f.bytes);
      return check;
    }
  }
  check.state = PartFolderState::kReady;
  return check;
}

}  // namespace xgauge
