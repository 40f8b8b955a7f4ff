#!/usr/bin/env python3
"""Lists the tensors of an Open Image Denoise TZA ("Tensor Archive") file: name, shape, layout, dtype.

Standard library only. Format (little-endian): u16 magic 0x41D7, u8 major (2), u8 minor, u64 table offset;
at the table: u32 count, then per tensor: u16 name length + UTF-8 name, u8 ndims, ndims x u32 dims,
ndims layout chars, 1 dtype char ('f' float32, 'h' float16, 'b' int8, 'B' uint8), u64 data offset.

Usage: tools/dev/tza_dump.py FILE.tza [FILE.tza ...] [--compact]
"""
import struct
import sys

DTYPE_SIZE = {"f": 4, "h": 2, "b": 1, "B": 1}


def read_table(path):
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < 12:
        raise ValueError(f"{path}: truncated header")
    magic, major, minor, table = struct.unpack_from("<HBBQ", data, 0)
    if magic != 0x41D7:
        raise ValueError(f"{path}: bad magic 0x{magic:04X}")
    if major != 2:
        raise ValueError(f"{path}: unsupported version {major}.{minor}")
    (count,) = struct.unpack_from("<I", data, table)
    pos = table + 4
    tensors = []
    for _ in range(count):
        (name_len,) = struct.unpack_from("<H", data, pos)
        pos += 2
        name = data[pos:pos + name_len].decode("utf-8")
        pos += name_len
        (ndims,) = struct.unpack_from("<B", data, pos)
        pos += 1
        dims = list(struct.unpack_from(f"<{ndims}I", data, pos))
        pos += 4 * ndims
        layout = data[pos:pos + ndims].decode("ascii")
        pos += ndims
        dtype = chr(data[pos])
        pos += 1
        (offset,) = struct.unpack_from("<Q", data, pos)
        pos += 8
        n = 1
        for d in dims:
            n *= d
        end = offset + n * DTYPE_SIZE.get(dtype, 0)
        if end > len(data):
            raise ValueError(f"{path}: tensor {name} data [{offset}, {end}) is past the end ({len(data)})")
        tensors.append((name, dims, layout, dtype, offset))
    return (major, minor), tensors, len(data)


def main(argv):
    compact = "--compact" in argv
    files = [a for a in argv if a != "--compact"]
    if not files:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    for path in files:
        (major, minor), tensors, size = read_table(path)
        print(f"{path}: version {major}.{minor}, {len(tensors)} tensors, {size} bytes")
        for name, dims, layout, dtype, offset in tensors:
            shape = "x".join(str(d) for d in dims)
            if compact:
                print(f"  {name} {shape}")
            else:
                print(f"  {name:<20} {shape:<16} {layout:<5} {dtype}  @{offset}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
