"""RLlib's PPO with one policy shared by every bot of a bbbench multi-bot task: the
route to one training spread over a Ray cluster (`ray start --head` on one machine,
`ray start --address HEAD:6379` on the others, then run this on the head).

    pip install 'bbbench[rllib]'
    python examples/rllib_shared_ppo.py [--task bbbench/MultiBalance-v1] [--bots 4]
        [--iterations 50] [--env-runners 2] [--address auto]

Every bot's experience trains the one policy, `shared`; the bots' env is bbbench's
PettingZoo parallel env in RLlib's own wrapper (`ParallelPettingZooEnv`), with no
glue. Each iteration prints the mean episode return (per bot, summed over bots as
RLlib reports it) and the env steps sampled so far.
"""

from __future__ import annotations

import argparse


def build(task: str, bots: int, env_runners: int, batch: int):
    """RLlib's PPO config: one shared policy over every bot of `task`."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
    from ray.tune.registry import register_env

    import bbbench

    register_env(
        "bbbench_multi",
        lambda config: ParallelPettingZooEnv(bbbench.make_parallel(task, n_bots=bots)),
    )
    return (
        PPOConfig()
        .environment("bbbench_multi")
        .framework("torch")
        .multi_agent(
            policies={"shared"},
            policy_mapping_fn=lambda agent_id, *args, **kwargs: "shared",
        )
        .env_runners(num_env_runners=env_runners, rollout_fragment_length="auto")
        .training(
            train_batch_size_per_learner=batch,
            minibatch_size=min(batch, 256),
            num_epochs=4,
            lr=3e-4,
            gamma=0.99,
        )
        .debugging(seed=0)
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="bbbench/MultiBalance-v1")
    parser.add_argument("--bots", type=int, default=4)
    parser.add_argument("--iterations", type=int, default=50)
    parser.add_argument("--env-runners", type=int, default=2)
    parser.add_argument("--batch", type=int, default=4000, help="env steps per iteration")
    parser.add_argument("--address", help="a Ray cluster (default: a local Ray)")
    args = parser.parse_args()

    import ray

    ray.init(address=args.address, include_dashboard=False, log_to_driver=False)
    algo = build(args.task, args.bots, args.env_runners, args.batch).build_algo()
    for iteration in range(args.iterations):
        result = algo.train()
        runners = result.get("env_runners", {})
        print(
            f"iteration {iteration + 1}: mean episode return "
            f"{runners.get('episode_return_mean', float('nan')):.2f}, "
            f"{result.get('num_env_steps_sampled_lifetime', 0)} env steps",
            flush=True,
        )
    algo.stop()
    ray.shutdown()


if __name__ == "__main__":
    main()
