// memory.hpp: glibc's malloc kept from returning freed memory to the kernel.
#include <clearfit/memory.hpp>

#include <cstdlib>  // <features.h>, which says whether this is glibc
#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace clearfit {

void keep_freed_memory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
#endif
}

}  // namespace clearfit
