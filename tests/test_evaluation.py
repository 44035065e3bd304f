"""`bbbench eval`: fixed seeds, reproducible bytes, statistics, workers, Ray, bad input."""

from __future__ import annotations

import json
import os
from collections import deque
from pathlib import Path

import numpy as np
import pytest

import bbbench
from bbbench.cli import main
from bbbench.dev.random_reference import measure
from bbbench.evaluation import dumps, evaluate, stats
from bbbench.evaluation.backends import _next_job
from bbbench.evaluation.episodes import LockstepPlayer
from bbbench.evaluation.harness import play_draws, play_tasks
from bbbench.evaluation.results import read
from bbbench.policies import BUILTIN_POLICIES, load_policy, register_policy
from bbbench.policies.controllers.builtin import PDPolicy
from bbbench.policies.policy import PDActor
from bbbench.tasks.perturbations import ComOffset, Push
from conftest import follows_results_schema

FLAT = "bbbench/FlatBalance-v0"
VELOCITY = "bbbench/VelocityTracking-v0"
MULTI = "bbbench/MultiBalance-v0"


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(["eval", *argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


# -- statistics on known data ----------------------------------------------------------


def test_iqm_is_the_mean_of_the_middle_half():
    assert stats.iqm(np.arange(1, 9)) == 4.5  # mean of 3, 4, 5, 6
    assert stats.iqm([10.0, 0.0, 1.0, 2.0, 3.0, -50.0, 4.0, 5.0]) == 2.5  # outliers cut


def test_bootstrap_interval_of_a_mean_of_coin_flips_is_the_binomial_quantiles():
    # 10 zeros and 10 ones: a resampled mean is Binomial(20, 1/2) / 20, whose 2.5% and
    # 97.5% quantiles are 6/20 and 14/20.
    low, high = stats.stratified_bootstrap_ci([np.repeat([0.0, 1.0], 10)], stats.mean)
    assert (low, high) == (0.3, 0.7)


def test_bootstrap_interval_is_fixed_by_its_seed_and_degenerate_on_constant_data():
    data = np.random.default_rng(1).normal(size=50)
    first = stats.stratified_bootstrap_ci([data], stats.iqm)
    assert first == stats.stratified_bootstrap_ci([data], stats.iqm)
    assert first != stats.stratified_bootstrap_ci([data], stats.iqm, seed=1)
    assert first[0] < stats.iqm(data) < first[1]
    assert stats.stratified_bootstrap_ci([np.full(7, 2.5)], stats.mean) == (2.5, 2.5)


def test_stratified_bootstrap_resamples_within_each_task():
    # Each task constant: every resample keeps each task's size, so the pooled IQM never
    # moves. (An unstratified resample of the pool would.)
    strata = [np.zeros(4), np.ones(4)]
    assert stats.stratified_bootstrap_ci(strata, stats.iqm) == (0.5, 0.5)


# -- episodes on fixed seeds --------------------------------------------------------------


def test_episodes_are_the_eval_seeds_in_order_and_match_a_gymnasium_loop():
    evaluation = evaluate(load_policy("pd"), [VELOCITY], episodes=3, workers=2)
    task = evaluation.document["tasks"][0]
    assert task["seeds"] == list(bbbench.spec(VELOCITY).eval_seeds[:3])
    env = bbbench.make(VELOCITY)  # gymnasium.make: with TimeLimit
    controller = bbbench.policies.PDController()
    for episode in task["episodes"]:
        observation, _ = env.reset(seed=episode["seed"])
        total, steps, errors, done = 0.0, 0, 0.0, False
        while not done:
            observation, reward, terminated, truncated, info = env.step(controller(observation))
            total, steps, errors = total + reward, steps + 1, errors + info["velocity_error"]
            done = terminated or truncated
        assert episode["return"] == total
        assert episode["length"] == steps
        assert episode["velocity_error"] == errors / steps
        assert episode["success"] == (not terminated)


def test_a_runner_holds_the_worlds_of_one_task_at_a_time_and_results_do_not_change():
    policy = load_policy("pd")
    runner = LockstepPlayer(
        actors={task: policy.actor(task) for task in (FLAT, VELOCITY)},
        action_mode="discrete",
        sampled=False,
    )
    flat_seeds = bbbench.spec(FLAT).eval_seeds[:3]
    try:
        first = runner.play(FLAT, flat_seeds)
        assert runner.worlds() == {FLAT: 3}
        runner.play(VELOCITY, bbbench.spec(VELOCITY).eval_seeds[:2])
        assert list(runner.worlds()) == [VELOCITY]  # Flat's worlds were closed
        assert runner.play(FLAT, flat_seeds) == first
    finally:
        runner.close()


def test_draws_of_several_policies_on_one_pool_play_as_each_policy_alone():
    """`play_draws` (the spot-check) plays every policy's draws on one pool, in worlds
    kept from one policy's group to the next: each episode is the one its policy plays
    alone, in fresh worlds."""
    pd, lqr = load_policy("pd"), load_policy("lqr")
    tasks = [bbbench.spec(VELOCITY).with_perturbation(Push(0.5)), bbbench.spec(VELOCITY)]
    tasks.append(tasks[0].with_perturbation(ComOffset(0.03)))
    seeds = [bbbench.spec(VELOCITY).eval_seeds[i] for i in (3, 0, 5)]
    draws = [
        (policy, task, seed)
        for policy in (pd, lqr)
        for task, seed in zip(tasks, seeds, strict=True)
    ]
    draws.append((pd, bbbench.spec(MULTI), bbbench.spec(MULTI).eval_seeds[1]))
    together = play_draws(draws, workers=1)
    for (policy, task, seed), episode in zip(draws, together, strict=True):
        alone = play_tasks(policy, [task], seeds=[[seed]], workers=1).episodes[0][0]
        assert episode.record() == alone.record()
    assert together[0].record() != together[3].record()  # PD's and LQR's differ


def test_multi_bot_episodes_score_per_bot():
    evaluation = evaluate(load_policy("pd"), [MULTI], episodes=2, workers=1)
    task = evaluation.document["tasks"][0]
    assert task["bots"] == 4
    env = bbbench.make_parallel(MULTI)
    controller = bbbench.policies.PDController()
    for episode in task["episodes"]:
        observations, _ = env.reset(seed=episode["seed"])
        returns = dict.fromkeys(env.possible_agents, 0.0)
        falls = 0
        while env.agents:
            actions = {agent: controller(observations[agent]) for agent in env.agents}
            observations, rewards, terminations, _, _ = env.step(actions)
            for agent, reward in rewards.items():
                returns[agent] += reward
            falls += sum(terminations.values())
        assert episode["return"] == pytest.approx(sum(returns.values()) / 4, rel=1e-12)
        assert episode["falls"] == falls


def test_results_are_byte_identical_across_runs_worker_counts_and_processes(capsys, tmp_path):
    outputs = []
    for workers in ("1", "2", "2"):
        out = tmp_path / f"results-{len(outputs)}.json"
        code, _, _ = run_cli(
            capsys, "pd", "--task", FLAT, MULTI, "--episodes", "3", "--workers", workers,
            "--json", str(out),
        )  # fmt: skip
        assert code == 0
        outputs.append(out.read_bytes())
    assert outputs[0] == outputs[1] == outputs[2]
    document = json.loads(outputs[0])
    follows_results_schema(document)
    assert not list(tmp_path.glob(".*partial*"))


def test_results_document_records_the_policy_and_the_tasks(tmp_path, capsys):
    out = tmp_path / "results.json"
    code, stdout, _ = run_cli(capsys, "--episodes", "2", "--json", str(out))  # the reference
    assert code == 0
    document = json.loads(out.read_text())
    follows_results_schema(document)
    policy = document["policy"]
    reference = Path(bbbench.policies.registry.REFERENCE_POLICY)
    import hashlib

    assert policy["sha256"] == hashlib.sha256(reference.read_bytes()).hexdigest()
    assert (policy["algorithm"], policy["action_mode"], policy["source"]) == (
        "PPO",
        "discrete",
        "file",
    )
    # Every single-bot task of the two-wheel bot: the reference zip fits no other robot's.
    latest = [
        task_id
        for task_id in bbbench.list_tasks(multi_agent=False, latest=True)
        if bbbench.spec(task_id).robot == "two-wheel"
    ]
    assert [t["task"] for t in document["tasks"]] == latest
    for task in document["tasks"]:
        spec = bbbench.spec(task["task"])
        assert task["fingerprint"] == spec.fingerprint
        assert task["random_return"] == spec.random_return
        assert len(task["episodes"]["rows"]) == 2  # the text's table: a row per episode
    assert document["overall"]["tasks"] == len(latest)
    assert f"Mean normalized score over {len(latest)} tasks" in stdout
    assert "FlatBalance-v1" in stdout


def test_stochastic_runs_are_reproducible_and_differ_from_deterministic_ones():
    policy = load_policy("reference")
    runs = [
        dumps(evaluate(policy, [VELOCITY], episodes=2, workers=2, stochastic=s).document)
        for s in (True, True, False)
    ]
    assert runs[0] == runs[1]
    assert runs[0] != runs[2]
    assert json.loads(runs[0])["deterministic"] is False


def test_normalized_scores_put_random_at_0_and_the_maximum_at_1():
    evaluation = evaluate(load_policy("random"), [FLAT], workers=2)  # all 100 eval seeds
    aggregate = evaluation.document["tasks"][0]["aggregate"]
    assert aggregate["normalized_score"] == pytest.approx(0.0, abs=1e-12)
    spec = bbbench.spec(FLAT)
    assert (spec.max_return - spec.random_return) > 100


@pytest.mark.slow
def test_stored_random_references_are_what_the_random_policy_scores():
    measured = measure()
    for task_id, value in measured.items():
        assert bbbench.spec(task_id).random_return == pytest.approx(value, rel=1e-9), task_id


# -- workers that die --------------------------------------------------------------------


class CrashingPD(PDPolicy):
    """The PD baseline, whose worker process dies on the first step of one episode (the
    one whose first target velocity is `fatal_target`), `times` times at most."""

    def __init__(self, fatal_target: float, budget: Path) -> None:
        super().__init__()
        self.name = "crashing-pd"
        self.fatal_target, self.budget = fatal_target, budget

    def actor(self, task_id, deterministic=True):
        return CrashingActor(super().actor(task_id), self.fatal_target, str(self.budget))


class CrashingActor(PDActor):
    def __init__(self, inner, fatal_target, budget):
        super().__init__(inner.controller)
        object.__setattr__(self, "fatal", (fatal_target, budget))

    def __call__(self, observations, rngs=None):
        fatal_target, budget = self.fatal
        for observation in observations:
            if observation[4] == fatal_target and observation[3] == 0.0:
                left = int(Path(budget).read_text())
                if left > 0:
                    Path(budget).write_text(str(left - 1))
                    os._exit(1)
        return super().__call__(observations, rngs)


def crashing_policy(tmp_path: Path, seed_index: int, times: int) -> CrashingPD:
    env = bbbench.make(VELOCITY)
    observation, _ = env.reset(seed=bbbench.spec(VELOCITY).eval_seeds[seed_index])
    budget = tmp_path / "crashes"
    budget.write_text(str(times))
    return CrashingPD(float(observation[4]), budget)


def test_each_worker_plays_its_own_stretch_of_jobs_then_takes_from_the_longest_left():
    stretches = [deque([0, 1, 2]), deque([3, 4, 5, 6]), deque([7])]
    taken = [_next_job(stretches, 0) for _ in range(3)]
    assert taken == [0, 1, 2]
    assert _next_job(stretches, 0) == 6  # the end of the longest stretch: its last task
    assert _next_job(stretches, 1) == 3  # the owner goes on from the front
    assert _next_job(stretches, 2) == 7
    assert [_next_job(stretches, 2) for _ in range(2)] == [5, 4]
    assert not any(stretches)


def test_a_worker_that_dies_once_has_its_episodes_retried_with_the_same_results(tmp_path):
    clean = evaluate(load_policy("pd"), [VELOCITY], episodes=12, workers=2)
    crashed = evaluate(crashing_policy(tmp_path, 9, times=1), [VELOCITY], episodes=12, workers=2)
    assert (tmp_path / "crashes").read_text() == "0"  # it did die
    assert crashed.missing == []
    assert crashed.document["tasks"] == clean.document["tasks"]


def test_episodes_whose_worker_dies_twice_are_reported_and_the_rest_is_written(tmp_path, capsys):
    # 12 episodes are two lockstep groups, seeds 0-7 and 8-11: the second one dies.
    policy = crashing_policy(tmp_path, 9, times=5)
    register_policy("crashing-pd", lambda: policy)
    try:
        out = tmp_path / "partial.json"
        code, _, err = run_cli(
            capsys, "crashing-pd", "--task", VELOCITY, "--episodes", "12", "--workers", "2",
            "--json", str(out),
        )  # fmt: skip
    finally:
        del BUILTIN_POLICIES["crashing-pd"]
    assert (tmp_path / "crashes").read_text() == "3"  # tried twice, no more
    assert code == 1
    seeds = list(bbbench.spec(VELOCITY).eval_seeds[:12])
    assert "4 episode(s) missing" in err
    assert f"seed {seeds[9]}" in err
    task = read(out)["tasks"][0]
    assert task["missing"] == seeds[8:]
    assert [e["seed"] for e in task["episodes"]] == seeds[:8]
    assert task["aggregate"]["episodes"] == 8


# -- Ray --------------------------------------------------------------------------------


@pytest.mark.slow
def test_the_ray_backend_gives_the_local_backends_bytes():
    pytest.importorskip("ray", reason="the Ray backend is an extra: pip install 'bbbench[ray]'")
    policy = load_policy("reference")
    tasks = [FLAT, "bbbench/Bumps-v0"]
    local = evaluate(policy, tasks, episodes=3, workers=2)
    on_ray = evaluate(policy, tasks, episodes=3, workers=2, backend="ray")
    assert dumps(on_ray.document) == dumps(local.document)
    pd = load_policy("pd")
    assert dumps(evaluate(pd, [MULTI], episodes=2, backend="ray").document) == dumps(
        evaluate(pd, [MULTI], episodes=2).document
    )


# -- video -------------------------------------------------------------------------------


@pytest.mark.parametrize(("task_id", "suffix", "shape"), [
    (FLAT, ".gif", (240, 320, 3)),
    (MULTI, ".mp4", (360, 480, 3)),
])  # fmt: skip
def test_video_writes_the_first_episode(tmp_path, capsys, task_id, suffix, shape):
    import imageio.v3 as iio

    out = tmp_path / f"episode{suffix}"
    code, stdout, _ = run_cli(
        capsys, "random", "--task", task_id, "--episodes", "1", "--video", str(out)
    )
    assert code == 0
    frames = iio.imread(out)
    assert frames.shape[1:] == shape
    assert f"{frames.shape[0]} frames" in stdout
    assert f"episode seed {bbbench.spec(task_id).eval_seeds[0]}" in stdout


def test_a_swap_videos_last_frame_is_of_a_step_with_bots_in_the_world():
    """Swap's bots leave the world as they fall: the video ends on the last step with a bot
    in it, not on the empty world after the last one fell."""
    from bbbench.evaluation.episodes import action_generator
    from bbbench.evaluation.play import MultiEpisode
    from bbbench.evaluation.video import FRAME_EVERY, _play
    from bbbench.policies import load_policy

    task = bbbench.spec("bbbench/Swap-v0")
    policy, seed = load_policy("random"), task.eval_seeds[0]
    act = policy.acting(task.id, False)
    frames = []
    _play(task, policy, act, action_generator(seed), seed, frames)
    env = bbbench.make_parallel(task.id, render_mode="rgb_array")
    played = MultiEpisode(env, act, seed, action_generator(seed)).play()
    env.close()
    assert played.falls == 4  # every bot fell, before the time limit
    assert played.length < task.max_episode_steps
    with_bots = range(played.length)  # after step `length` the world is empty
    assert len(frames) == len([step for step in with_bots if step % FRAME_EVERY == 0])


# -- bad input ---------------------------------------------------------------------------


@pytest.mark.parametrize(("argv", "expected"), [
    (["pd", "--task", "bbbench/FlatBalanse-v0"], "Did you mean 'bbbench/FlatBalance-v0'"),
    (["pd", "--episodes", "0"], "--episodes must be at least 1, got 0"),
    (["pd", "--episodes", "-3"], "--episodes must be at least 1, got -3"),
    (["pd", "--episodes", "101"], "--episodes 101: the tasks have 100 evaluation seeds each"),
    (["pd", "--seeds", "test"], "--seeds 'test': the public seeds are 'evaluation' (what the"),
    (["pd", "--workers", "0"], "--workers must be at least 1"),
    (["pd", "--address", "10.0.0.1:6379"], "use it with --backend ray"),
    (["pd", "--json", "/no/such/dir/out.json"], "no directory /no/such/dir"),
    (["pd", "--video", "clip.avi"], "ending in .gif or .mp4"),
    (["reference", "--task", MULTI], "MultiBalance-v0 plays the two-wheel robot and wants Box(17"),
    (["no-such-policy"], "unknown policy 'no-such-policy'"),
])  # fmt: skip
def test_bad_input_is_a_one_line_error_with_exit_code_2(capsys, argv, expected):
    code, stdout, err = run_cli(capsys, *argv)
    assert code == 2
    assert expected in err
    assert err.startswith("bbbench: error:")
    assert len(err.strip().splitlines()) == 1
    assert stdout == ""


def test_validation_seeds_are_played_on_request_and_said_in_the_document(tmp_path, capsys):
    """`--seeds validation` plays each task's validation seeds, which no board scores: the
    document names the split and the seeds, and its episodes are those a Gymnasium loop
    plays on them."""
    out = tmp_path / "validation.json"
    code, _, _ = run_cli(
        capsys, "pd", "--task", "bbbench/FlatBalance-v1", "--episodes", "2", "--workers", "1",
        "--seeds", "validation", "--json", str(out),
    )  # fmt: skip
    assert code == 0
    document = read(out)
    spec = bbbench.spec("bbbench/FlatBalance-v1")
    assert document["split"] == "validation"
    (block,) = document["tasks"]
    assert block["seeds"] == list(spec.validation_seeds[:2])
    assert [episode["seed"] for episode in block["episodes"]] == block["seeds"]
    on_eval = evaluate(load_policy("pd"), [spec.id], episodes=2, workers=1).document
    assert "split" not in on_eval
    assert on_eval["tasks"][0]["episodes"] != block["episodes"]


def test_a_policy_is_refused_on_a_task_it_cannot_play_before_anything_is_played():
    """PD's nine actions mean other ones to the steering robot: `evaluate` in Python
    refuses, as the command does, rather than score them."""
    from bbbench.policies import PolicyError

    played = []
    with pytest.raises(PolicyError, match="SteerTracking-v0 plays the two-wheel-steer robot"):
        evaluate(
            load_policy("pd"),
            ["bbbench/FlatBalance-v1", "bbbench/SteerTracking-v0"],
            episodes=1,
            workers=1,
            on_result=lambda n, results: played.append(n),
        )
    assert played == []
