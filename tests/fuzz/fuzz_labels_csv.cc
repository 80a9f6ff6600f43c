// libFuzzer target: the "labels_csv" reader of tests/fuzz/readers.h (run by scripts/fuzz.sh).
#include "fuzz_common.h"
BODYMODEL_FUZZ_TARGET(labels_csv)
