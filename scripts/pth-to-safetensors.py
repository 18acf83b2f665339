"""Converts a PyTorch state dict saved in the legacy (pre-1.6, non-zip) format to .safetensors,
without torch: the pickle is read with its tensor and storage classes stood in for, and each
tensor's elements are gathered from its storage by its strides (the EfficientNet-Lite0 weights'
convolutions are strided views of TensorFlow's layouts).

Usage: python3 scripts/pth-to-safetensors.py IN.pth OUT.safetensors
"""
import itertools
import json
import pickle
import struct
import sys
from collections import OrderedDict

# torch's storage classes: safetensors' dtype name and the element size.
DTYPES = {
    "FloatStorage": ("F32", 4),
    "DoubleStorage": ("F64", 8),
    "HalfStorage": ("F16", 2),
    "LongStorage": ("I64", 8),
    "IntStorage": ("I32", 4),
}
LEGACY_MAGIC = 0x1950A86A20F9469CFC6C
LEGACY_PROTOCOL = 1001


class Storage:
    def __init__(self, kind, size):
        self.kind, self.size, self.data = kind, size, None


class StorageType:
    def __init__(self, name):
        self.name = name


class TensorView:
    def __init__(self, storage, offset, shape, stride):
        self.storage, self.offset = storage, offset
        self.shape, self.stride = tuple(shape), tuple(stride)

    def row_major(self):
        """The elements' bytes in row-major order."""
        size = DTYPES[self.storage.kind][1]
        count, expected = 1, []
        for dim in reversed(self.shape):
            expected.insert(0, count)
            count *= dim
        strides = [s for s, d in zip(self.stride, self.shape) if d > 1]
        if strides == [e for e, d in zip(expected, self.shape) if d > 1]:
            return self.storage.data[self.offset * size : (self.offset + count) * size]
        data = memoryview(self.storage.data)
        out = bytearray()
        for index in itertools.product(*(range(d) for d in self.shape)):
            at = self.offset + sum(i * s for i, s in zip(index, self.stride))
            out += data[at * size : (at + 1) * size]
        return bytes(out)


def rebuild_tensor(storage, offset, shape, stride, *_):
    return TensorView(storage, offset, shape, stride)


class LegacyUnpickler(pickle.Unpickler):
    def __init__(self, file):
        super().__init__(file)
        self.storages = {}

    def find_class(self, module, name):
        if module == "torch._utils" and name in ("_rebuild_tensor", "_rebuild_tensor_v2"):
            return rebuild_tensor
        if module == "torch" and name in DTYPES:
            return StorageType(name)
        if module == "collections" and name == "OrderedDict":
            return OrderedDict
        raise pickle.UnpicklingError(f"unexpected class {module}.{name}")

    def persistent_load(self, saved_id):
        typename, storage_type, key, _location, size, view = saved_id
        if typename != "storage" or view is not None:
            raise pickle.UnpicklingError(f"unexpected persistent id {saved_id!r}")
        return self.storages.setdefault(key, Storage(storage_type.name, size))


def read_legacy(path):
    with open(path, "rb") as f:
        if pickle.load(f) != LEGACY_MAGIC:
            sys.exit(f"{path}: not a legacy PyTorch file")
        if pickle.load(f) != LEGACY_PROTOCOL:
            sys.exit(f"{path}: unknown protocol")
        pickle.load(f)  # system information
        unpickler = LegacyUnpickler(f)
        state = unpickler.load()
        for key in pickle.load(f):
            storage = unpickler.storages[key]
            (count,) = struct.unpack("<q", f.read(8))
            storage.data = f.read(count * DTYPES[storage.kind][1])
    return state


def write_safetensors(state, path):
    header, chunks, offset = {}, [], 0
    for name, tensor in state.items():
        raw = tensor.row_major()
        dtype = DTYPES[tensor.storage.kind][0]
        header[name] = {"dtype": dtype, "shape": list(tensor.shape),
                        "data_offsets": [offset, offset + len(raw)]}
        chunks.append(raw)
        offset += len(raw)
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 8)
    with open(path, "wb") as out:
        out.write(struct.pack("<Q", len(text)))
        out.write(text)
        for chunk in chunks:
            out.write(chunk)


if __name__ == "__main__":
    source, target = sys.argv[1:3]
    write_safetensors(read_legacy(source), target)
