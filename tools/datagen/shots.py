"""Shots (issue 51, "Shots, not frames"): what make_scene.py --shot and render_shots.py share, in plain Python.

A shot's camera, object and light moves are drawn from a random stream of their own (shot_rng), so a seed builds the
same scene with or without --shot; its first draw is the shot kind (drawn even when the kind is given, so that the
draws after it are the same). The kind of a seed is therefore known without Blender (kind_of).
"""
import random

KINDS = ["dolly", "pan", "orbit", "truck", "objects", "light", "mixed"]
KIND_WEIGHTS = [1.0, 1.0, 1.0, 1.0, 1.2, 0.8, 1.5]
CAMERA_KINDS = ["dolly", "pan", "orbit", "truck"]

# Measured by tools/datagen/vector_convention_check.py (README, "Shots and motion vectors").
VECTOR_CONVENTION = (
    "ViewLayer.Vector.{X,Y} = position in frame f-1 minus the pixel, ViewLayer.Vector.{Z,W} = the pixel minus the "
    "position in frame f+1 (so previous = pixel + (X, Y), next = pixel - (Z, W)); in pixels of the render, x to the "
    "right, y up (an EXR row index grows downwards: previous row = row - Y, next row = row + W); one whole frame each "
    "way; float32")


def shot_rng(seed):
    return random.Random(seed * 15485863 + 101)


def draw_kind(rng):
    return rng.choices(KINDS, KIND_WEIGHTS)[0]


def kind_of(seed):
    """The shot kind that --shot auto draws for this scene seed."""
    return draw_kind(shot_rng(seed))


def parse_int_list(text):
    """"1-16", "3,5-7" -> [1, ..., 16], [3, 5, 6, 7] (duplicates dropped, order kept)."""
    out = []
    for part in str(text).split(","):
        part = part.strip()
        if not part:
            continue
        lo, sep, hi = part.partition("-")
        out.extend(range(int(lo), int(hi) + 1) if sep else [int(lo)])
    return list(dict.fromkeys(out))


def frame_file(name, frame):
    return f"{name}.{frame:04d}.exr"
