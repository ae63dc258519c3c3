#!/bin/bash
# Coverage-guided fuzzing of every volume reader with libFuzzer:
#   fuzz/run.sh [SECONDS per target, default 60] [TARGET ...]   (default: every target)
# Needs a nightly toolchain and cargo-fuzz (`cargo +nightly install cargo-fuzz`). Seeds are
# the formats tests' intact files; what a run finds is in fuzz/artifacts/TARGET. A panic, a
# run over 10 s or an allocation over 256 MB from an input of at most 64 KB is a finding.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(nrrd nifti nifti_gz metaimage vtk vti mrc mrc_gz dicom den)
rm -rf fuzz/seeds
VOXCUBE_FUZZ_SEEDS="$PWD/fuzz/seeds" VOXCUBE_FUZZ=0 \
  cargo test -q --release -p voxcube --test formats damaged_files > /dev/null
for t in "${targets[@]}"; do
  mkdir -p "fuzz/corpus/$t" "fuzz/seeds/$t"
  echo "== $t: $secs s"
  cargo +nightly fuzz run "$t" "fuzz/corpus/$t" "fuzz/seeds/$t" -- \
    -max_total_time="$secs" -timeout=10 -rss_limit_mb=1024 -malloc_limit_mb=256 \
    -max_len=65536 -print_final_stats=1 2>&1 | grep -E "^(==|stat::number_of_executed_units|stat::peak_rss_mb|SUMMARY|Done)|panicked|ERROR" || true
done
