#!/usr/bin/env python3
"""Seeds for fuzz_tev_ipc: tev IPC packets of every type as a tev client writes them (the layout of tev's
src/python/ipc.py client), each input one byte (the harness's read size - 1) and then a stream of packets.

    /usr/bin/python3 tests/fuzz/make_ipc_seeds.py tests/fuzz/corpus/fuzz_tev_ipc
"""
import os
import struct
import sys


def packet(type_byte, body):
    return struct.pack("<I", 5 + len(body)) + bytes([type_byte]) + body


def s(text):
    return text.encode() + b"\0"


def open_v1(path):
    return packet(0, b"\1" + s(path))


def open_v2(path, channels):
    return packet(7, b"\1" + s(path) + s(channels))


def reload(name):
    return packet(1, b"\0" + s(name))


def close(name):
    return packet(2, s(name))


def create(name, w, h, channels):
    return packet(4, b"\1" + s(name) + struct.pack("<iii", w, h, len(channels)) + b"".join(s(c) for c in channels))


def update_v1(name, channel, x, y, w, h):
    values = struct.pack(f"<{w * h}f", *[0.25 * i for i in range(w * h)])
    return packet(3, b"\0" + s(name) + s(channel) + struct.pack("<iiii", x, y, w, h) + values)


def update_v2(name, channels, x, y, w, h):
    n = len(channels) * w * h
    body = b"\0" + s(name) + struct.pack("<i", len(channels)) + b"".join(s(c) for c in channels)
    return packet(5, body + struct.pack("<iiii", x, y, w, h) + struct.pack(f"<{n}f", *[0.5 * i for i in range(n)]))


def update_v3(name, channels, x, y, w, h):
    c = len(channels)
    body = b"\0" + s(name) + struct.pack("<i", c) + b"".join(s(ch) for ch in channels)
    body += struct.pack("<iiii", x, y, w, h)
    body += struct.pack(f"<{c}q", *range(c)) + struct.pack(f"<{c}q", *[c] * c)  # interleaved, as ipc.py sends
    return packet(6, body + struct.pack(f"<{c * w * h}f", *[float(i % 7) for i in range(c * w * h)]))


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    seeds = {
        "open_v1": open_v1("/tmp/render.exr:R,G,B"),
        "open_v2": open_v2("C:/renders/shot.exr", "albedo.*"),
        "reload": reload("render.exr"),
        "close": close("render.exr"),
        "create": create("pbrt", 16, 8, ["R", "G", "B", "A"]),
        "update_v1": update_v1("pbrt", "R", 0, 0, 4, 2),
        "update_v2": update_v2("pbrt", ["R", "G", "B"], 2, 1, 3, 2),
        "update_v3": update_v3("pbrt", ["R", "G", "B", "A"], 4, 4, 4, 4),
        "vector_graphics": packet(8, b"\0" + s("pbrt") + b"\0" + struct.pack("<i", 0)),
        "stream_render": create("live", 8, 8, ["R", "G", "B"]) + update_v3("live", ["R", "G", "B"], 0, 0, 8, 4)
        + update_v2("live", ["R", "G", "B"], 0, 4, 8, 4) + reload("live") + close("live"),
    }
    for i, (name, data) in enumerate(seeds.items()):
        piece = bytes([(7 * i + 3) % 64])  # the harness reads the stream in pieces of this + 1 bytes
        with open(os.path.join(out, name + ".bin"), "wb") as f:
            f.write(piece + data)


if __name__ == "__main__":
    main()
