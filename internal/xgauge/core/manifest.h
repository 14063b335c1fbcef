// A part folder's manifest (manifest.json): which files a part's acquisition
// made, their sizes and SHA-256, and when it was taken. It is written last,
// atomically, by whoever acquires the part (`xgauge simulate` for a lot, a
// loader's PC on a line), so its presence says the folder is complete; its
// digests let a reader refuse a file that is still being written or was
// changed afterwards. docs/formats.md, "Part manifest".
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace xgauge {

inline constexpr const char* kManifestFileName = "manifest.json";
inline constexpr const char* kManifestFormat = "xgauge part manifest 1";

struct ManifestFile {
  std::string name;    // a plain file name inside the part folder (no '/')
  std::string sha256;  // 64 lower-case hex digits
  uint64_t bytes = 0;
};

struct Manifest {
  std::string part;    // the part's id, unique in its lot
  std::string lot;     // may be empty: the lot is then the plan's
  std::string time;    // acquisition time, UTC, ISO 8601 ("2026-12-04T15:00:00Z")
  int64_t index = -1;  // the part's place in production order; -1 unknown
  std::vector<ManifestFile> files;

  nlohmann::json toJson() const;
  // The digest that identifies the part's inputs: SHA-256 over the part id
  // and every (name, sha256) in name order. Two folders with the same bytes
  // under the same id have the same digest.
  std::string digest() const;
};

// Writes `folder`/manifest.json atomically, hashing each named file (read
// once). Throws Error naming a file that is missing.
Manifest writeManifest(const std::filesystem::path& folder, Manifest manifest,
                       const std::vector<std::string>& file_names);

// What a reader finds in a part folder.
enum class PartFolderState {
  kIncomplete,  // no manifest yet, or a listed file missing or still short
  kReady,       // every listed file present with its size and digest
  kCorrupt,     // a listed file has the right size but another digest, or the manifest is bad
};
struct PartFolderCheck {
  PartFolderState state = PartFolderState::kIncomplete;
  std::string why;  // for kIncomplete and kCorrupt: the file and what is wrong
  Manifest manifest;
};

// Reads and checks `folder`'s manifest; never throws for a bad folder (the
// state says why), so a watcher can come back to it later.
PartFolderCheck checkPartFolder(const std::filesystem::path& folder);

}  // namespace xgauge
