// libFuzzer target: the "c3d" reader of tests/fuzz/readers.h (run by scripts/fuzz.sh).
#include "fuzz_common.h"
BODYMODEL_FUZZ_TARGET(c3d)
