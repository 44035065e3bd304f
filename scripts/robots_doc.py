"""Write docs/robots.md: the robots, with the wheel-legged robot's facts and spaces as its
module computes them (tests/test_wheel_legged.py checks the file carries the same tables).

    python scripts/robots_doc.py
"""

from __future__ import annotations

from pathlib import Path

from bbbench.files import write_atomic
from bbbench.robots import steering
from bbbench.robots.wheel_legged import LEG_POSITION_GAIN, facts_markdown, interface_markdown

RADIUS = steering.MODEL.wheel_radius  # m
OUT = Path(__file__).resolve().parent.parent / "docs" / "robots.md"
ROBOT_ROWS = "\n".join(
    [
        "| `two-wheel` | FlatBalance, VelocityTracking, NoisySensors, Bumps, Obstacles, Slopes, "
        "PushRecovery, MultiBalance, MultiBumps | `Discrete(9)` or `Box(-1, 1, (1,))`: a change "
        "of the wheels' commanded speed | `Box(5,)`: the five shared values |",
        "| `wheel-legged` | LeggedFlatBalance, LeggedVelocityTracking, LeggedBumps, "
        "LeggedObstacles | `Box(-1, 1, (6,))`: four leg targets, two wheel-speed changes | "
        "`Box(17,)`: the five, then the legs |",
        "| `two-wheel-steer` | none yet: the steering tasks come with it (issue 52) | "
        "`Discrete(27)` or `Box(-1, 1, (2,))`: changes of the forward and turning commands | "
        "`Box(8,)`: the five, then yaw rate, wheel speed difference, turning command; a "
        "task's own fields after them |",
    ]
)


def text() -> str:
    return f"""\
# The robots

Every task names the robot it plays (`TaskSpec.robot`, shown by `bbbench list`); the
robot decides the body in the world, the actions and the observation
(`bbbench.robots.Robot`). Every robot's observation begins with the same five values —
pitch, pitch rate, wheel speed, wheel command and target velocity, in the same units and
bounds — and every robot plays the suite's ground generators, commands and reward, so
that a task's seed is the same ground and the same targets whichever robot plays it.
The leaderboard ranks each robot's tasks on a track of its own.

| robot | tasks | actions | observation |
|---|---|---|---|
{ROBOT_ROWS}

## The two-wheel bot

The tutorial's robot: a 0.8 kg torso on two 0.1 m wheels on one axle, 1.0 kg and 0.5 m
tall (`bbbench/robots/balancebot.urdf`; `BalanceEnv`'s docstring has its tables).

## The wheel-legged robot

The tutorial's third idea, "Boston Dynamics' Handle is a balancing bot at heart but it
is so much more agile due to all the articulations and suspension it includes", in the
two-wheel bot's family: the same wheels and wheel motors on two legs, each with an
actuated hip and knee, as on Upkie and Ascento (`bbbench/robots/wheel_legged.urdf`,
`bbbench.robots.wheel_legged`). Its facts, read from the URDF:

{facts_markdown()}

The leg servos are soft position loops, like a suspension: each control step a servo is
asked for the joint speed {LEG_POSITION_GAIN:g} x (target - angle) rad/s, clipped to the
joint's speed limit, and holds it with at most the joint's torque limit (the module's
docstring has the measurements behind the gain). Its classical controller
(`bbbench eval legged`, `bbbench.policies.controllers.legged`) balances through the wheels as the
two-wheel bot's PD does and rides low on its legs; docs/tasks.md compares the two robots
on the same ground.

{interface_markdown()}

## The two-wheel bot that steers

The two-wheel bot's body and motors with its wheels commanded apart, as a differential
drive (`bbbench.robots.steering`): a forward command and a turning command, the left
wheel held at forward - turning and the right at forward + turning. Turning left
(counter-clockwise from above) is positive; a turning command d turns the bot at about
{RADIUS:g} x 2d / 0.24 = {RADIUS * 2 / 0.24:.2f} d rad/s (the wheels 0.24 m apart). The
published two-wheel robot and its tasks are unchanged: this is a robot of its own, with
tasks of its own.

{steering.interface_markdown()}
"""


def main() -> None:
    write_atomic(OUT, text().encode())
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
