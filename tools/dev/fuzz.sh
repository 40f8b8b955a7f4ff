#!/usr/bin/env bash
# Builds the libFuzzer harnesses (the `fuzz` preset: clang, -fsanitize=fuzzer,address,undefined) and runs each
# for SECONDS (default 60) on a copy of its seed corpus (tests/fuzz/corpus/<harness>), so the committed seeds stay
# as they are. Prints, per harness, the executions and libFuzzer's coverage (cov: edges, ft: features) from its
# last status line; exits 1 if any harness crashed, leaked, hit UB, ran out of memory or timed out on an input
# (the input is kept as build/fuzz/artifacts/<harness>-crash-*, logs in build/fuzz/logs/).
#
#   tools/dev/fuzz.sh [SECONDS]                 every harness, SECONDS each
#   FUZZ_HARNESSES="fuzz_tza" tools/dev/fuzz.sh 600    only those
#   FUZZ_KEEP_CORPUS=DIR tools/dev/fuzz.sh      keep the grown corpora in DIR/<harness> (default: a temp dir, removed)
#   FUZZ_NO_BUILD=1 tools/dev/fuzz.sh           skip the build (already built)
#   FUZZ_JOBS=1 tools/dev/fuzz.sh               one harness at a time (default: one per core)
set -uo pipefail
cd "$(dirname "$0")/../.."

seconds=${1:-60}
harnesses=${FUZZ_HARNESSES:-"fuzz_exr_loader fuzz_safetensors fuzz_tza fuzz_channel_mapping fuzz_tev_ipc fuzz_live_images"}
bin=build/fuzz/tests/fuzz
logs=build/fuzz/logs
artifacts=build/fuzz/artifacts

if [ "${FUZZ_NO_BUILD:-0}" != 1 ]; then
  cmake --preset fuzz >/dev/null || exit 1
  cmake --build --preset fuzz -j "$(nproc)" || exit 1
fi
mkdir -p "$logs" "$artifacts"

if [ -n "${FUZZ_KEEP_CORPUS:-}" ]; then
  work=$FUZZ_KEEP_CORPUS
  mkdir -p "$work"
else
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
fi

# ASan: leaks are bugs; UBSan: print a stack and stop at the first report (the build has -fno-sanitize-recover).
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}

# One harness: fuzz its corpus copy, then leave libFuzzer's exit status beside its log.
fuzz_one() {
  local h=$1 corpus=$work/$1
  mkdir -p "$corpus"
  cp -n tests/fuzz/corpus/$h/* "$corpus"/ 2>/dev/null
  # -timeout: an input that takes over 60 s is a hang; -rss_limit_mb: libFuzzer's default, written out.
  "$bin/$h" "$corpus" -max_total_time="$seconds" -timeout=60 -rss_limit_mb=2048 -print_final_stats=1 \
    -artifact_prefix="$artifacts/$h-" >"$logs/$h.log" 2>&1
  echo $? >"$logs/$h.rc"
}

# Harnesses are single-threaded: run up to FUZZ_JOBS (default: one per core) at a time.
jobs=${FUZZ_JOBS:-$(nproc)}
failed=()
started=()
running=0
for h in $harnesses; do
  [ -x "$bin/$h" ] || { echo "fuzz: $bin/$h is missing" >&2; failed+=("$h"); continue; }
  started+=("$h")
  rm -f "$logs/$h.rc"
  fuzz_one "$h" &
  if ((++running >= jobs)); then wait -n; ((running--)); fi
done
wait

printf '%-22s %8s %12s %10s %8s %8s  %s\n' harness seconds execs exec/s cov ft result
for h in "${started[@]}"; do
  log=$logs/$h.log
  rc=$(cat "$logs/$h.rc" 2>/dev/null || echo "?")
  last=$(grep -E '^#[0-9]+' "$log" | tail -n 1)
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
  [ -n "$execs" ] || execs=$(sed -E -n 's/^#([0-9]+).*/\1/p' <<<"$last")
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -n 1)
  cov=$(sed -E -n 's/.* cov: ([0-9]+).*/\1/p' <<<"$last")
  ft=$(sed -E -n 's/.* ft: ([0-9]+).*/\1/p' <<<"$last")
  result=ok
  if [ "$rc" != 0 ]; then
    result="FAILED (exit $rc; see $log)"
    failed+=("$h")
  fi
  printf '%-22s %8s %12s %10s %8s %8s  %s\n' "$h" "$seconds" "${execs:-?}" "${rate:-?}" "${cov:-?}" "${ft:-?}" "$result"
done

if ((${#failed[@]})); then
  echo "fuzz: ${failed[*]} failed; reproduce with $bin/<harness> $artifacts/<harness>-crash-..." >&2
  for h in "${failed[@]}"; do
    [ -f "$logs/$h.log" ] && grep -m 20 -E 'ERROR|SUMMARY|runtime error|#[0-9]+ 0x' "$logs/$h.log" >&2
  done
  exit 1
fi
