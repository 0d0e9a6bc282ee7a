// Every test executable's one FELT_DEFINE_ALLOC_COUNTER() (tests/alloc_counter.h): CMake
// compiles this file into each, so any test may use felt::AllocationGuard.
#include "tests/alloc_counter.h"

FELT_DEFINE_ALLOC_COUNTER();
