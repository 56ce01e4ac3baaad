#!/usr/bin/env bash
# scripts/fuzz.sh SECONDS [HARNESS...]: builds the libFuzzer harnesses of fuzz/ with clang in build-fuzz/
# (LANCER_FUZZ=ON: ASan, UBSan, libFuzzer), seeds a corpus per harness from the repo's scenes, its broken
# test corpus and cut-down shared data (fuzz/make_seeds.py; nothing is copied into the repo), runs each
# harness for SECONDS, one after the other, and prints harness, executions, exec/s, corpus entries,
# coverage and findings. Exits 1 when a harness found a crash, hang, leak or out-of-memory (the inputs are
# in build-fuzz/findings/HARNESS/). Not run in CI: libFuzzer needs time (docs/robustness.md, "Fuzzing").
set -euo pipefail

usage() {
    echo "usage: scripts/fuzz.sh SECONDS [HARNESS...]  (harnesses: ${ALL_HARNESSES[*]})" >&2
    exit 2
}

ALL_HARNESSES=(off_fuzz dsc_fuzz nff_fuzz ply_fuzz obj_fuzz plo_fuzz rays_fuzz mesh_rays_fuzz instances_fuzz)
[[ $# -ge 1 && $1 =~ ^[0-9]+$ && $1 -gt 0 ]] || usage
seconds=$1
shift
harnesses=("$@")
[[ ${#harnesses[@]} -gt 0 ]] || harnesses=("${ALL_HARNESSES[@]}")
for harness in "${harnesses[@]}"; do
    [[ " ${ALL_HARNESSES[*]} " == *" $harness "* ]] || usage
done

source_dir=$(cd "$(dirname "$0")/.." && pwd)
build=$source_dir/build-fuzz
shared_data=$source_dir/../shared/data

launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S "$source_dir" -B "$build" -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DLANCER_FUZZ=ON -DLANCER_BUILD_TESTS=OFF -DLANCER_BUILD_BENCH=OFF -DLANCER_BUILD_APPS=OFF \
    -DLANCER_WARNINGS_AS_ERRORS=ON "${launcher[@]}" >/dev/null
cmake --build "$build" -j"${FUZZ_BUILD_JOBS:-2}" --target "${harnesses[@]}" make_plo_seeds

# A scratch folder per run (the harnesses write their inputs there, and the seeds are written there anew
# every run), so that two runs side by side do not remove each other's files: a shared seed folder, removed
# and rewritten by a second run while the first harness was still starting, stopped it before its first input.
# The corpus each harness grows is kept between runs.
mkdir -p "$build/tmp"
scratch=$(mktemp -d "$build/tmp/run.XXXXXX")
trap 'rm -rf "$scratch"' EXIT
seeds=$scratch/seeds
python3 "$source_dir/fuzz/make_seeds.py" "$source_dir" "$shared_data" "$seeds"
"$build/fuzz/make_plo_seeds" "$seeds/plo_fuzz" >/dev/null

export TMPDIR=$scratch
export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$source_dir/fuzz/lsan.supp}
report=$scratch/report.txt
printf '%-14s %12s %8s %8s %8s %8s\n' harness executions exec/s corpus coverage findings >"$report"
status=0
for harness in "${harnesses[@]}"; do
    corpus=$build/corpus/$harness
    findings=$build/findings/$harness
    log=$build/logs/$harness.log
    mkdir -p "$corpus" "$findings" "$build/logs" "$seeds/$harness"
    echo "fuzzing $harness for ${seconds}s (log: $log)"
    touch "$log.start"  # findings of earlier runs stay in $findings but are not counted again
    # -timeout: a hang; -rss_limit_mb/-malloc_limit_mb: a blind allocation (docs/formats.md, "Header counts").
    if ! "$build/fuzz/$harness" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
        -malloc_limit_mb=1024 -max_len=16384 -print_final_stats=1 -artifact_prefix="$findings/" \
        "$corpus" "$seeds/$harness" >"$log" 2>&1; then
        status=1
    fi
    executions=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
    per_second=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
    coverage=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | cut -d' ' -f2 || true)
    found=$(find "$findings" -type f -newer "$log.start" | wc -l)
    [[ $found -eq 0 ]] || status=1
    printf '%-14s %12s %8s %8s %8s %8s\n' "$harness" "${executions:-?}" "${per_second:-?}" \
        "$(find "$corpus" -type f | wc -l)" "${coverage:-?}" "$found" >>"$report"
done
cat "$report"
[[ $status -eq 0 ]] || echo "findings: see build-fuzz/findings/ and build-fuzz/logs/" >&2
exit $status
