"""Read an ONNX policy without trusting it: plain facts and numpy constants.

ONNX is a protobuf: a graph of named operators with its weights inside, data
and not code. `onnx.load` follows paths to external weight files (and has had
path-traversal CVEs doing so); bbbench never calls it. It parses the bytes with
the protobuf class alone, which touches no file, and then checks, before any
tensor is decoded:

- the file's size (`MAX_FILE_BYTES`), and that it is a model: a zip renamed
  `.onnx` or random bytes are refused by name;
- only the default operator domain, at an opset in `OPSETS`; no functions,
  training info, sparse tensors or subgraphs (`Loop`, `If`, `Scan` and any
  graph-valued attribute);
- at most `MAX_NODES` nodes, each an operator of `bbbench.policies.onnx.interpreter`'s
  set (any other is refused by name);
- no external data: every weight inside the file ("export with external_data=False");
- every tensor's declared size counts against `MAX_PARAMETERS` (the zips' cap),
  and its bytes must be exactly what its shape and type declare;
- weights float32 (float16, bfloat16 and float64 kept as their values, cast to
  float32 where a float32 layer uses them, as for zips), index tensors int64 or
  int32; finite;
- one graph input, float32 of shape (batch, width), and one output; or, for a
  recurrent policy, two of each: the observation and the state in, the action and the
  next state out (`bbbench.policies.onnx.contract`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from pathlib import Path
from typing import Any

import numpy as np

from bbbench.policies.archive import read_file
from bbbench.policies.errors import PolicyError, RefusedForSafety
from bbbench.policies.file_policy import MAX_PARAMETERS
from bbbench.policies.onnx.operators import OPERATORS, TABLE
from bbbench.portable import total

MAX_FILE_BYTES = 64 * 2**20  # 10M float32 parameters are 40 MB
MAX_NODES = 1000
OPSETS = range(11, 24)  # ai.onnx 11 to 23: Clip's bounds are inputs from 11 on
MAX_INDEX_ELEMENTS = 4096  # shapes, axes and indices are small

# TensorProto.DataType values bbbench reads, and their numpy type.
FLOAT, INT32, INT64, FLOAT16, DOUBLE, BFLOAT16 = 1, 6, 7, 10, 11, 16
_NUMPY = {FLOAT: "<f4", INT32: "<i4", INT64: "<i8", FLOAT16: "<f2", DOUBLE: "<f8", BFLOAT16: "<u2"}
_TYPE_NAMES = {
    1: "float32", 2: "uint8", 3: "int8", 4: "uint16", 5: "int16", 6: "int32", 7: "int64",
    8: "string", 9: "bool", 10: "float16", 11: "float64", 12: "uint32", 13: "uint64",
    14: "complex64", 15: "complex128", 16: "bfloat16",
}  # fmt: skip
_SUBGRAPH_OPERATORS = ("Loop", "If", "Scan")
EXPORT_HINT = "export it again with external_data=False (torch.onnx.export's keyword)"


def check_safety(model, where: str) -> int:
    """What bbbench refuses in any ONNX file it reads, a policy or one `bbbench export`
    converts, before a value is decoded: other operator domains, functions, subgraphs,
    sparse or external tensors, too many nodes, and tensors that declare more values
    than `MAX_PARAMETERS` all together (used or not). Its opset; `RefusedForSafety` (or
    `PolicyError`) if refused."""
    opset = _opset(where, model)
    if model.functions:
        raise RefusedForSafety(
            f"{where}: it defines functions ({model.functions[0].name}); bbbench runs plain "
            f"graphs only"
        )
    graph = model.graph
    if graph.sparse_initializer:
        raise PolicyError(f"{where}: sparse initializers; bbbench reads dense float32 weights")
    if len(graph.node) > MAX_NODES:
        raise RefusedForSafety(
            f"{where}: {len(graph.node)} nodes, more than the {MAX_NODES} bbbench runs"
        )
    tensors = [(t.name or "(unnamed)", t) for t in graph.initializer]
    declared = 0
    for node in graph.node:
        _check_node(where, node)
        tensors += [(node.output[0], a.t) for a in node.attribute if a.type == a.TENSOR]
        declared += total(len(a.floats) + len(a.ints) + len(a.strings) for a in node.attribute)
    for tensor_name, tensor in tensors:  # every size and location before any value is decoded
        declared += _check_tensor(where, tensor_name, tensor)
        if declared > MAX_PARAMETERS:
            raise RefusedForSafety(
                f"{where}: its tensors declare more than {MAX_PARAMETERS:,} values (at "
                f"{tensor_name!r}, shape {list(tensor.dims)}); bbbench evaluates smaller networks"
            )
    return opset


@dataclasses.dataclass(frozen=True)
class Node:
    """One operator of the graph: its type, input and output names, plain attributes."""

    op: str
    inputs: tuple[str, ...]  # "" where an optional input is left out
    outputs: tuple[str, ...]
    attributes: dict[str, Any]


@dataclasses.dataclass(frozen=True, eq=False)
class OnnxModel:
    """What an ONNX file holds, read safely."""

    name: str
    sha256: str
    opset: int
    metadata: dict[str, str]
    nodes: tuple[Node, ...]
    constants: dict[str, np.ndarray]  # initializers (and Constant nodes' values)
    input: str
    input_width: int | None  # declared; None if not
    batched: bool  # the input's first dimension is symbolic: one call for many rows
    output: str
    output_width: int | None
    output_type: int
    # A recurrent policy's second input and output (its state in and out), and the state's
    # declared width; None for a policy without one.
    state_input: str | None = None
    state_output: str | None = None
    state_width: int | None = None


def read_onnx(path: str | Path) -> OnnxModel:
    """An ONNX policy file, read safely; `PolicyError` (or `RefusedForSafety`) if not."""
    path = Path(path)
    content = read_file(path, MAX_FILE_BYTES, "an ONNX model (.onnx)")
    return parse_onnx(content, str(path), path.name)


def parse_proto(content: bytes, where: str):
    """The bytes of an ONNX file as onnx's `ModelProto` (protobuf's parser only: no
    `onnx.load`), with a graph of operators; `PolicyError` if they are not one."""
    import onnx  # lazy: onnx, for ONNX files only

    if content[:4] == b"PK\x03\x04":
        raise PolicyError(
            f"{where}: a zip file, not an ONNX model; a stable-baselines3 model is scored as a .zip"
        )
    model = onnx.ModelProto()
    try:
        model.ParseFromString(content)
    except Exception as error:  # protobuf's DecodeError, or a recursion limit
        raise PolicyError(
            f"{where}: not an ONNX model ({type(error).__name__}: the bytes are no ModelProto; "
            f"truncated?)"
        ) from None
    if not model.HasField("graph") or not model.graph.node or not model.ir_version:
        raise PolicyError(f"{where}: not an ONNX model (no graph of operators; truncated?)")
    return model


def parse_onnx(content: bytes, where: str, name: str) -> OnnxModel:
    """The bytes of an ONNX policy, checked and decoded (`where` names them in errors,
    `name` is the policy's name); `PolicyError` (or `RefusedForSafety`) if not one."""
    model = parse_proto(content, where)
    opset = check_safety(model, where)
    if model.training_info:
        raise PolicyError(f"{where}: it holds training info; export the inference graph only")
    graph = model.graph
    for node in graph.node:
        _check_operator(where, node)
    constants = {t.name: decode(where, t.name, t) for t in graph.initializer}
    nodes = tuple(_node(where, node) for node in graph.node)
    inputs = [i for i in graph.input if i.name not in constants]
    outputs = list(graph.output)
    if len(inputs) not in (1, 2) or len(outputs) != len(inputs):
        raise PolicyError(
            f"{where}: {len(inputs)} graph input(s) and {len(outputs)} output(s) "
            f"({', '.join(i.name for i in inputs)} -> {', '.join(o.name for o in outputs)}); "
            f"a bbbench policy takes one observation and gives one output (a recurrent one "
            f"also takes its state, second, and gives its next state, second)"
        )
    graph_input, graph_output = inputs[0], outputs[0]
    elem, dims = _tensor_type(graph_input)
    if elem != FLOAT:
        raise PolicyError(
            f"{where}: its input {graph_input.name!r} is {_TYPE_NAMES.get(elem, elem)}; bbbench "
            f"observations are float32"
        )
    if dims is not None and len(dims) != 2:
        raise PolicyError(
            f"{where}: its input {graph_input.name!r} has {len(dims)} dimension(s); expected "
            f"(batch, observation width)"
        )
    output_type, output_dims = _tensor_type(graph_output)
    if output_type not in (FLOAT, 0):
        raise PolicyError(
            f"{where}: its output {graph_output.name!r} is "
            f"{_TYPE_NAMES.get(output_type, output_type)}; a bbbench policy outputs float32 "
            f"action scores (Discrete) or actions (Box)"
        )
    state_width = None
    if len(inputs) == 2:
        for tensor, role in ((inputs[1], "state input"), (outputs[1], "state output")):
            kind, shape = _tensor_type(tensor)
            if kind not in (FLOAT, 0) or (shape is not None and len(shape) != 2):
                raise PolicyError(
                    f"{where}: 2 graph input(s) and 2 output(s) ({graph_input.name}, "
                    f"{inputs[1].name} -> {graph_output.name}, {outputs[1].name}), but its "
                    f"{role} {tensor.name!r} is not a recurrent state (float32, (batch, state "
                    f"width)); keep the output that acts with bbbench export --output"
                )
        state_width = _static(_tensor_type(inputs[1])[1], 1)
    return OnnxModel(
        name=name,
        sha256=hashlib.sha256(content).hexdigest(),
        opset=opset,
        metadata={prop.key: prop.value for prop in model.metadata_props},
        nodes=nodes,
        constants=constants,
        input=graph_input.name,
        input_width=_static(dims, 1),
        batched=dims is None or not isinstance(dims[0], int) or dims[0] != 1,
        output=graph_output.name,
        output_width=_static(output_dims, -1),
        output_type=output_type,
        state_input=inputs[1].name if len(inputs) == 2 else None,
        state_output=outputs[1].name if len(outputs) == 2 else None,
        state_width=state_width,
    )


def _opset(path: Path, model) -> int:
    versions = {}
    for entry in model.opset_import:
        if entry.domain not in ("", "ai.onnx"):
            raise RefusedForSafety(
                f"{path}: imports the operator domain {entry.domain!r}; bbbench runs the "
                f"default domain (ai.onnx) only"
            )
        versions[""] = entry.version
    opset = versions.get("")
    if opset not in OPSETS:
        raise PolicyError(
            f"{path}: opset {opset}; bbbench runs opsets {OPSETS.start} to {OPSETS.stop - 1} "
            f"(torch.onnx.export's opset_version)"
        )
    return opset


def _check_node(path: Path, node) -> None:
    if node.domain not in ("", "ai.onnx"):
        raise RefusedForSafety(
            f"{path}: operator {node.domain}.{node.op_type} is outside the default domain; "
            f"bbbench runs ai.onnx operators only"
        )
    if node.op_type in _SUBGRAPH_OPERATORS or any(
        a.type in (a.GRAPH, a.GRAPHS) for a in node.attribute
    ):
        raise RefusedForSafety(
            f"{path}: operator {node.op_type} holds a subgraph; bbbench runs plain graphs "
            f"(no Loop, If or Scan)"
        )
    if not node.output:
        raise PolicyError(f"{path}: operator {node.op_type} with no output")


def _check_operator(path: Path, node) -> None:
    """A node of a policy's graph: an operator of bbbench's set, with one output (a
    recurrent cell's second, its final state, may be named too)."""
    if node.op_type not in OPERATORS:
        raise PolicyError(
            f"{path}: operator {node.op_type!r} is not in bbbench's operator set "
            f"({', '.join(sorted(OPERATORS))})"
        )
    operator = TABLE.get(node.op_type)
    most = 2 if operator is not None and operator.last_output else 1
    if not 1 <= len(node.output) <= most or not node.output[0]:
        raise PolicyError(f"{path}: operator {node.op_type} with {len(node.output)} outputs")


def _check_tensor(path: Path, name: str, tensor) -> int:
    """The tensor's declared number of values, after checking where its data is and how
    it is typed (nothing decoded)."""
    if tensor.data_location == tensor.EXTERNAL or tensor.external_data:
        where = {e.key: e.value for e in tensor.external_data}.get("location", "?")
        raise RefusedForSafety(
            f"{path}: tensor {name!r} keeps its data in the external file {where!r}; bbbench "
            f"never opens other files: {EXPORT_HINT}"
        )
    if tensor.HasField("segment"):
        raise PolicyError(f"{path}: tensor {name!r} is segmented; unsupported")
    if tensor.data_type not in _NUMPY:
        kind = _TYPE_NAMES.get(tensor.data_type, f"type {tensor.data_type}")
        raise PolicyError(
            f"{path}: tensor {name!r} is {kind}; bbbench reads float32 weights (float16, "
            f"bfloat16, float64) and int64 or int32 indices"
        )
    if any(d < 0 for d in tensor.dims):
        raise PolicyError(f"{path}: tensor {name!r} has a negative dimension {list(tensor.dims)}")
    count = math.prod(tensor.dims) if tensor.dims else 1
    if tensor.data_type in (INT32, INT64) and count > MAX_INDEX_ELEMENTS:
        raise RefusedForSafety(f"{path}: integer tensor {name!r} of {count:,} values")
    return count


def _typed_field(tensor):
    if tensor.data_type == FLOAT:
        return tensor.float_data
    if tensor.data_type == DOUBLE:
        return tensor.double_data
    if tensor.data_type == INT64:
        return tensor.int64_data
    return tensor.int32_data  # int32, and float16 and bfloat16 as their bits


def decode(path: Path, name: str, tensor) -> np.ndarray:
    """A checked tensor's values: float32 or float64 (float16 and bfloat16 made float32),
    or int64; `PolicyError` if its data is not exactly what it declares, or not finite."""
    shape = tuple(tensor.dims)
    count = math.prod(shape) if shape else 1
    dtype = np.dtype(_NUMPY[tensor.data_type])
    if tensor.raw_data:
        if len(tensor.raw_data) != count * dtype.itemsize:
            raise PolicyError(
                f"{path}: tensor {name!r} declares shape {list(shape)} "
                f"({count * dtype.itemsize} bytes of {_TYPE_NAMES[tensor.data_type]}) but "
                f"holds {len(tensor.raw_data)} bytes"
            )
        values = np.frombuffer(tensor.raw_data, dtype=dtype)
    else:
        field = _typed_field(tensor)
        if len(field) != count:
            raise PolicyError(
                f"{path}: tensor {name!r} declares shape {list(shape)} ({count} values) but "
                f"holds {len(field)}"
            )
        if tensor.data_type in (FLOAT16, BFLOAT16):
            values = np.array(field, dtype=np.uint32).astype(np.uint16).view(dtype)
        else:
            values = np.array(field, dtype=dtype)
    if tensor.data_type == BFLOAT16:  # its bits are float32's upper half
        values = (values.astype(np.uint32) << 16).view(np.float32)
    elif tensor.data_type == FLOAT16:
        values = values.astype(np.float32)
    elif tensor.data_type == INT32:
        values = values.astype(np.int64)
    values = values.astype(values.dtype.newbyteorder("="), copy=True).reshape(shape)
    if values.dtype.kind == "f" and not np.isfinite(values).all():
        raise PolicyError(f"{path}: tensor {name!r} holds NaN or infinite values")
    return values


def _node(path: Path, node) -> Node:
    attributes = {}
    for a in node.attribute:
        if a.type == a.FLOAT:
            attributes[a.name] = float(a.f)
        elif a.type == a.INT:
            attributes[a.name] = int(a.i)
        elif a.type == a.STRING:
            attributes[a.name] = a.s.decode("utf-8", "replace")
        elif a.type == a.INTS:
            attributes[a.name] = tuple(int(v) for v in a.ints)
        elif a.type == a.FLOATS:
            attributes[a.name] = tuple(float(v) for v in a.floats)
        elif a.type == a.STRINGS:  # GRU's activations
            attributes[a.name] = tuple(v.decode("utf-8", "replace") for v in a.strings)
        elif a.type == a.TENSOR:
            attributes[a.name] = decode(path, node.output[0], a.t)
        else:
            raise PolicyError(
                f"{path}: operator {node.op_type}'s attribute {a.name!r} is of a kind bbbench "
                f"does not read"
            )
    return Node(node.op_type, tuple(node.input), tuple(node.output), attributes)


def _tensor_type(value) -> tuple[int, list | None]:
    """(element type, dims or None) of a graph input or output; a dim is an int, or its
    symbolic name."""
    if not value.type.HasField("tensor_type"):
        return -1, None
    tensor_type = value.type.tensor_type
    if not tensor_type.HasField("shape"):
        return tensor_type.elem_type, None
    dims = [
        d.dim_value if d.HasField("dim_value") else (d.dim_param or "?")
        for d in tensor_type.shape.dim
    ]
    return tensor_type.elem_type, dims


def _static(dims: list | None, index: int) -> int | None:
    if not dims:
        return None
    value = dims[index]
    return value if isinstance(value, int) and value > 0 else None
