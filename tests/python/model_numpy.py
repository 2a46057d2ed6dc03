"""Our model and SHAP files read with numpy alone: an independent forward pass of a model
written by `causal-arm train`, and the tensors of `shap_values.safetensors`."""

import json
import pathlib
import struct

import numpy as np

_DTYPES = {"F32": "<f4", "F64": "<f8", "U32": "<u4", "U64": "<u8", "I64": "<i8"}


def load_safetensors(path: pathlib.Path, with_metadata: bool = False):
    """Reads a safetensors file (u64 header size, JSON header, data); F32 tensors come back
    as float64 arrays, others in their own type."""
    raw = pathlib.Path(path).read_bytes()
    (size,) = struct.unpack("<Q", raw[:8])
    header = json.loads(raw[8:8 + size])
    data = raw[8 + size:]
    out = {}
    for name, info in header.items():
        if name == "__metadata__":
            continue
        start, end = info["data_offsets"]
        array = np.frombuffer(data[start:end], dtype=_DTYPES[info["dtype"]]).reshape(info["shape"])
        out[name] = array.astype(np.float64) if info["dtype"] == "F32" else array
    if with_metadata:
        return out, header.get("__metadata__", {})
    return out


def numpy_predict(model_dir: pathlib.Path, name: str, inputs: np.ndarray) -> np.ndarray:
    """The model's prediction from its files alone: standardise, tanh layers, linear,
    un-standardise, add the offset columns (delta forward model). Euler angles are not
    wrapped (what SHAP explains)."""
    model_dir = pathlib.Path(model_dir)
    meta = json.loads((model_dir / f"{name}.json").read_text())
    t = load_safetensors(model_dir / f"{name}.safetensors")
    h = (inputs - t["input.mean"]) / t["input.std"]
    layers = len(meta["architecture"]["hidden"]) + 1
    for i in range(layers):
        h = h @ t[f"layers.{i}.weight"].T + t[f"layers.{i}.bias"]
        if i < layers - 1:
            h = np.tanh(h)
    y = h * t["output.std"] + t["output.mean"]
    offset = meta["problem"]["offset_columns"]
    if offset is not None:
        y = y + inputs[:, offset]
    return y
