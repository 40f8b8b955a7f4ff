#!/usr/bin/env bash
# Sets Residue up on Debian 12: installs the Debian packages it needs (only those missing), configures and
# builds the Release preset, then runs the main job on the bundled example.
# Idempotent; run as root or as a user with sudo. Environment: RESIDUE_SKIP_EXAMPLE=1 skips the example run.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(
  # toolchain
  build-essential cmake ninja-build pkg-config
  # libraries of residue_core and residue-cli
  libopenimageio-dev openimageio-tools libopenexr-dev libtbb-dev libcli11-dev nlohmann-json3-dev
  # inference: Eigen (portable backend) and oneDNN (fast backend, AVX-512 / AMX)
  libeigen3-dev libdnnl-dev
  # training: libtorch (residue-train, and the trainer/inference parity test)
  libtorch-dev
  # viewer: Qt6 Widgets, OpenColorIO, and Xvfb for the screenshot script
  qt6-base-dev libopencolorio-dev xvfb
  # packaging test: cpack DEB needs fakeroot (dpkg-dev comes with build-essential)
  fakeroot
  # tests: GoogleTest, and scikit-image + OpenImageIO's Python bindings for the independent metric checks
  libgtest-dev libgmock-dev python3 python3-numpy python3-skimage python3-openimageio
  # `import residue` (app/python): pybind11, Python's headers, and pytest for its tests
  pybind11-dev python3-dev python3-pytest
  # the Python module's PyTorch test (tensors in and out through NumPy)
  python3-torch
  # data generation: Blender (Cycles) for tools/datagen
  blender
  # fuzzing (tools/dev/fuzz.sh, the `fuzz` preset): clang 14 and its compiler-rt, which holds libFuzzer
  # (libclang_rt.fuzzer-x86_64.a) and clang's ASan/UBSan runtimes; the `asan` preset uses gcc's (build-essential)
  clang libclang-rt-14-dev
  # render farm: Slurm and munge, for `residue-cli farm slurm` and its end-to-end test on a one-node cluster
  slurmctld slurmd slurm-client munge
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "setup: installing ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

cmake --preset release
cmake --build --preset release -j "$(nproc)"

# `import residue` for Debian's python3: a .pth file naming the build's module folder, in the system's site folder
# when run as root, else in the user's.
if [ -d build/release/python ]; then
  if [ "$(id -u)" -eq 0 ]; then site=$(/usr/bin/python3 -c 'import site; print(site.getsitepackages()[0])')
  else site=$(/usr/bin/python3 -m site --user-site); fi
  mkdir -p "$site"
  echo "$PWD/build/release/python" > "$site/residue-build.pth"
  /usr/bin/python3 -c 'import residue' && echo "setup: python3 -c 'import residue' works (via $site/residue-build.pth)"
fi

# The default model: the one the README's first command denoises the example with.
default_model=multiscale

if [ "${RESIDUE_SKIP_EXAMPLE:-0}" != 1 ]; then
  cli=build/release/app/residue-cli/residue-cli
  example=resources/examples/room
  echo
  echo "== residue-cli eval on the bundled example ($example) =="
  "$cli" eval "$example/noisy.exr" --reference "$example/reference.exr"
  if [ -f "resources/models/$default_model.safetensors" ]; then
    echo
    echo "== residue-cli denoise on the bundled example, model '$default_model' =="
    mkdir -p build/example
    "$cli" denoise "$example/noisy.exr" --reference "$example/reference.exr" --model "$default_model" \
      --output build/example/room-denoised.exr --force
  fi
fi
