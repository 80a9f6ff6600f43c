// libFuzzer target: the "pose_csv" reader of tests/fuzz/readers.h (run by scripts/fuzz.sh).
#include "fuzz_common.h"
BODYMODEL_FUZZ_TARGET(pose_csv)
