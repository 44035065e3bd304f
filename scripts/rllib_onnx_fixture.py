"""Write tests/data/rllib_flatbalance.onnx: an RLlib PPO policy on FlatBalance-v1, exported
by RLlib's own `Policy.export_model(onnx=17)`, kept as RLlib wrote it.

Runs where ray[rllib] is installed (`pip install -e ".[rllib]" onnx`: .ci/run's rllib
environment). The file has RLlib's two inputs (`obs`, `state_ins`) and two outputs
(`output`, `state_outs`); `bbbench export` keeps the acting one and adds the contract:

    bbbench export tests/data/rllib_flatbalance.onnx --out policy.onnx --output output \\
        --observation 5 --action-space "Discrete(9)" --algorithm PPO

    python scripts/rllib_onnx_fixture.py [--out PATH] [--iterations N]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

FIXTURE = Path(__file__).resolve().parents[1] / "tests" / "data" / "rllib_flatbalance.onnx"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=FIXTURE)
    parser.add_argument("--iterations", type=int, default=1)
    args = parser.parse_args()

    import ray
    from ray.rllib.algorithms.ppo import PPOConfig

    import bbbench  # noqa: F401 (registers the bbbench/ task IDs)

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    config = (
        PPOConfig()
        # export_model(onnx=...) is the old API stack's (Policy) export.
        .api_stack(enable_rl_module_and_learner=False, enable_env_runner_and_connector_v2=False)
        .environment("bbbench/FlatBalance-v1")
        .framework("torch")
        .env_runners(num_env_runners=0, rollout_fragment_length=200)
        .training(
            train_batch_size=400,
            minibatch_size=100,
            num_epochs=2,
            model={"fcnet_hiddens": [32, 32]},
        )
        .debugging(seed=0)
    )
    algo = config.build()
    for _ in range(args.iterations):
        algo.train()
    with tempfile.TemporaryDirectory() as folder:
        algo.get_policy().export_model(folder, onnx=17)
        shutil.copyfile(Path(folder) / "model.onnx", args.out)
    algo.stop()
    ray.shutdown()
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
