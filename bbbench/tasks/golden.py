"""Golden rollouts: each task version's behaviour, pinned by hashes stored in the repo.

A task ID's fingerprint hashes its spec together with the hash of a golden
rollout: for each of `GOLDEN_SEEDS`, what the seed generated (the whole target
schedule, sensor errors and terrain), then the observations and rewards of the
fixed action sequence `golden_actions()`, all rounded to `DECIMALS` places. tests/test_versions.py
recomputes both for every registered ID and fails when either differs from
`golden.json`: a behaviour change needs a new version (`-v1`), and the old one
stays registered.

    python -m bbbench.tasks.golden           # print the hashes as they are now
    python -m bbbench.tasks.golden --add     # store the IDs golden.json lacks
"""

from __future__ import annotations

import argparse
import hashlib
import json
from pathlib import Path

import numpy as np

GOLDEN_FILE = Path(__file__).with_name("golden.json")
GOLDEN_SEEDS = (2**31, 2**31 + 1)  # two evaluation seeds
GOLDEN_STEPS = 200  # per seed, or until the episode ends
DECIMALS = 4  # observations and rewards are rounded to 1e-4 before hashing


def golden_actions() -> list[int]:
    """The fixed discrete action sequence of every golden rollout."""
    return [int(a) for a in np.random.default_rng(0).integers(0, 9, size=GOLDEN_STEPS)]


def rollout_hash(spec) -> str:
    """Hash of the task's golden rollout (discrete actions, the spec as given)."""
    if spec.multi_agent:
        return _multi_rollout_hash(spec)
    from bbbench.tasks.balance import BalanceEnv  # the env needs the suite; import late

    env = BalanceEnv(spec)
    digest = hashlib.sha256()
    for seed in GOLDEN_SEEDS:
        observation, _ = env.reset(seed=seed)
        # What the seed generated, whole: a short rollout can fall on the level
        # start pad before the terrain, a later target or the noise ever shows.
        generated = [np.asarray(env._targets, dtype=np.float64).ravel()]
        if env._errors is not None:
            generated.append(np.asarray(env._errors, dtype=np.float64).ravel())
        heightmap = getattr(env._ground, "heightmap", None)
        if heightmap is not None:
            generated.append(heightmap.heights.ravel())
        values = [*generated, observation]
        for action in golden_actions():
            observation, reward, terminated, _, _ = env.step(action)
            values.append(np.append(observation, reward))
            if terminated:
                break
        rounded = np.round(np.concatenate(values).astype(np.float64), DECIMALS) + 0.0  # no -0.0
        digest.update(rounded.tobytes())
    env.close()
    return digest.hexdigest()[:16]


def _multi_rollout_hash(spec) -> str:
    """The same for a multi-bot task: bot j plays the fixed sequence shifted by j steps."""
    from bbbench.tasks.multi import MultiBalanceEnv

    env = MultiBalanceEnv(spec)
    actions = golden_actions()
    digest = hashlib.sha256()
    for seed in GOLDEN_SEEDS:
        observations, _ = env.reset(seed=seed)
        values = [np.asarray(env._targets, dtype=np.float64).ravel()]
        heightmap = getattr(env._ground, "heightmap", None)
        if heightmap is not None:
            values.append(heightmap.heights.ravel())
        values.extend(observations.values())
        for t in range(GOLDEN_STEPS):
            if not env.agents:
                break
            step = {a: actions[(t + env._index[a]) % GOLDEN_STEPS] for a in env.agents}
            observations, rewards, *_ = env.step(step)
            values.extend(np.append(observations[a], rewards[a]) for a in observations)
        rounded = np.round(np.concatenate(values).astype(np.float64), DECIMALS) + 0.0
        digest.update(rounded.tobytes())
    env.close()
    return digest.hexdigest()[:16]


def load() -> dict[str, dict[str, str]]:
    """The stored hashes: {task id: {"spec": ..., "rollout": ...}}."""
    return json.loads(GOLDEN_FILE.read_text()) if GOLDEN_FILE.exists() else {}


def current(task_ids) -> dict[str, dict[str, str]]:
    from bbbench.tasks.suite import spec

    return {
        task_id: {"spec": spec(task_id).spec_hash, "rollout": rollout_hash(spec(task_id))}
        for task_id in task_ids
    }


def main() -> None:
    from bbbench.tasks.suite import list_tasks

    parser = argparse.ArgumentParser(description="Golden rollout hashes of the suite.")
    parser.add_argument(
        "--add",
        action="store_true",
        help="store hashes for IDs golden.json lacks (never changes one)",
    )
    args = parser.parse_args()
    stored, now = load(), current(list_tasks())
    for task_id, hashes in now.items():
        state = (
            "ok" if stored.get(task_id) == hashes else "NEW" if task_id not in stored else "CHANGED"
        )
        print(f"{task_id:30s} spec {hashes['spec']} rollout {hashes['rollout']}  {state}")
    if args.add:
        merged = {**now, **stored}  # an existing ID's hashes are never overwritten
        temporary = GOLDEN_FILE.with_suffix(".json.partial")
        temporary.write_text(json.dumps(dict(sorted(merged.items())), indent=2) + "\n")
        temporary.replace(GOLDEN_FILE)


if __name__ == "__main__":
    main()
