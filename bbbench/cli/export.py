"""`bbbench export`: a policy as a self-contained ONNX file with its contract inside."""

from __future__ import annotations

import argparse
from pathlib import Path

from bbbench.cli.common import UsageError, add_contract_options
from bbbench.files import check_output_path
from bbbench.policies import PolicyError, load_policy
from bbbench.policies.onnx import export
from bbbench.policies.onnx.policy import OnnxPolicy
from bbbench.policies.registry import BUILTIN_POLICIES, REFERENCE_POLICY, TERRAIN_POLICIES
from bbbench.tasks.suite import spec


def add_parser(commands) -> None:
    export = commands.add_parser(
        "export",
        help="write a policy as ONNX with its contract inside, for bbbench eval and the board",
        description="Write POLICY as one ONNX file with its contract (observation width, "
        "action space, algorithm, training steps) in its metadata_props. A stable-baselines3 "
        ".zip is written as the graph of the layers bbbench runs, its VecNormalize statistics "
        "folded in, and plays the zip's episodes byte for byte (checked before writing). An "
        "ONNX file from another library (RLlib's export_policy_model, Isaac Lab's "
        "policy.onnx) keeps the one output that acts and gets the contract, from "
        "--observation and --action-space.",
    )
    export.add_argument("policy", metavar="POLICY", help="a stable-baselines3 .zip or a .onnx")
    export.add_argument("--out", required=True, metavar="OUT", help="the .onnx file to write")
    export.add_argument(
        "--vecnormalize",
        metavar="PKL",
        help="a zip's VecNormalize statistics; found on its own where rl-zoo3 saves them",
    )
    export.add_argument("--task", metavar="ID", help="the task it was trained on (recorded)")
    export.add_argument("--algorithm", help="what trained it, for the board (a zip: its own)")
    export.add_argument(
        "--training-steps",
        type=int,
        metavar="N",
        help="its training budget in world steps (a multi-bot world step moves every bot once)",
    )
    export.add_argument(
        "--output", metavar="NAME", help="an ONNX file's output that acts (default: the first)"
    )
    add_contract_options(export)
    export.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    try:
        if Path(args.out).suffix.lower() != ".onnx":
            raise ValueError(f"--out {args.out}: an ONNX file is written as .onnx")
        check_output_path(args.out, "--out")
        shipped = {"reference": REFERENCE_POLICY, **TERRAIN_POLICIES}
        args.policy = str(shipped.get(args.policy, args.policy))
        if args.policy in BUILTIN_POLICIES:
            raise ValueError(
                f"{args.policy!r} is a built-in controller, not a network: score it by name"
            )
        if Path(args.out).resolve() == Path(args.policy).resolve():
            raise ValueError(f"--out {args.out}: the policy itself; write another file")
        if args.training_steps is not None and args.training_steps < 0:
            raise ValueError(f"--training-steps {args.training_steps}: a whole number >= 0")
        if args.task is not None:
            spec(args.task)
        if Path(args.policy).suffix.lower() == ".onnx":
            if args.vecnormalize is not None:
                raise ValueError("--vecnormalize is for a zip; an ONNX graph normalizes inside")
            path = export.export_foreign(
                args.policy,
                args.out,
                observation=args.observation,
                action_space=args.action_space,
                algorithm=args.algorithm,
                training_steps=args.training_steps,
                task=args.task,
                output=args.output,
            )
        else:
            if args.observation is not None or args.action_space is not None:
                raise ValueError("--observation and --action-space are for an ONNX file")
            if args.output is not None:
                raise ValueError("--output names an ONNX file's output")
            policy = load_policy(args.policy, vecnormalize=args.vecnormalize)
            path = export.export_zip(
                policy, args.out, task_id=args.task, training_steps=args.training_steps
            )
        written = OnnxPolicy(path)
    except (PolicyError, ValueError) as error:
        raise UsageError(str(error)) from None
    print(
        f"wrote {path}: {written.algorithm}, {written.spaces_text()}, SHA-256 "
        f"{written.sha256[:16]}..."
    )
