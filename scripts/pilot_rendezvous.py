"""Rendezvous-v0's pilots (docs/notebook.md, "Rendezvous-v0's first learned policy"): the
shipped IPPO recipe (or `--algo mappo`'s) trained on a variant of the task, to ask what
keeps it from the channel; its curve on the training seeds printed.

    python scripts/pilot_rendezvous.py --tell one-hot --steps 1500000
    python scripts/pilot_rendezvous.py --tell one-hot --own-share 1 --steps 900000
    python scripts/pilot_rendezvous.py --tell one-hot --hold 100,100 --steps 1200000
    python scripts/pilot_rendezvous.py --tell direct --steps 900000
    python scripts/pilot_rendezvous.py --tell one-hot --landmarks 2 --steps 900000
    python scripts/pilot_rendezvous.py --tell one-hot --landmarks 2 --play rendezvous
    python scripts/pilot_rendezvous.py --tell in-range --landmarks 2 --steps 1500000
    python scripts/pilot_rendezvous.py --landmarks 2 --play policy.onnx --muted
    python scripts/pilot_rendezvous.py --tell one-hot --landmarks 2 --entities --seeds 0,1,2
    python scripts/pilot_rendezvous.py --tell one-hot --landmarks 2 --play policy.onnx --arrival
    python scripts/pilot_rendezvous.py --tell one-hot --landmarks 2 --algo mappo --seeds 0,1,2

A variant is not a task: it changes the scenario's module in this process (the worker
processes that step the worlds fork after it), never a registered ID or the board.
`--tell one-hot` writes the scout's one-hot into every bot's row (every bot told the goal
as the scout is); `direct` also writes the goal's own distance and bearing into every
landmark's three values (nothing to pick out, as Swap-v0 gives a goal); `in-range`
writes it into the rows of the bots within the channel's range of the scout (the scout's
word heard in the bot's own values, with no sender to find among the slots); `none` is
the task's (the scout alone told). `--landmarks` draws fewer landmarks (the goal among 2 or
3); `--own-share W` pays each bot W x its own share + (1 - W) x the team's mean;
`--hold LOW,HIGH` holds each goal LOW-HIGH s; `--wired` makes the scout's message the
controller's word for the goal, whatever it sends (the listeners' half of the channel
alone); `--hush` silences every bot but the scout (no babble to tell its words from).
`--beacon` (with `--tell none`) gives the scout the goal's own values and the others no
landmark, and hears a sender only while it says something (`beacon`): the channel as a
beacon a listener finds by a slot's presence, not by a word it must decode; there, the
rendezvous controller is `BeaconController` (the listeners follow the nearest sender).
`--entities` trains the actor with a landmark encoder beside the sender slots
(`landmark_entities`: each landmark's values and its told bit through one shared layer,
with the landmark's own learned code and the pooled senders added, summed over the
landmarks), so that picking the goal out is a gate, not a product to learn.
`--play` plays a policy (a built-in, such as the task's controller, or a file) on the
variant instead of training, heard or `--muted`; with `--arrival`, it prints how the
policy drives after each goal is set instead (`arrival`: by steps since the goal moved,
its bots' velocity towards the goal, their distance to it and to the other landmarks,
the bot-steps), which tells a team that gathers at the goal from one that stops in
the landmarks' middle, as a mean return cannot; `--seeds 0,1,2` trains a policy a seed,
one after another (into `--out`'s s0, s1, ...), and ends with each point's mean over
them. Each point: world steps, the mean return per bot on the curve's training seeds,
the mean episode length (played: the bot-episodes that fell, of 4 a seed).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

import bbbench.marl.models
import bbbench.policies.controllers.builtin
import bbbench.policies.controllers.rendezvous as controller
import bbbench.tasks.scenarios.rendezvous as rendezvous
from bbbench.policies.encoder import pool_slots
from bbbench.tasks.channel import SenderSlot, sender_slots
from bbbench.tasks.group import nearest_others
from bbbench.tasks.suite import agent_layout
from bbbench.training.benchmarl.train import train_marl
from bbbench.training.seeds import evaluation_seeds

sys.path.insert(0, str(Path(__file__).parent))
from calibrate_rendezvous import episode

TASK = "bbbench/Rendezvous-v0"
TELLING = ("none", "one-hot", "direct", "in-range")


def places() -> tuple[int, int]:
    """Where, in a bot's row on the variant (after `apply`), landmark 0's distance is and
    its told bit (`goal_is_landmark0`): each landmark's three values, and its bit, follow."""
    names = list(agent_layout(TASK))
    return names.index("landmark0_distance"), names.index("goal_is_landmark0")


def told_everyone(observe, tell: str):
    """`Rendezvous.observe` with the scout's one-hot in every row, as `tell` (one of
    `TELLING` but "none") says: "one-hot", in every row; "direct", in every row, and the
    goal's own distance and bearing in every landmark's three values; "in-range", in the
    rows of the scout and of the bots that hear it on the channel alone, as if its word
    were heard in the bot's own values. The fields' `places` are found at the first step,
    once the variant is in place: a pilot plays one task, so one layout."""
    found: list[tuple[int, int]] = []

    def observe_told(self, scene, states, commands, targets, step):
        rows = observe(self, scene, states, commands, targets, step)
        if not found:
            found.append(places())
        first, told = found[0]
        rows[:, told : told + rendezvous.LANDMARKS] = 0.0
        if tell == "in-range":
            rows[hearing_scout(self, states), told + self.goal] = 1.0
        else:
            rows[:, told + self.goal] = 1.0
        if tell == "direct":
            goal = rows[:, first + 3 * self.goal : first + 3 * self.goal + 3].copy()
            for k in range(rendezvous.LANDMARKS):
                rows[:, first + 3 * k : first + 3 * k + 3] = goal
        return rows

    return observe_told


def hearing_scout(self, states) -> list[int]:
    """The rows of the live bots (their `states`, in order) that are the scout or hear it:
    the scout among their channel's `slots` nearest others, within its `range`, as
    `Channel.blocks` chooses senders; none once the scout has fallen."""
    live = list(self._live)
    if self.scout not in live:
        return []
    scout, channel = live.index(self.scout), self.channel
    positions = [complex(state.position[0], state.position[1]) for state in states]
    nearest = nearest_others(positions, channel.slots)
    return [
        row
        for row, here in enumerate(positions)
        if row == scout or (scout in nearest[row] and abs(positions[scout] - here) <= channel.range)
    ]


def beacon(observe):
    """`Rendezvous.observe` as a beacon (`--beacon`): the scout sees the goal's own
    distance and bearing in every landmark's values (as `--tell direct` gives every bot),
    the others no landmark (zeros); and a sender is heard only while it says something
    (a slot whose message values are all 0 reads as no sender: zeros, presence bit too).
    A listener then finds the scout by a slot's presence alone, which the encoder already
    multiplies by, where the task asks it to pick a landmark out by a word."""
    found: list[tuple[tuple[int, int], list[SenderSlot]]] = []

    def observe_beacon(self, scene, states, commands, targets, step):
        rows = observe(self, scene, states, commands, targets, step)
        if not found:
            found.append((places(), sender_slots(agent_layout(TASK))))
        (first, _), slots = found[0]
        width = 3 * rendezvous.LANDMARKS
        for row, i in enumerate(self._live):
            if i == self.scout:
                goal = rows[row, first + 3 * self.goal : first + 3 * self.goal + 3]
                rows[row, first : first + width] = np.tile(goal, rendezvous.LANDMARKS)
            else:
                rows[row, first : first + width] = 0.0
        for slot in slots:
            silent = (rows[:, list(slot.messages)] == 0.0).all(axis=1)
            rows[silent, slot.right : slot.present + 1] = 0.0
        return rows

    return observe_beacon


class BeaconController(controller.RendezvousController):
    """The rendezvous controller on the `--beacon` variant (`--play rendezvous` plays it
    there, and a training's normalizer measures its play): the scout, the one bot that
    sees landmark values (each the goal's), heads to the goal and says (1, 1); a bot that
    hears a sender heads for the nearest one, saying nothing; one that hears none stands."""

    def __init__(self, layout, channel, neighbours, action_mode) -> None:
        super().__init__(layout, channel, neighbours, action_mode)
        self.heard_at = [(slot.right, slot.present) for slot in sender_slots(layout)]

    def belief(self, observation):
        """Landmark 0 (whose values are the goal's) and (1, 1) for the scout; nothing for
        the others."""
        if float(observation[self.landmarks[0]]) > 0.0:
            return 0, controller.TOLD[3]
        return None, controller.NOTHING

    def guide(self, observation):
        """The scout's as the rendezvous controller's; a listener's towards the nearest
        sender it hears, slowing to stand within `GATHERED` m of it."""
        if float(observation[self.landmarks[0]]) > 0.0:
            return super().guide(observation)
        for right, present in self.heard_at:
            if observation[present] > 0.5:
                r, f = float(observation[right]), float(observation[right + 1])
                distance = math.hypot(r, f)
                speed = controller.arrival_speed(observation, distance)
                return self.avoid.around(
                    observation, speed * f / distance, speed * r / distance, speed
                )
        return 0.0, 0.0


def wired_scout(observe):
    """`Rendezvous.observe` with the scout's last message replaced by the controller's
    word for the goal now (`TOLD`): a speaker that always tells, whatever it sends."""

    def observe_wired(self, scene, states, commands, targets, step):
        if self.scout in scene.live:
            scene.sent[self.scout] = controller.TOLD[self.goal]
        return observe(self, scene, states, commands, targets, step)

    return observe_wired


def hushed_others(observe):
    """`Rendezvous.observe` with every bot's last message but the scout's replaced by
    nothing (zeros): the scout is the only sender a bot hears say anything, so a
    listener need not tell its words from the others' babble."""

    def observe_hushed(self, scene, states, commands, targets, step):
        nothing = (0.0,) * self.channel.width
        for i in scene.live:
            if i != self.scout:
                scene.sent[i] = nothing
        return observe(self, scene, states, commands, targets, step)

    return observe_hushed


def own_shares(outcome, weight: float):
    """`Rendezvous.outcome` paying each live bot `weight` x its own share and the rest of
    its reward from the team's mean."""

    def outcome_own(self, agents, states, targets, seed):
        done = outcome(self, agents, states, targets, seed)
        team = done.rewards[0] if done.rewards else 0.0
        rewards = [weight * self._shares[i] + (1.0 - weight) * team for i in self._live]
        return dataclasses.replace(done, rewards=rewards)

    return outcome_own


def fewer_words(heard, landmarks: int):
    """The controller's `heard`, a word for a landmark the variant lacks heard as nothing
    (a random action's message, while the normalizer is measured)."""

    def heard_of_fewer(values):
        said = heard(values)
        return None if said is None or said[0] >= landmarks else said

    return heard_of_fewer


def landmark_entities(own, slots, slot_width, actions, presence, embed, hidden, pool):
    """`neighbour_encoder`'s signature and sender slots, with a landmark encoder beside
    them: each landmark's distance, bearing and told bit through one shared layer, plus
    that landmark's learned code and the pooled senders' embedding, ReLU, summed over the
    landmarks. A told bit (or a heard word, through the pooled senders) can then open one
    landmark's features and close the others'. The senders are pooled as `pool` says,
    as `neighbour_encoder` pools them (Rendezvous-v0's recipe says mean). Built from the
    operators bbbench's interpreter runs (Slice, Concat, Reshape, MatMul, Add, Mul, Relu,
    ReduceSum)."""
    import torch  # lazy: torch, for training only

    first, told = places()
    count = rendezvous.LANDMARKS

    class LandmarkEntities(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.per_slot = torch.nn.Linear(slot_width, embed)
            self.per_landmark = torch.nn.Linear(4, embed)
            self.code = torch.nn.Parameter(0.1 * torch.randn(count, embed))
            self.heard = torch.nn.Linear(embed, embed, bias=False)
            layers, width = [], own + 2 * embed
            for size in hidden:
                layers += [torch.nn.Linear(width, size), torch.nn.Tanh()]
                width = size
            self.head = torch.nn.Sequential(*layers, torch.nn.Linear(width, actions))

        def senders(self, obs):
            """The sender slots' embeddings, pooled."""
            grouped = obs[:, own : own + slots * slot_width].reshape(-1, slots, slot_width)
            return pool_slots(torch.relu(self.per_slot(grouped)), grouped, presence, pool)

        def landmarks(self, obs, pooled):
            """The landmarks' features, each with its code and the heard senders, summed."""
            parts = []
            for k in range(count):
                parts += [
                    obs[:, first + 3 * k : first + 3 * k + 3],
                    obs[:, told + k : told + k + 1],
                ]
            marks = torch.cat(parts, dim=1).reshape(-1, count, 4)
            context = self.heard(pooled).reshape(-1, 1, embed)
            return torch.relu(self.per_landmark(marks) + self.code + context).sum(dim=1)

        def forward(self, obs):
            pooled = self.senders(obs)
            return self.head(torch.cat([obs[:, :own], pooled, self.landmarks(obs, pooled)], dim=1))

    return LandmarkEntities()


def arrival(policy: str, seeds: list[int], width: int = 50) -> list[tuple[float, ...]]:
    """How `policy` drives once told a goal (`--arrival`): over an episode a seed (4 bots,
    heard), each live bot's velocity towards the goal (m/s), its distance to the goal and
    its mean distance to the other landmarks (m), by the steps since the goal last moved,
    in bins of `width` steps: (the bin's first step, the three means, the bot-steps in
    it). A bot that drives to the goal ends nearer it than the others; one that drives to
    the landmarks' middle ends as near the others."""
    bins: dict[int, list[tuple[float, float, float]]] = {}

    def watch(env, step: int) -> None:
        scenario = env._scenario
        since = step - scenario.schedule[scenario._next - 1][0]
        distances, _, towards = scenario._seen  # the live bots' as `observe` saw them
        kept = {env.agent_index[agent] for agent in env.agents}  # those still in the episode
        rows = [row for row, i in enumerate(scenario._live) if i in kept]
        others = [place for k, place in enumerate(scenario.landmarks) if k != scenario.goal]
        for state, row in zip(env._states, rows, strict=True):
            x, y, _ = state.axle
            away = sum(math.hypot(ox - x, oy - y) for ox, oy in others) / len(others)
            bins.setdefault(since // width, []).append((towards[row], distances[row], away))

    for seed in seeds:
        episode((policy, 4, False, seed, None), watch)
    return [(k * width, *np.mean(bins[k], axis=0).tolist(), len(bins[k])) for k in sorted(bins)]


def apply(args: argparse.Namespace, assign=setattr) -> None:
    """The variant, in this process's modules (`assign`: `setattr`, or a test's
    `monkeypatch.setattr`, which undoes it)."""
    if args.landmarks is not None:
        for module in (rendezvous, controller):
            assign(module, "LANDMARKS", args.landmarks)
        assign(rendezvous, "_OWN_FIELDS", rendezvous._landmark_fields())
        assign(controller, "heard", fewer_words(controller.heard, args.landmarks))
    if args.hold is not None:
        assign(rendezvous, "HOLD", args.hold)
    scenario = rendezvous.Rendezvous
    if args.wired:
        assign(scenario, "observe", wired_scout(scenario.observe))
    if args.hush:
        assign(scenario, "observe", hushed_others(scenario.observe))
    if args.tell != "none":
        assign(scenario, "observe", told_everyone(scenario.observe, args.tell))
    if args.beacon:
        assign(scenario, "observe", beacon(scenario.observe))
        assign(bbbench.policies.controllers.builtin, "RendezvousController", BeaconController)
    if args.own_share is not None:
        assign(scenario, "outcome", own_shares(scenario.outcome, args.own_share))
    if args.entities:
        assign(bbbench.marl.models, "neighbour_encoder", landmark_entities)


def printed(curve: list[float]):
    """A training's `on_progress`: each point printed, its mean return kept in `curve`."""

    def print_point(frames: int, _, point: dict | None) -> None:
        if point:
            curve.append(point["mean"])
            print(frames, round(point["mean"], 2), round(point["mean_length"]), flush=True)

    return print_point


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line's variant and run (`argv`, or the process's), checked: a bad value
    exits with its one line and code 2."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tell", choices=TELLING, default="none")
    parser.add_argument("--wired", action="store_true", help="the scout's words wired to the goal")
    parser.add_argument("--hush", action="store_true", help="every bot but the scout silent")
    parser.add_argument("--beacon", action="store_true", help="scout sees goal; silence unheard")
    parser.add_argument("--landmarks", type=int, choices=(2, 3, 4))
    parser.add_argument("--own-share", type=float, help="W in [0, 1]: a bot's own share's weight")
    parser.add_argument("--hold", help="LOW,HIGH s: each goal's hold")
    parser.add_argument("--play", help="a built-in (rendezvous) or a policy file: play it")
    parser.add_argument("--muted", action="store_true", help="play with the messages muted")
    parser.add_argument("--arrival", action="store_true", help="--play's drive after each goal")
    parser.add_argument("--entities", action="store_true", help="the actor's landmark encoder")
    parser.add_argument("--algo", choices=("ippo", "mappo"), default="ippo", help="the method")
    parser.add_argument("--recipe", help="a recipe file for --algo (default: the shipped one)")
    parser.add_argument("--seeds", default="0", help="training seeds, e.g. 0,1,2: a policy each")
    parser.add_argument("--steps", type=int, default=900_000, help="world steps")
    parser.add_argument("--every", type=int, default=300_000, help="world steps a point")
    parser.add_argument("--out", type=Path, default=Path("pilot-rendezvous"), help="a folder")
    args = parser.parse_args(argv)
    try:
        args.seeds = [int(seed) for seed in args.seeds.split(",")]
    except ValueError:
        parser.error(f"--seeds {args.seeds!r}: expected whole numbers, e.g. 0,1,2")
    if args.arrival and not args.play:
        parser.error("--arrival plays a policy: give it with --play, e.g. --play policy.onnx")
    if args.beacon and args.tell != "none":
        parser.error(f"--beacon with --tell {args.tell}: a beacon tells the scout alone")
    if args.own_share is not None and not 0.0 <= args.own_share <= 1.0:
        parser.error(f"--own-share {args.own_share}: expected a weight from 0 to 1")
    if args.hold is not None:
        try:
            low, high = (float(value) for value in args.hold.split(","))
        except ValueError:
            parser.error(f"--hold {args.hold!r}: expected LOW,HIGH seconds, e.g. 3,6")
        if not 0.0 < low <= high:
            parser.error(f"--hold {args.hold!r}: expected 0 < LOW <= HIGH")
        args.hold = (low, high)
    return args


def main() -> None:
    args = parse()
    apply(args)
    if args.play and args.arrival:
        for first, *means, count in arrival(args.play, evaluation_seeds(TASK)):
            print(first, *(round(mean, 2) for mean in means), count, flush=True)
        return
    if args.play:  # each worker process the same variant (they may not fork)
        jobs = [(args.play, 4, args.muted, seed, None) for seed in evaluation_seeds(TASK)]
        with ProcessPoolExecutor(2, initializer=apply, initargs=(args,)) as pool:
            played = list(pool.map(episode, jobs))
        returns, falls = zip(*played, strict=True)
        print(0, round(sum(returns) / len(returns), 2), sum(falls), flush=True)
        return
    curves: dict[int, list[float]] = {}
    for seed in args.seeds:  # one after another: two trainings at once lose more than they share
        folder = args.out / f"s{seed}" if len(args.seeds) > 1 else args.out
        folder.mkdir(parents=True, exist_ok=True)
        trained = train_marl(
            TASK,
            args.algo,
            str(folder / "policy.onnx"),
            steps=args.steps,
            seed=seed,
            recipe_file=args.recipe,
            eval_freq=args.every,
            on_progress=printed(curves.setdefault(seed, [])),
        )
        print("seed", seed, "minutes", round(trained.seconds / 60.0, 1), flush=True)
    if len(args.seeds) > 1:  # each point's mean over the seeds
        for k, points in enumerate(zip(*curves.values(), strict=False)):
            print("mean", (k + 1) * args.every, round(sum(points) / len(points), 2), flush=True)


if __name__ == "__main__":
    main()
