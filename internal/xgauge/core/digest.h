// SHA-256 digests of input files, so that a result names exactly the bytes it
// was computed from. The digest is taken from the bytes a loader reads, never
// by opening the file a second time (OpenSSL's libcrypto does the hashing).
#pragma once

#include <memory>
#include <string>
#include <string_view>

namespace xgauge {

// Incremental SHA-256: update() with consecutive pieces, then hex().
class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  void update(const void* data, size_t bytes);
  // The digest of everything passed so far, as 64 lower-case hex digits.
  // Ends the hashing: no update() after it.
  std::string hex();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// SHA-256 of `bytes`, 64 lower-case hex digits.
std::string sha256Hex(std::string_view bytes);

}  // namespace xgauge
