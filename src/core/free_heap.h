#pragma once
// Returning the heap's free pages to the system between the large steps of a stage.

#include <cstddef>  // defines __GLIBC__ on glibc
#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace wavebrdf::detail {

// glibc keeps the pages of freed blocks resident in its heap; when the next step's blocks do not
// fit where the last step's were (the field tiles' sizes differ by a margin), the heap grows and
// the resident size counts both. malloc_trim gives every free page back (madvise), so the peak
// is what is live. Changes no value; a no-op without glibc.
inline void release_free_heap() {
#if defined(__GLIBC__)
    malloc_trim(0);
#endif
}

}  // namespace wavebrdf::detail
