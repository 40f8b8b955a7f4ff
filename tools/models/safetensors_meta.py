"""Reading and writing safetensors files for the tools: the JSON header (the model's metadata), rewritten with the
tensors copied byte for byte, as the tools that stamp measurements into model files do; and whole files of tensors
(average_weights.py, the fuzz seeds). Files are replaced atomically."""
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


def read_tensors(path):
    """A file's metadata and its tensors as {name: (dtype, shape, raw little-endian bytes)}."""
    header, data = read_header(path)
    tensors = {}
    for name, info in header.items():
        if name != "__metadata__":
            begin, end = info["data_offsets"]
            tensors[name] = (info["dtype"], tuple(info["shape"]), data[begin:end])
    return header.get("__metadata__", {}), tensors


def write_tensors(path, metadata, tensors):
    """Writes the metadata and {name: (dtype, shape, raw bytes)} (in name order) as a safetensors file."""
    header, blobs, offset = {"__metadata__": metadata}, [], 0
    for name in sorted(tensors):
        dtype, shape, raw = tensors[name]
        header[name] = {"dtype": dtype, "shape": list(shape), "data_offsets": [offset, offset + len(raw)]}
        blobs.append(raw)
        offset += len(raw)
    write_header(path, header, b"".join(blobs))


def metadata(path):
    with open(path, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        return json.loads(f.read(n)).get("__metadata__", {})


if __name__ == "__main__":
    # /usr/bin/python3 tools/models/safetensors_meta.py MODEL: the metadata, JSON-valued entries expanded.
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
