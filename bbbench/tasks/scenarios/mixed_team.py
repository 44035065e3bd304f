"""`MixedBeamCarry`: BeamCarry's beam carried by a mixed team, wheel-legged robots and
two-wheel bots in turn, a wheel-legged robot in front (issue 67), and the tasks played
with it (MixedBeamCarry-v0, MixedBeamCarryBumps-v0)."""

from __future__ import annotations

import dataclasses

from bbbench.tasks.scenario import register_scenario
from bbbench.tasks.scenarios import beam_carry
from bbbench.tasks.scenarios.beam_carry import BeamCarry
from bbbench.tasks.scenarios.column import team_description
from bbbench.tasks.spec import TaskSpec


@register_scenario
class MixedBeamCarry(BeamCarry):
    """BeamCarry's column and beam with two robots in it (`TaskSpec.robots`): bot i plays
    the task's robots in turn, the front bot the first. Each bot observes in its own
    robot's layout (the wheel-legged robot's seventeen values, the two-wheel bot's five),
    then the beam's four values and its neighbours ahead and behind, as on BeamCarry; each
    acts in its own robot's action space. The beam is hinged to the top of every torso: a
    wheel-legged robot's legs set the height of its hinges, and so how much of the load it
    carries. Shortened, they lift its wheels and hang it from the beam: a robot that hangs
    cannot drive, and the front one must lead."""

    name = "mixed-beam-carry"
    summary = "a column of wheel-legged robots and two-wheel bots in turn carrying one beam"
    robots = ("two-wheel", "wheel-legged")
    mixes = True
    controller = "mixed-team"  # bbbench.policies.controllers.team: both robots as one team


_MIXED_WHY = """\
Only the front bot, a wheel-legged robot, observes the team's target velocity; the others
read 0 in that slot. Targets are drawn from [-2, 2] m/s and held 2-5 s, as on BeamCarry.
Every agent receives the team's reward, `StayUpReward.terms(pitch, error)` with the most
tilted bot's pitch and `error` = |the beam's velocity - target|. A fall of any bot ends
every agent's episode. The two robots keep their own spaces: a wheel-legged robot
observes 31 values (its seventeen, the beam's four, the bots ahead and behind) and acts
in `Box(-1, 1, (6,))`; a two-wheel bot observes 19 (its five, then the same) and acts in
`Box(-1, 1, (1,))`. Actions are continuous (the only mode both robots take). A
MARL library trains one policy per robot (`TaskSpec.robot_groups`). The naive baseline
is `per-bot` (each robot's own controller on the target it observes); the classical team
controller is `mixed-team` (`bbbench.policies.controllers.team`); docs/tasks.md has the
calibration."""


def _mixed(row: TaskSpec, task_id: str, summary: str, description: str, random_return: float):
    """A BeamCarry row played by the mixed team: every other field is the row's."""
    return dataclasses.replace(
        row,
        id=task_id,
        summary=summary,
        description=team_description(description, _MIXED_WHY),
        scenario="mixed-beam-carry",
        robot="wheel-legged",
        robots=("wheel-legged", "two-wheel"),
        version_history=("v0: initial release (issue 67).",),
        random_return=random_return,
    )


_FLAT, _HILLS = beam_carry.TASKS
TASKS = (
    _mixed(
        _FLAT,
        "bbbench/MixedBeamCarry-v0",
        "BeamCarry's beam carried by wheel-legged robots and two-wheel bots in turn, led by a "
        "wheel-legged robot (3 bots, 2-4)",
        """\
BeamCarry-v0's column, beam and targets on flat ground, carried by a mixed team: bot i
is a wheel-legged robot for even i and a two-wheel bot for odd i (3 bots by default:
wheel-legged, two-wheel, wheel-legged; `n_bots` 2-4). The beam is hinged to the top of
every torso: a wheel-legged robot's legs set the height of its hinges (its torso's top
is 50.8 cm up standing, the two-wheel bot's 50 cm) and so its share of the load. With
its legs short it hangs from the beam, its wheels off the ground: the front robot, which
alone knows the target, must keep its wheels down to lead.""",
        1.3147836080572284,
    ),
    _mixed(
        _HILLS,
        "bbbench/MixedBeamCarryBumps-v0",
        "MixedBeamCarry's mixed team over BeamCarryBumps' hills (`difficulty=` 0..1)",
        """\
MixedBeamCarry-v0's mixed team and beam on BeamCarryBumps-v0's strip of smooth random
hills (default difficulty 0.6: 0.08 m high). On a hill the beam pitches; a wheel-legged
robot's legs can raise or lower its hinges.""",
        1.3052203748635904,
    ),
)
