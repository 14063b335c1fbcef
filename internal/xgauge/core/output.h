// A command's outputs: checked before any work, all appearing at its end or
// none at all, and no temporary file left behind by an error or an
// interruption (Ctrl-C, SIGTERM, SIGHUP).
//
// - checkOutputFolder / checkOutputFile run before the work starts: the
//   place must be creatable and writable (tried with a probe file, so a
//   read-only file system counts even for root) and not an existing entry
//   of the wrong kind.
// - An OutputTransaction, while it exists, holds back every file finished
//   through AtomicFile (core/atomic_file.h) and every folder made through
//   createOutputFolder(); commit() moves the files into place. Destroyed
//   without commit (an exception), it removes them and the folders it made.
// - installInterruptCleanup() (once, first thing in main, before any thread
//   starts) turns the termination signals into an orderly cleanup on a
//   thread of its own: temporary and held-back files and folders made by the
//   open transaction are removed, then the process exits with 128 + signal.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace xgauge {

// Throws Error (naming the path and the reason) unless `folder` is an
// existing writable folder or can be created.
void checkOutputFolder(const std::filesystem::path& folder);
// Throws Error unless `file` can be written: not a folder, and its folder
// exists or can be created, and is writable.
void checkOutputFile(const std::filesystem::path& file);

// Creates `folder` and its missing parents; under an OutputTransaction, the
// ones created are removed again if the transaction does not commit.
void createOutputFolder(const std::filesystem::path& folder);

class OutputTransaction {
 public:
  OutputTransaction();  // becomes the process's open transaction (one at a time)
  ~OutputTransaction();
  OutputTransaction(const OutputTransaction&) = delete;
  OutputTransaction& operator=(const OutputTransaction&) = delete;

  // Moves every held-back file into place, in the order they were finished,
  // then removes the files named by removeOnCommit().
  void commit();
  // A file an earlier run left that this run's outputs contradict (a failed
  // calibration's diagnostic beside a new material.json, or the reverse):
  // removed when, and only when, the transaction commits.
  void removeOnCommit(const std::filesystem::path& stale);

  // For AtomicFile::commit(): when a transaction is open, it takes the
  // finished temporary file and returns true.
  static bool holdBack(const std::filesystem::path& temp, const std::filesystem::path& target);
  // For createOutputFolder().
  static void noteCreatedFolder(const std::filesystem::path& folder);

 private:
  bool committed_ = false;
  std::vector<std::filesystem::path> stale_;
};

// Temporary files that an interruption must remove (AtomicFile registers
// its own).
void registerTemporary(const std::filesystem::path& path);
void unregisterTemporary(const std::filesystem::path& path);

void installInterruptCleanup();

}  // namespace xgauge
