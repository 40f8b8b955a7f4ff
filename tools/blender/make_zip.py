#!/usr/bin/python3
"""Packs the Blender add-on (tools/blender/residue_blender/) into a zip that Blender installs:
Edit > Preferences > Add-ons > Install... (or bpy.ops.preferences.addon_install).

    /usr/bin/python3 tools/blender/make_zip.py [OUT.zip]     (default: residue_blender.zip here)
"""
import pathlib
import sys
import zipfile

HERE = pathlib.Path(__file__).resolve().parent
PACKAGE = HERE / "residue_blender"


def make_zip(out):
    out = pathlib.Path(out)
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(PACKAGE.rglob("*.py")):
            z.write(f, f.relative_to(HERE))
    return out


if __name__ == "__main__":
    print(make_zip(sys.argv[1] if len(sys.argv) > 1 else "residue_blender.zip"))
