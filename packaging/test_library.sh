#!/usr/bin/env bash
# The installed library as another project uses it: `cmake --install` of the dev component into a temporary prefix,
# packaging/library_example configured against it with find_package(Residue CONFIG) and built, then run on the bundled room:
# it must write the EXR and lower the relMSE well below the noisy input's.
#   test_library.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1 src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" --component dev > "$tmp/install.log"
test -f "$tmp/prefix/lib/cmake/Residue/ResidueConfig.cmake" || { echo "no ResidueConfig.cmake installed"; exit 1; }
test -f "$tmp/prefix/include/residue/core/denoise/denoiser.h" || { echo "headers not installed"; exit 1; }
cmake -S "$src/packaging/library_example" -B "$tmp/example" -DCMAKE_PREFIX_PATH="$tmp/prefix" -DCMAKE_BUILD_TYPE=Release \
  > "$tmp/configure.log" 2>&1 || { cat "$tmp/configure.log"; exit 1; }
cmake --build "$tmp/example" -j2 > "$tmp/build.log" 2>&1 || { cat "$tmp/build.log"; exit 1; }
"$tmp/example/denoise_one" "$src/resources/examples/room/noisy.exr" "$tmp/out.exr" multiscale | tee "$tmp/run.log"
test -s "$tmp/out.exr" || { echo "no output written"; exit 1; }
# relMSE 0.0016 (noisy 0.060) on the room: the denoised one must be below a tenth of the noisy one.
python3 - "$tmp/run.log" <<'PY'
import re, sys
m = re.search(r"relMSE ([0-9.e+-]+) \(noisy ([0-9.e+-]+)\)", open(sys.argv[1]).read())
assert m, "no relMSE line"
den, noisy = float(m.group(1)), float(m.group(2))
assert den < 0.1 * noisy, f"denoised relMSE {den} is not below a tenth of the noisy {noisy}"
print(f"ok: relMSE {den} against the noisy {noisy}")
PY
