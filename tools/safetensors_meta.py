"""Reading and rewriting a safetensors file's JSON header (the model's metadata), for the tools that stamp
measurements into model files. Only the header changes (the tensors are copied byte for byte), and the file is
replaced atomically."""
import json, os, struct, tempfile


def read_header(path):
    with open(path, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        header = json.loads(f.read(n))
        data = f.read()
    return header, data


def write_header(path, header, data):
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 8)  # safetensors pads the header to 8 bytes
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(os.path.abspath(path)), prefix=".stamp-")
    with os.fdopen(fd, "wb") as f:
        f.write(struct.pack("<Q", len(text)) + text + data)
    os.replace(tmp, path)


def metadata(path):
    with open(path, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        return json.loads(f.read(n)).get("__metadata__", {})


if __name__ == "__main__":
    # /usr/bin/python3 tools/safetensors_meta.py MODEL: the metadata, JSON-valued entries expanded.
    import sys
    if len(sys.argv) != 2:
        sys.exit("usage: safetensors_meta.py MODEL.safetensors")
    meta = metadata(sys.argv[1])
    for key, value in meta.items():
        try:
            meta[key] = json.loads(value) if value[:1] in "[{" else value
        except ValueError:
            pass
    print(json.dumps(meta, indent=2, sort_keys=True))
