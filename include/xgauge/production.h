// xgauge's production line from code: the parts of a lot measured as they
// come into a results store, the store's lots as SPC pages and alarms, and
// a lot exported as Q-DAS AQDEF or CSV. In the style of xgauge/xgauge.h: an
// options struct, one call, a summary whose termination and message say how
// it ended. Needs only the C++ standard library; nothing here throws for
// bad input. docs/formats.md describes the plan and the store.
#pragma once

#include "xgauge/runtime.h"

#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace xgauge {

// Called on the calling thread with each line a call has to show (a part
// measured, an alarm).
using LineCallback = std::function<void(const std::string&)>;

struct InspectionOptions {
  std::filesystem::path plan;           // the inspection plan (JSON)
  std::filesystem::path source;         // a folder of part folders (default: the plan's)
  std::filesystem::path watch;          // or a folder parts arrive in, looked at until idle
  std::string store;                    // SQLite file or postgresql:// URL (default: the plan's)
  std::filesystem::path output_folder;  // <output>/<lot>/<part> (default: the plan's)
  std::string station;                  // default: the plan's, or the host
  std::string shard;                    // empty, or "i/N": this process's share
  double poll_s = 1.0;                  // watch: seconds between looks
  double idle_exit_s = 0.0;             // watch: stop after this long without a new part; 0: never
  std::size_t spc_baseline = 0;         // > 0: SPC after each part, phase I the first N
  bool write_report = true;             // report.html per part
  LineCallback on_line;                 // one line per part measured, and alarms
};

struct InspectionSummary {
  RunTermination termination = RunTermination::kFailure;
  std::string message;  // kFailure: why
  int measured = 0, not_measured = 0, already = 0, failed = 0, not_ready = 0;
  std::vector<std::string> failed_parts;  // part folders refused or failed (a folder run:
                                          // also those incomplete or corrupt)
  int exit_status = 1;  // `xgauge inspect`'s: 1 when a part failed or on kFailure
};

InspectionSummary inspect(const InspectionOptions& options);

// Control charts, Nelson rules and capability per lot and dimension. Each
// lot's alarms in the store become this analysis's, replacing the earlier
// one's.
struct ProcessControlOptions {
  std::string store;                    // SQLite file or postgresql:// URL
  std::vector<std::string> lots;        // empty: every lot
  std::filesystem::path output_folder;  // <output>/<lot>/<dimension>.html, spc.json
  std::size_t baseline = 30;            // phase I: the first N parts of each lot; a lot
                                        // (dimension) with fewer measured parts is refused
  std::string baseline_lot;             // or every part of this lot
  std::vector<int> rules;               // 1..8, 9 the moving range; empty: all
  LineCallback on_alarm;                // each alarm, after the pages are written
};

struct ProcessControlSummary {
  RunTermination termination = RunTermination::kFailure;
  std::string message;  // kFailure: why
  std::size_t pages = 0, alarms = 0;
  int new_alarms = 0;  // not among the lot's alarms before (its previous analysis's)
};

ProcessControlSummary processControl(const ProcessControlOptions& options);

// A lot of a results store as a Q-DAS AQDEF file (.dfq) and/or CSV.
struct LotExportOptions {
  std::string store;  // SQLite file or postgresql:// URL
  std::string lot;
  std::filesystem::path dfq, csv;  // at least one
  std::string part_number;         // K1001 (default: the lot's name)
  std::string part_description;    // K1002
};

struct LotExportSummary {
  RunTermination termination = RunTermination::kFailure;
  std::string message;  // kFailure: why
  std::size_t parts = 0;
};

LotExportSummary exportLot(const LotExportOptions& options);

}  // namespace xgauge
