#pragma once
// Process-wide heap policy for the command-line front ends (library code never sets it).
namespace clearfit {

/// Keeps freed heap memory in the process instead of returning it to the kernel (glibc: allocations
/// below 64 MiB from the heap, not mmap; the heap trimmed only beyond 256 MiB free). A solver that
/// allocates its matrices afresh every iteration (libmrcal's: libdogleg, CHOLMOD) then reuses the
/// same pages instead of faulting in new ones: `clearfit calibrate`'s first solve ran 2.9x faster
/// (README, Calibration). No-op without glibc.
void keep_freed_memory();

}  // namespace clearfit
