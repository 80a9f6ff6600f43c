// libFuzzer target: the "trc" reader of tests/fuzz/readers.h (run by scripts/fuzz.sh).
#include "fuzz_common.h"
BODYMODEL_FUZZ_TARGET(trc)
