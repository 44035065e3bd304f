"""A hostile corpus of ONNX files: each is refused with exit code 2 and one line, before
any episode is played, with nothing written."""

from __future__ import annotations

import io
import itertools
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from onnx import AttributeProto, TensorProto, helper, numpy_helper

from bbbench import evaluation
from bbbench.cli import main

FLAT = "bbbench/FlatBalance-v1"
CONTRACT = {"bbbench.observation": "5", "bbbench.action_space": "Discrete(9)"}


def tensor(name: str, values) -> TensorProto:
    return numpy_helper.from_array(np.asarray(values, dtype=np.float32), name)


def layer_graph(nodes=None, initializers=None, inputs=None, outputs=None, **extra):
    """obs (batch, 5) -> Gemm -> scores (batch, 9), or what is given instead."""
    nodes = nodes or [helper.make_node("Gemm", ["obs", "w", "b"], ["scores"])]
    if initializers is None:
        initializers = [tensor("w", np.full((5, 9), 0.1)), tensor("b", np.zeros(9))]
    inputs = inputs or [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", 5])]
    outputs = outputs or [helper.make_tensor_value_info("scores", TensorProto.FLOAT, ["batch", 9])]
    return helper.make_graph(nodes, "hostile", inputs, outputs, initializers, **extra)


def model_bytes(graph=None, opset: int = 17, props=None, domain: str = "", **fields) -> bytes:
    opsets = [helper.make_opsetid(domain, opset)]
    model = helper.make_model(graph or layer_graph(), opset_imports=opsets, **fields)
    helper.set_model_props(model, CONTRACT if props is None else props)
    return model.SerializeToString()


def external(location: str) -> bytes:
    weight = tensor("w", np.full((5, 9), 0.1))
    weight.ClearField("raw_data")
    weight.data_location = TensorProto.EXTERNAL
    entry = weight.external_data.add()
    entry.key, entry.value = "location", location
    return model_bytes(layer_graph(initializers=[weight, tensor("b", np.zeros(9))]))


def declared(dims, raw: bytes) -> bytes:
    weight = TensorProto(name="w", data_type=TensorProto.FLOAT, dims=dims, raw_data=raw)
    return model_bytes(layer_graph(initializers=[weight, tensor("b", np.zeros(9))]))


def declared_unused() -> bytes:
    """A valid graph beside a tensor nothing reads that declares 10^10 values."""
    unused = TensorProto(
        name="unused", data_type=TensorProto.FLOAT, dims=[100_000, 100_000], raw_data=b"\0" * 16
    )
    weights = [tensor("w", np.full((5, 9), 0.1)), tensor("b", np.zeros(9)), unused]
    return model_bytes(layer_graph(initializers=weights))


def op(op_type: str, **attributes) -> bytes:
    node = helper.make_node(op_type, ["obs"], ["scores"], **attributes)
    return model_bytes(layer_graph(nodes=[node]))


def gemm(**attributes) -> bytes:
    node = helper.make_node("Gemm", ["obs", "w", "b"], ["scores"], **attributes)
    return model_bytes(layer_graph(nodes=[node]))


def weights_of(value: float) -> bytes:
    return model_bytes(
        layer_graph(initializers=[tensor("w", np.full((5, 9), value)), tensor("b", np.zeros(9))])
    )


def subgraph(op_type: str) -> bytes:
    body = layer_graph()
    attribute = {"If": "then_branch", "Loop": "body", "Scan": "body"}[op_type]
    node = helper.make_node(op_type, ["obs"], ["scores"], **{attribute: body})
    return model_bytes(layer_graph(nodes=[node]))


def with_function() -> bytes:
    function = helper.make_function(
        "custom", "Scale", ["x"], ["y"], [helper.make_node("Relu", ["x"], ["y"])],
        [helper.make_opsetid("", 17)],
    )  # fmt: skip
    node = helper.make_node("Scale", ["obs"], ["scores"], domain="custom")
    model = helper.make_model(
        layer_graph(nodes=[node]),
        opset_imports=[helper.make_opsetid("", 17)],
        functions=[function],
    )
    helper.set_model_props(model, CONTRACT)
    return model.SerializeToString()


def identity_chain(count: int) -> bytes:
    nodes = [helper.make_node("Gemm", ["obs", "w", "b"], ["x0"])]
    nodes += [helper.make_node("Identity", [f"x{i}"], [f"x{i + 1}"]) for i in range(count)]
    nodes[-1].output[0] = "scores"
    return model_bytes(layer_graph(nodes=nodes))


def renamed_zip() -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("data", "{}")
    return buffer.getvalue()


def two_inputs() -> bytes:
    inputs = [
        helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", 5]),
        helper.make_tensor_value_info("state_ins", TensorProto.FLOAT, ["batch"]),
    ]
    return model_bytes(layer_graph(inputs=inputs))


def two_outputs() -> bytes:
    nodes = [
        helper.make_node("Gemm", ["obs", "w", "b"], ["scores"]),
        helper.make_node("Relu", ["scores"], ["more"]),
    ]
    outputs = [
        helper.make_tensor_value_info("scores", TensorProto.FLOAT, ["batch", 9]),
        helper.make_tensor_value_info("more", TensorProto.FLOAT, ["batch", 9]),
    ]
    return model_bytes(layer_graph(nodes=nodes, outputs=outputs))


def output_of(kind: int, width: int = 9) -> bytes:
    outputs = [helper.make_tensor_value_info("scores", kind, ["batch", width])]
    return model_bytes(layer_graph(outputs=outputs))


def wider_input() -> bytes:
    inputs = [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", 7])]
    initializers = [tensor("w", np.full((7, 9), 0.1)), tensor("b", np.zeros(9))]
    return model_bytes(layer_graph(inputs=inputs, initializers=initializers))


def narrower_output() -> bytes:
    """Three scores, undeclared, where the contract's Discrete(9) wants nine."""
    initializers = [tensor("w", np.full((5, 3), 0.1)), tensor("b", np.zeros(3))]
    outputs = [helper.make_tensor_value_info("scores", TensorProto.FLOAT, None)]
    return model_bytes(layer_graph(initializers=initializers, outputs=outputs))


def integer_arithmetic() -> bytes:
    nodes = [
        helper.make_node("Shape", ["obs"], ["shape"]),
        helper.make_node("Add", ["shape", "shape"], ["twice"]),
        helper.make_node("Gemm", ["obs", "w", "b"], ["scores"]),
    ]
    return model_bytes(layer_graph(nodes=nodes))


def out_of_order() -> bytes:
    nodes = [
        helper.make_node("Relu", ["hidden"], ["scores"]),
        helper.make_node("Gemm", ["obs", "w", "b"], ["hidden"]),
    ]
    return model_bytes(layer_graph(nodes=nodes))


def graph_attribute() -> bytes:
    node = helper.make_node("Relu", ["obs"], ["scores"])
    attribute = node.attribute.add()
    attribute.name, attribute.type = "hidden", AttributeProto.GRAPH
    attribute.g.CopyFrom(layer_graph())
    return model_bytes(layer_graph(nodes=[node]))


def typed_field_lies() -> bytes:
    weight = TensorProto(name="w", data_type=TensorProto.FLOAT, dims=[5, 9])
    weight.float_data.extend([0.1] * 10)
    return model_bytes(layer_graph(initializers=[weight, tensor("b", np.zeros(9))]))


def string_tensor() -> bytes:
    text = helper.make_tensor("b", TensorProto.STRING, [1], [b"rm -rf /"])
    return model_bytes(layer_graph(initializers=[tensor("w", np.full((5, 9), 0.1)), text]))


def sparse() -> bytes:
    values = tensor("w_values", [1.0])
    indices = numpy_helper.from_array(np.array([0], dtype=np.int64), "w_indices")
    matrix = helper.make_sparse_tensor(values, indices, [5, 9])
    graph = layer_graph(initializers=[tensor("b", np.zeros(9))])
    graph.sparse_initializer.append(matrix)
    return model_bytes(graph)


def input_of(kind: int) -> bytes:
    inputs = [helper.make_tensor_value_info("obs", kind, ["batch", 5])]
    return model_bytes(layer_graph(inputs=inputs))


def training_info() -> bytes:
    model = helper.make_model(layer_graph(), opset_imports=[helper.make_opsetid("", 17)])
    model.training_info.add()
    helper.set_model_props(model, CONTRACT)
    return model.SerializeToString()


def doubling(source: str, count: int = 60) -> bytes:
    """A dead branch of Concats, each doubling the last: 2**60 values if run."""
    nodes = [helper.make_node("Gemm", ["obs", "w", "b"], ["scores"])]
    if source == "k0":
        nodes.append(helper.make_node("Constant", [], ["k0"], value_floats=[1.0]))
    names = [source] + [f"d{i}" for i in range(count)]
    for a, b in itertools.pairwise(names):
        nodes.append(helper.make_node("Concat", [a, a], [b], axis=-1))
    return model_bytes(layer_graph(nodes=nodes))


def valid() -> bytes:
    return model_bytes()


# (name, the file's bytes, a fragment of the one-line error)
CORPUS: list[tuple[str, Callable[[], bytes], str]] = [
    ("random-bytes", lambda: np.random.default_rng(0).bytes(4096), "not an ONNX model"),
    ("empty", lambda: b"", "not an ONNX model"),
    ("truncated", lambda: valid()[: len(valid()) // 2], "not an ONNX model"),
    ("zip-renamed", renamed_zip, "a zip file, not an ONNX model"),
    ("external-relative", lambda: external("weights.bin"), "external_data=False"),
    ("external-absolute", lambda: external("/etc/passwd"), "external_data=False"),
    ("external-traversal", lambda: external("../../secret.bin"), "external_data=False"),
    ("declared-1e10", lambda: declared([100_000, 100_000], b"\0" * 16), "10,000,000"),
    ("declared-1e10-unused", declared_unused, "10,000,000"),
    ("shape-lies", lambda: declared([5, 9], b"\0" * 4), "declares shape [5, 9]"),
    ("typed-field-lies", typed_field_lies, "declares shape [5, 9]"),
    ("unknown-operator", lambda: op("FooBar"), "'FooBar' is not in bbbench's operator set"),
    ("softmax", lambda: op("Softmax"), "'Softmax' is not in bbbench's operator set"),
    (
        "com-microsoft",
        lambda: model_bytes(
            layer_graph(
                nodes=[helper.make_node("FusedGemm", ["obs"], ["scores"], domain="com.microsoft")]
            )
        ),
        "outside the default domain",
    ),
    ("com-microsoft-opset", lambda: model_bytes(domain="com.microsoft", opset=1), "domain"),
    ("opset-99", lambda: model_bytes(opset=99), "opset 99"),
    ("opset-9", lambda: model_bytes(opset=9), "opset 9"),
    ("loop", lambda: subgraph("Loop"), "subgraph"),
    ("if", lambda: subgraph("If"), "subgraph"),
    ("scan", lambda: subgraph("Scan"), "subgraph"),
    ("graph-attribute", graph_attribute, "subgraph"),
    ("function", with_function, "functions"),
    ("two-inputs", two_inputs, "2 graph input(s)"),
    ("two-outputs", two_outputs, "2 output(s)"),
    ("wrong-width", wider_input, "is 7 wide"),
    ("output-disagrees", lambda: output_of(TensorProto.FLOAT, 3), "is 3 wide"),
    ("output-undeclared-3", narrower_output, "disagrees with the contract"),
    ("int64-output", lambda: output_of(TensorProto.INT64), "int64"),
    ("float64-input", lambda: input_of(TensorProto.DOUBLE), "float64"),
    ("gemm-alpha", lambda: gemm(alpha=2.0), "alpha and beta must be 1"),
    ("gemm-beta", lambda: gemm(beta=0.5), "alpha and beta must be 1"),
    ("gemm-trans-a", lambda: gemm(transA=1), "transA=1"),
    ("nan-weights", lambda: weights_of(np.nan), "NaN or infinite"),
    ("inf-weights", lambda: weights_of(np.inf), "NaN or infinite"),
    ("10000-nodes", lambda: identity_chain(10_000), "10001 nodes"),
    ("concat-doubling", lambda: doubling("obs"), "more than the 1,000,000 a row"),
    ("constant-doubling", lambda: doubling("k0"), "more than the 1,000,000 a row"),
    ("integer-arithmetic", integer_arithmetic, "integers"),
    ("out-of-order", out_of_order, "topological order"),
    ("string-tensor", string_tensor, "is string"),
    ("sparse", sparse, "sparse"),
    ("training-info", training_info, "training info"),
    ("no-contract", lambda: model_bytes(props={}), "--action-space SPACE"),
    (
        "bad-action-space",
        lambda: model_bytes(props={**CONTRACT, "bbbench.action_space": "Discrete(banana)"}),
        "not an action space",
    ),
    (
        "unknown-key",
        lambda: model_bytes(props={**CONTRACT, "bbbench.exec": "import os"}),
        "unknown metadata key",
    ),
    (
        "task-unknown",
        lambda: model_bytes(props={**CONTRACT, "bbbench.task": "bbbench/Nope-v0"}),
        "unknown task 'bbbench/Nope-v0'",
    ),
    (
        "task-it-cannot-play",
        lambda: model_bytes(props={**CONTRACT, "bbbench.task": "bbbench/BeamCarry-v0"}),
        "trained on bbbench/BeamCarry-v0, which it cannot play",
    ),
    (
        "steps-1e40",
        lambda: model_bytes(props={**CONTRACT, "bbbench.training_steps": "9" * 40}),
        "must be a whole number from 0 to 10,000,000,000,000",
    ),
    (
        "contract-width-0",
        lambda: model_bytes(props={**CONTRACT, "bbbench.observation": "0"}),
        "not an observation width",
    ),
]


def test_the_corpus_is_at_least_thirty_files():
    assert len(CORPUS) >= 30
    assert len({name for name, _, _ in CORPUS}) == len(CORPUS)


def test_the_valid_file_the_corpus_breaks_is_scored(tmp_path, capsys):
    path = tmp_path / "valid.onnx"
    path.write_bytes(valid())
    assert main(["eval", str(path), "--task", FLAT, "--episodes", "1", "--workers", "1"]) == 0


@pytest.mark.parametrize(("name", "make", "fragment"), CORPUS, ids=[c[0] for c in CORPUS])
def test_a_hostile_file_is_one_line_and_exit_2_before_any_episode(
    tmp_path, capsys, monkeypatch, name, make, fragment
):
    def never(*args, **kwargs):
        raise AssertionError("an episode was played")

    monkeypatch.setattr(evaluation, "evaluate", never)
    path = tmp_path / f"{name}.onnx"
    path.write_bytes(make())
    out = tmp_path / "results.json"
    argv = ["eval", str(path), "--task", FLAT, "--episodes", "1", "--json", str(out)]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1, err
    assert fragment in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


def test_a_file_over_the_size_cap_is_refused_unread(tmp_path, capsys, monkeypatch):
    from bbbench.policies.onnx import reader as onnx_file

    monkeypatch.setattr(onnx_file, "MAX_FILE_BYTES", 1000)
    path = tmp_path / "big.onnx"
    path.write_bytes(valid() + b"\0" * 1000)
    code = main(["eval", str(path), "--task", FLAT, "--episodes", "1"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "refused for safety" in err
    assert "more than the 1000 bytes" in err


def test_external_data_is_never_opened(tmp_path, capsys, monkeypatch):
    import builtins

    secret = tmp_path / "weights.bin"
    secret.write_bytes(np.full((5, 9), 0.1, dtype=np.float32).tobytes())
    path = tmp_path / "external.onnx"
    path.write_bytes(external("weights.bin"))
    opened = []
    real_open = builtins.open

    def watch(file, *args, **kwargs):
        opened.append(str(file))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", watch)
    assert main(["eval", str(path), "--task", FLAT, "--episodes", "1"]) == 2
    assert str(secret) not in opened
    assert Path(path).exists()


@pytest.mark.parametrize(
    ("name", "make", "fragment"),
    [c for c in CORPUS if c[0] in ("declared-1e10-unused", "external-traversal", "function")],
    ids=lambda value: value if isinstance(value, str) else "",
)
def test_export_refuses_what_eval_refuses_even_where_it_would_drop_it(
    tmp_path, capsys, name, make, fragment
):
    path = tmp_path / f"{name}.onnx"
    path.write_bytes(make())
    code = main(["export", str(path), "--out", str(tmp_path / "out.onnx")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1, err
    assert fragment in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


def test_export_refuses_a_task_the_policy_cannot_play(tmp_path, capsys):
    path = tmp_path / "mlp5.onnx"
    path.write_bytes(valid())
    out = tmp_path / "out.onnx"
    code = main(["export", str(path), "--out", str(out), "--task", "bbbench/BeamCarry-v0"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "trained on bbbench/BeamCarry-v0, which it cannot play" in err
    assert not out.exists()
