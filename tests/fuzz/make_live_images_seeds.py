#!/usr/bin/env python3
"""Seeds for fuzz_live_images: scripts of operations on the viewer's streamed images (fuzz_targets.h,
LiveImagesScript). Each operation is [op, client, image] and its arguments:
  0 create:  huge (255: 16384 x 16384), width - 1, height - 1, channel layout (0 RGB, 1 RGBA, 2 RGB + albedo, 3 Y, 4 N)
  1 update:  channel (0 R, 1 G, 2 B, 3 A, 4 albedo.G, 5 Z), x, y, width - 1, height - 1, first value
  3 close;   4 corrupt the next packet (two bytes say where and how);   5 show (turn it into an AOV stack)

    /usr/bin/python3 tests/fuzz/make_live_images_seeds.py tests/fuzz/corpus/fuzz_live_images
"""
import os
import sys


def create(client, image, w, h, layout=0, huge=0):
    return [0, client, image, huge, w - 1, h - 1, layout]


def update(client, image, channel, x, y, w, h, base=1):
    return [1, client, image, channel, x, y, w - 1, h - 1, base]


def close(client, image):
    return [3, client, image]


def show(image):
    return [5, 0, image]


SEEDS = {
    # A small test frame shown, then the real one under another name (the crash of issue 49).
    "small_then_large": create(0, 0, 4, 4) + [u for c in range(3) for u in update(0, 0, c, 0, 0, 4, 4)] + show(0)
    + create(0, 1, 96, 96, 1) + update(0, 1, 0, 0, 0, 40, 40) + update(0, 1, 3, 60, 60, 40, 40) + show(1),
    "rgb_tiles": create(0, 0, 64, 48) + [u for ty in (0, 32) for tx in (0, 32) for c in range(3)
                                          for u in update(0, 0, c, tx, ty, 32, 32, tx + ty)] + show(0),
    "albedo_layers": create(1, 2, 32, 32, 2) + update(1, 2, 4, 0, 0, 32, 32) + update(1, 2, 0, 0, 0, 32, 32) + show(2),
    "huge_refused": create(0, 0, 8, 8) + create(1, 1, 1, 1, 0, 255) + show(0) + show(1),
    "over_the_cap": create(0, 0, 96, 96, 1) + create(1, 1, 96, 96, 1) + create(2, 2, 96, 96, 1) + show(2),
    "recreate_and_close": create(0, 3, 16, 16) + update(0, 3, 1, 8, 8, 16, 16) + create(0, 3, 8, 8, 1)
    + update(0, 3, 3, 0, 0, 8, 8) + close(0, 3) + show(3) + update(1, 3, 0, 0, 0, 1, 1),
    "corrupt_then_good": create(0, 0, 8, 8) + [4, 0, 0, 3, 7] + update(0, 0, 0, 0, 0, 8, 8) + update(1, 0, 1, 0, 0, 8, 8)
    + show(0),
    "no_colour": create(2, 1, 12, 12, 3) + update(2, 1, 5, 0, 0, 12, 12) + create(2, 2, 12, 12, 4) + show(1) + show(2),
    "overhang": create(0, 0, 10, 10) + update(0, 0, 0, 5, 5, 40, 40) + update(0, 0, 2, 99, 99, 1, 1) + show(0),
    "three_clients": create(0, 0, 20, 20) + create(1, 1, 20, 20) + create(2, 2, 20, 20)
    + update(2, 0, 0, 0, 0, 20, 20) + update(0, 1, 0, 0, 0, 20, 20) + close(1, 2) + show(0) + show(1) + show(2),
}


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    for name, ops in SEEDS.items():
        with open(os.path.join(out, name), "wb") as f:
            f.write(bytes(ops))


if __name__ == "__main__":
    main()
