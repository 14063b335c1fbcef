#include "xgauge/core/memory.h"

#include <cstdlib>  // defines __GLIBC__ where the C library is glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace xgauge {

void keepLargeBlocksInHeap() {
#if defined(__GLIBC__)
  // No block of the main heap gets a mapping of its own, and freed memory
  // at the heap's top stays with the process (up to 1 GiB) rather than
  // being trimmed and faulted in again by the next solve.
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

}  // namespace xgauge
