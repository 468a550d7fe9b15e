#!/usr/bin/env bash
# Runs the fuzz targets one after the other, MINUTES each (default 10), and
# prints per target the executions, the corpus size and the findings.
#
#   fuzz/run.sh [MINUTES] [TARGET...]      (no TARGET: all of them)
#
# Not for CI: it needs the nightly toolchain and cargo-fuzz
# (`cargo install cargo-fuzz`), and takes MINUTES per target. The seed corpus
# is built first when fuzz/corpus/<target> is missing (fuzz/seed.py).
# libFuzzer runs in fork mode with one worker, going on after a crash, OOM or
# timeout; findings land in fuzz/artifacts/<target>/ and the logs in
# fuzz/logs/<target>.log (libFuzzer's own fuzz-0.log is moved there). Limits: 2 GiB RSS and malloc, 10 s per input.
# Replay a finding with
#   cargo run -p voxcast --example fuzz_replay -- TARGET FILE
# and keep it as a regression input in
# crates/voxcast/tests/fuzz-regressions/TARGET/.
set -euo pipefail
cd "$(dirname "$0")"

minutes=${1:-10}
shift || true
all=(vdb image_stack fds fds_s3d fds_sf fds_q nifti metaimage vtk obj geometry scene tf nrrd zarr
    mitsuba_vol raw dicom)
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=("${all[@]}")

mkdir -p logs
[ -d corpus ] || ./seed.py
# One build of every target first (debug assertions and overflow checks on).
nice -n 19 cargo +nightly fuzz build -a

summary=()
for t in "${targets[@]}"; do
    [ -d "corpus/$t" ] || ./seed.py >/dev/null
    mkdir -p "artifacts/$t"
    before=$(ls "artifacts/$t" | wc -l)
    echo "== $t: $minutes min"
    # The readers use rayon; one thread keeps the run to one core.
    RAYON_NUM_THREADS=1 nice -n 19 cargo +nightly fuzz run -a "$t" "corpus/$t" -- \
        -max_total_time=$((minutes * 60)) -fork=1 -jobs=1 -workers=1 \
        -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1 \
        -rss_limit_mb=2048 -malloc_limit_mb=2048 -timeout=10 -max_len=32768 \
        >"logs/$t.log" 2>&1 || true
    # With -jobs, libFuzzer writes the worker's output to fuzz-0.log.
    if [ -f fuzz-0.log ]; then cat fuzz-0.log >>"logs/$t.log"; rm -f fuzz-0.log; fi
    execs=$(grep -oE '^#[0-9]+' "logs/$t.log" | tail -1 | tr -d '#')
    crashes=$(grep -oE 'oom/timeout/crash: [0-9]+/[0-9]+/[0-9]+' "logs/$t.log" | tail -1 | cut -d' ' -f2)
    after=$(ls "artifacts/$t" | wc -l)
    line=$(printf '%-12s %4s min  %10s execs  corpus %5s  oom/timeout/crash %-9s  new artifacts %s' \
        "$t" "$minutes" "${execs:-?}" "$(ls "corpus/$t" | wc -l)" "${crashes:-0/0/0}" "$((after - before))")
    echo "$line"
    summary+=("$line")
done
echo
echo "== summary"
printf '%s\n' "${summary[@]}"
