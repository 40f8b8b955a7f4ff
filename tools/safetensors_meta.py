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
    # --set KEY=VALUE (repeatable) rewrites entries instead, e.g. --set name=base to ship a run under its
    # family's name (the name is what tables and the viewer show).
    import argparse
    p = argparse.ArgumentParser(description="Shows (or with --set, rewrites) a model file's metadata.")
    p.add_argument("model")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    a = p.parse_args()
    if a.set:
        header, data = read_header(a.model)
        for item in a.set:
            key, sep, value = item.partition("=")
            if not sep or not key:
                p.error(f"--set {item}: expected KEY=VALUE")
            header.setdefault("__metadata__", {})[key] = value
        write_header(a.model, header, data)
    meta = metadata(a.model)
    for key, value in meta.items():
        try:
            meta[key] = json.loads(value) if value[:1] in "[{" else value
        except ValueError:
            pass
    print(json.dumps(meta, indent=2, sort_keys=True))
