// `xgauge inspect PLAN`: the parts of a lot measured as they come. An
// inspection plan is a measurement job without its radiographs' folder (the
// radiographs, dark and flat frames are file names inside each part's
// folder) plus where the parts come from and where results go
// (docs/formats.md, "Inspection plan").
//
// A part is taken only when its manifest (core/manifest.h) is there and
// every file it lists matches its size and SHA-256; it is claimed in the
// results store (production/store.h), measured, its outputs written
// (result.json, report.html, ...) and its results recorded with the claim
// released in one transaction. A part already measured with the same
// inputs is skipped, so a restart after kill -9 at any moment measures
// only what is not in the store, and measures it to the same numbers (a
// measurement is deterministic for given inputs and seed).
#pragma once

#include "xgauge/production/store.h"

#include <nlohmann/json.hpp>

#include <atomic>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

struct InspectionPlan {
  std::filesystem::path file;
  std::string sha256;
  std::string description;
  std::string lot;               // "" : the manifest's lot, else the source folder's name
  std::string station;           // "" : the host name
  std::string store;             // an SQLite file (relative to the plan) or a postgresql:// URL
  std::filesystem::path source;  // folder of part folders; may be empty (given on the command line)
  std::filesystem::path output;  // per-part outputs go to output/<lot>/<part>; may be empty
  double claim_lease_s = 900.0;
  // The job, its part, machine, material and verification paths made
  // absolute; radiographs' image, dark, flat and previous left as names
  // inside a part folder.
  nlohmann::json job;

  // Reads and checks the plan, the job's keys included (Error naming the
  // plan file and key).
  static InspectionPlan load(const std::filesystem::path& path);
  // The files every part must have (the radiographs, dark, flat, previous).
  std::vector<std::string> partFiles() const;
};

// `--shard i/N`: which share of the parts (or a study's runs) this process
// takes. A part is in shard i (1-based) when a fixed hash of its id is i - 1
// modulo N, so N processes together take every part once whatever order the
// parts arrive in.
struct Shard {
  int index = 1, count = 1;
  static Shard parse(const std::string& text);  // "2/4"; Error otherwise
  bool takes(const std::string& id) const;
};

struct InspectOptions {
  std::filesystem::path source;  // overrides the plan's
  std::string store;             // overrides the plan's
  std::filesystem::path output;  // overrides the plan's
  std::string station;           // overrides the plan's
  bool watch = false;            // keep looking for parts arriving
  double poll_s = 1.0;           // watch: how often the folder is looked at
  double idle_exit_s = 0.0;      // watch: stop after this long without a new part (0: never)
  bool report = true;            // report.html per part
  Shard shard;
  // > 0: after each part, SPC over its lot with the first `spc_baseline`
  // parts as phase I (production/spc_report.h), once that many are
  // measured; new alarms go into the store and out as "ALARM ..." lines.
  size_t spc_baseline = 0;
};

struct InspectSummary {
  int measured = 0;      // measured by this process
  int already = 0;       // found in the store
  int elsewhere = 0;     // claimed by another live station (left to it)
  int not_ready = 0;     // incomplete or corrupt folders left (last look)
  int failed = 0;        // input errors, or (a folder run) folders incomplete or corrupt
  int not_measured = 0;  // of `measured`: fits the failure rule refused
  std::vector<std::string> failed_parts;  // the part folders that failed, in order
};

// One line per part measured goes to `line` (stdout in the CLI): the part,
// its verdict, and its worst dimension's deviation over its tolerance.
InspectSummary inspect(const InspectionPlan& plan, const InspectOptions& options,
                       const std::function<void(const std::string&)>& line);

// The line for a part: "p0007  conforms  width -0.42" where -0.42 is the
// dimension's (value - mid-zone) over half the zone's width (|x| > 1: out
// of the tolerance zone), the largest |x| of the part's toleranced
// dimensions; "no tolerance" and "not measured" otherwise.
std::string partLine(const std::string& part, const nlohmann::json& result);

}  // namespace xgauge
