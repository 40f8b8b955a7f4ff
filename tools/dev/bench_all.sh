#!/bin/bash
# Every speed figure in docs/PERFORMANCE.md, measured in one go on one machine, so that the tables compare like
# with like. Run it on an idle machine (about 25 minutes on 2 cores); it writes JSON per table and the end-to-end
# runs as text into OUTDIR (default docs/benchmarks/DATE-CPU), then the model cards' benchmark can be re-stamped
# from the same machine with tools/models/stamp_benchmark.py.
#
#   tools/dev/bench_all.sh [OUTDIR]        (CLI=path/to/residue-cli to use another build;
#                                       ONLY="narrow oidn_2k oidn_cards paper e2e": a subset, e.g. without the
#                                       paper model's 9 minutes)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
cli=${CLI:-$root/build/release/app/residue-cli/residue-cli}
[ -x "$cli" ] || { echo "bench_all: no residue-cli at $cli (build first, or set CLI)" >&2; exit 1; }
# The CPU in the folder's name, e.g. amd-epyc-f26m2 (model name, family, model: one name covers several cores).
cpu=$(awk -F': ' '/^model name/{if (!n) n=$2} /^cpu family/{f=$2} /^model\t/{m=$2} END{print n "-f" f "m" m}' /proc/cpuinfo |
      tr 'A-Z' 'a-z' | tr -cs 'a-z0-9' '-' | sed 's/-$//')
out=${1:-$root/docs/benchmarks/$(date +%Y-%m-%d)-$cpu}
mkdir -p "$out"
echo "bench_all: writing to $out"

only=${ONLY:-narrow oidn_2k oidn_cards paper e2e}
wanted() { [[ " $only " == *" $1 "* ]]; }

bench() {  # NAME ARGS...: one bench table as JSON
  local name=$1; shift
  wanted "$name" || return 0
  echo "bench_all: $name"
  "$cli" bench "$@" --json > "$out/$name.json.tmp" && mv "$out/$name.json.tmp" "$out/$name.json"
}
bench narrow --models tiny,small,base --tiles 256,512,1024 --size 1024
bench oidn_2k --models oidn --tiles 512,1024,2048 --size 2048
bench oidn_cards --models oidn,oidn-cleanaux --tiles 256,512 --size 1024
bench paper --models 16/128 --tiles 256,512,1024 --size 1024

# End to end: one process reading a 2048^2 Cycles-layout render (the bundled example upscaled; 15 half channels,
# zip), denoising it and writing a half EXR, three times per model and precision, on the default backend (what a
# user gets). The CLI's own `time` line is denoise(); `files` is reading and writing; the wall clock is the whole
# process.
if ! wanted e2e; then echo "bench_all: done"; exit 0; fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
oiiotool "$root"/resources/examples/*/noisy.exr --resize 2048x2048 -d half --compression zip -o "$work/big.exr"
e2e=$out/end_to_end.txt
: > "$e2e.tmp"
for model in small oidn; do
  for precision in bf16 fp32; do
    for run in 1 2 3; do
      rm -f "$work/out.exr"
      echo "== $model $precision run $run" >> "$e2e.tmp"
      /usr/bin/time -f "wall %e s, user %U s, sys %S s, max RSS %M KiB" \
        "$cli" denoise "$work/big.exr" -o "$work/out.exr" -m "$model" --precision "$precision" \
        2>&1 | grep -E '^(backend|time|files|wall)' >> "$e2e.tmp"
    done
  done
done
mv "$e2e.tmp" "$e2e"
echo "bench_all: done"
