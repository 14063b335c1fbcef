#include "xgauge/core/output.h"

#include "xgauge/core/error.h"

#include <fcntl.h>
#include <pthread.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <set>
#include <thread>
#include <utility>
#include <vector>

namespace xgauge {
namespace fs = std::filesystem;

namespace {

// What an interruption or a failed transaction must undo. One mutex guards
// it all; the interrupt thread takes it like any other thread.
struct Registry {
  std::mutex mutex;
  std::set<fs::path> temporaries;
  bool transaction_open = false;
  std::vector<std::pair<fs::path, fs::path>> held;  // temp, target, in finishing order
  std::vector<fs::path> created_folders;            // parents first
};

Registry& registry() {
  static Registry instance;
  return instance;
}

// Removes the open transaction's files and folders; the caller holds the mutex.
void undoLocked(Registry& r) {
  std::error_code ignored;
  for (const auto& path : r.temporaries) fs::remove(path, ignored);
  r.temporaries.clear();
  r.held.clear();
  // Children before parents; a folder someone else filled meanwhile stays.
  for (auto it = r.created_folders.rbegin(); it != r.created_folders.rend(); ++it)
    fs::remove(*it, ignored);
  r.created_folders.clear();
}

// Creating a file is the only sure test of a writable folder (permissions,
// read-only mounts, root).
void probeFolder(const fs::path& folder, const fs::path& output) {
  const fs::path probe = folder / fmt::format(".xgauge-probe.{}", ::getpid());
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0)
    throw Error(
        fmt::format("cannot write in the folder {}: {}", folder.string(), std::strerror(errno)),
        SourceLocation::inFile(output.string()));
  ::close(fd);
  ::unlink(probe.c_str());
}

}  // namespace

void checkOutputFolder(const fs::path& folder) {
  const SourceLocation where = SourceLocation::inFile(folder.string());
  std::error_code ec;
  const auto status = fs::status(folder, ec);
  if (fs::exists(status)) {
    if (!fs::is_directory(status))
      throw Error("exists and is not a folder: cannot write the outputs into it", where);
    probeFolder(folder, folder);
    return;
  }
  // The nearest existing ancestor must be a folder we can create in.
  fs::path existing = fs::absolute(folder, ec);
  if (ec) throw Error(fmt::format("cannot resolve the path: {}", ec.message()), where);
  while (!existing.empty() && !fs::exists(existing, ec) && existing != existing.root_path())
    existing = existing.parent_path();
  if (!fs::is_directory(existing, ec))
    throw Error(fmt::format("cannot create the folder: {} is not a folder", existing.string()),
                where);
  probeFolder(existing, folder);
}

void checkOutputFile(const fs::path& file) {
  const SourceLocation where = SourceLocation::inFile(file.string());
  std::error_code ec;
  const auto status = fs::status(file, ec);
  if (fs::is_directory(status)) throw Error("is a folder, not a file name", where);
  if (fs::exists(status) && !fs::is_regular_file(status))
    throw Error("exists and is not a regular file: will not replace it", where);
  const fs::path folder = file.has_parent_path() ? file.parent_path() : fs::path(".");
  if (!fs::is_directory(folder, ec))
    throw Error(fmt::format("the output folder {} does not exist", folder.string()), where);
  probeFolder(folder, file);
}

void createOutputFolder(const fs::path& folder) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  // The components that do not exist yet, outermost first.
  std::vector<fs::path> missing;
  std::error_code ec;
  for (fs::path p = folder; !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
    missing.push_back(p);
    if (p == p.parent_path()) break;
  }
  std::reverse(missing.begin(), missing.end());
  for (const auto& p : missing) {
    if (!fs::create_directory(p, ec) && ec)
      throw Error(fmt::format("cannot create the folder: {}", ec.message()),
                  SourceLocation::inFile(p.string()));
    if (r.transaction_open) r.created_folders.push_back(p);
  }
  if (!fs::is_directory(folder, ec))
    throw Error("exists and is not a folder", SourceLocation::inFile(folder.string()));
}

OutputTransaction::OutputTransaction() {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  if (r.transaction_open) throw Error("internal: an output transaction is already open");
  r.transaction_open = true;
}

OutputTransaction::~OutputTransaction() {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  if (!committed_) {
    for (const auto& [temp, target] : r.held) {
      std::error_code ignored;
      fs::remove(temp, ignored);
      r.temporaries.erase(temp);
    }
    r.held.clear();
    std::error_code ignored;
    for (auto it = r.created_folders.rbegin(); it != r.created_folders.rend(); ++it)
      fs::remove(*it, ignored);
  }
  r.held.clear();
  r.created_folders.clear();
  r.transaction_open = false;
}

void OutputTransaction::commit() {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  for (auto it = r.held.begin(); it != r.held.end(); it = r.held.erase(it)) {
    std::error_code ec;
    fs::rename(it->first, it->second, ec);
    if (ec)
      throw Error(fmt::format("cannot move the finished file into place: {}", ec.message()),
                  SourceLocation::inFile(it->second.string()));
    r.temporaries.erase(it->first);
  }
  for (const fs::path& stale : stale_) {
    std::error_code ec;
    fs::remove(stale, ec);
    if (ec)
      throw Error(fmt::format("cannot remove an earlier run's file: {}", ec.message()),
                  SourceLocation::inFile(stale.string()));
  }
  r.created_folders.clear();
  committed_ = true;
}

void OutputTransaction::removeOnCommit(const fs::path& stale) { stale_.push_back(stale); }

bool OutputTransaction::holdBack(const fs::path& temp, const fs::path& target) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  if (!r.transaction_open) return false;
  // A later file of the same name replaces an earlier one.
  for (auto it = r.held.begin(); it != r.held.end(); ++it) {
    if (it->second == target) {
      std::error_code ignored;
      fs::remove(it->first, ignored);
      r.temporaries.erase(it->first);
      r.held.erase(it);
      break;
    }
  }
  r.held.emplace_back(temp, target);
  return true;
}

void registerTemporary(const fs::path& path) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  r.temporaries.insert(path);
}

void unregisterTemporary(const fs::path& path) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  r.temporaries.erase(path);
}

void installInterruptCleanup() {
  static std::once_flag once;
  std::call_once(once, [] {
    // Blocked here, before any other thread exists, the signals stay blocked
    // in every thread; only the cleanup thread takes them, with sigwait, so
    // the cleanup runs as ordinary code rather than in a signal handler.
    sigset_t signals;
    sigemptyset(&signals);
    for (int s : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&signals, s);
    pthread_sigmask(SIG_BLOCK, &signals, nullptr);
    std::thread([signals] {
      int caught = 0;
      if (sigwait(&signals, &caught) != 0) return;
      // The lock is kept to the end: no thread registers a new file after
      // the cleanup.
      Registry& r = registry();
      const std::lock_guard lock(r.mutex);
      undoLocked(r);
      // Die of the signal, as the shell expects.
      std::signal(caught, SIG_DFL);
      sigset_t only;
      sigemptyset(&only);
      sigaddset(&only, caught);
      pthread_sigmask(SIG_UNBLOCK, &only, nullptr);
      std::raise(caught);
      std::_Exit(128 + caught);
    }).detach();
  });
}

}  // namespace xgauge
