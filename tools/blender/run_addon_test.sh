#!/bin/bash
# The Blender add-on's headless test (ctest: blender_addon): packs the add-on, installs it into a Blender whose
# user folders are a temporary directory (nothing of the user's Blender is touched), and runs test_addon.py.
#   tools/blender/run_addon_test.sh RESIDUE_CLI        exit 77 (skipped) without Blender
set -euo pipefail
cli=$1
blender=${BLENDER:-/usr/bin/blender}
[ -x "$blender" ] || { echo "no Blender at $blender: skipped"; exit 77; }
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
/usr/bin/python3 "$here/make_zip.py" "$tmp/residue_blender.zip" > /dev/null
export BLENDER_USER_CONFIG="$tmp/config" BLENDER_USER_SCRIPTS="$tmp/scripts" BLENDER_USER_DATAFILES="$tmp/datafiles"
export RESIDUE_CLI="$cli" RESIDUE_ADDON_ZIP="$tmp/residue_blender.zip" RESIDUE_TEST_DIR="$tmp/work"
export TMPDIR="$tmp"  # Blender's own temporary files (quit.blend) too
mkdir -p "$tmp/work"
"$blender" -b --factory-startup --python-exit-code 1 --python "$here/test_addon.py" 2>&1 | grep -v "^Fra:\|^Read \|^$" || true
# grep hides Blender's render log; the result is what test_addon.py wrote
[ -f "$tmp/work/PASSED" ] || { echo "test_addon.py did not pass"; exit 1; }
# The modal path needs a window: Blender under Xvfb (software OpenGL), events simulated.
if command -v xvfb-run > /dev/null; then
  blend="$tmp/start.blend"  # opening a file keeps the splash screen away
  "$blender" -b --factory-startup --python-expr "import bpy; bpy.ops.wm.save_as_mainfile(filepath='$blend')" > /dev/null 2>&1
  timeout 300 xvfb-run -a -s "-screen 0 1280x720x24" "$blender" --factory-startup --enable-event-simulate "$blend" \
    --python "$here/test_addon_modal.py" 2>&1 | grep -E "^(ok|FAILED)" || true
  [ -f "$tmp/work/MODAL_PASSED" ] || { echo "test_addon_modal.py did not pass"; exit 1; }
else
  echo "no xvfb-run: the modal path is not tested"
fi
echo "blender add-on test passed"
