// Process-wide memory settings.
#pragma once

namespace xgauge {

// Keeps large blocks (a Jacobian of a million pixels by a dozen parameters,
// a 4096^2 image) in the heap instead of giving each its own mapping: glibc
// maps every block above 32 MiB on its own and unmaps it when freed, so each
// least-squares solve, each re-solve of the uncertainty budget and each
// render with derivatives touched hundreds of MiB of fresh pages again. On
// the 2-core machines measured, those page faults took about 30 % of a
// 4096^2 measurement (570,000 faults against 163,000, 18.9 s against 13.2 s)
// at the same peak memory. Call at the start of main(), before the work
// starts; a no-op where the C library is not glibc. The main thread's heap
// is covered wholly; glibc still maps a worker thread's requests above its
// arenas' 64 MiB on their own.
void keepLargeBlocksInHeap();

}  // namespace xgauge
