"""Write docs/robots.md: the robots, each robot's tasks from the suite, and each robot's
facts and spaces as its module computes them (tests/test_docs.py holds the file to it).

    python scripts/robots_doc.py
"""

from __future__ import annotations

from pathlib import Path

from bbbench.files import write_atomic
from bbbench.robots import ROBOTS, TWO_WHEEL, steering
from bbbench.robots.layout import HEIGHT_SCAN_LAYOUT, SCAN_OFFSETS, fields_markdown
from bbbench.robots.twowheel import OBSERVATION_LAYOUT
from bbbench.robots.wheel_legged import LEG_POSITION_GAIN, facts_markdown, interface_markdown
from bbbench.tasks.suite import SUITE

RADIUS = steering.MODEL.wheel_radius  # m
OUT = Path(__file__).resolve().parent.parent / "docs" / "robots.md"
# Each robot's actions and observation, in a few words.
SPACES = {
    "two-wheel": "`Discrete(9)` or `Box(-1, 1, (1,))`: a change of the wheels' commanded speed "
    "| `Box(5,)`: the five shared values",
    "wheel-legged": "`Box(-1, 1, (6,))`: four leg targets, two wheel-speed changes | "
    "`Box(17,)`: the five, then the legs",
    "two-wheel-steer": "`Discrete(27)` or `Box(-1, 1, (2,))`: changes of the forward and "
    "turning commands | `Box(8,)`: the five, then yaw rate, wheel speed difference, turning "
    "command; a task's own fields after them",
}


def robot_rows() -> str:
    """A row per robot: its tasks' names in the suite's order, its spaces."""
    rows = []
    for name in ROBOTS:
        tasks = dict.fromkeys(
            task.name for task in SUITE.values() if name in (task.robots or (task.robot,))
        )
        rows.append(f"| `{name}` | {', '.join(tasks)} | {SPACES[name]} |")
    return "\n".join(rows)


def height_scan_markdown() -> str:
    """The height scan's values as a table: where each is read, ahead of the axle."""
    first = len(OBSERVATION_LAYOUT)
    rows = (
        f"| {first + k} | {field.name} | {field.low:g} | {field.high:g} | {field.unit} | "
        f"{offset:.1f} |"
        for k, (field, offset) in enumerate(zip(HEIGHT_SCAN_LAYOUT, SCAN_OFFSETS, strict=True))
    )
    return "\n".join(
        (
            "| Num | Observation | Min | Max | Unit | Ahead (m) |",
            "|-----|-------------|-----|-----|------|-----------|",
            *rows,
        )
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
{robot_rows()}

## The two-wheel bot

The tutorial's robot: a 0.8 kg torso, 0.2 x 0.05 x 0.4 m, on two 0.1 m wheels of 0.1 kg
on one axle, 1.0 kg and 0.5 m tall (`bbbench/robots/balancebot.urdf`,
`bbbench.robots.twowheel`). The wheels' velocity servos hold a commanded wheel speed with
at most 0.6 N m of torque each, up to 24.6 rad/s (2.46 m/s). It is an inverted pendulum:
left alone it falls; a policy keeps it up by changing the commanded wheel speed, driving
the wheels under the torso.

### Action Space

{TWO_WHEEL.actions_markdown()}

An action outside the space (or NaN) raises `ValueError`; nothing is clamped silently.

### Observation Space

`Box(5,)` of `float32` on its single-bot tasks; the multi-bot and team tasks append
their own fields (each task's page). Forward is the bot's own +y axis; angles are
measured in the bot's own frame against gravity, so they mean the same whatever the
heading or slope. The gyro saturates at 2000 deg/s, a common MEMS gyro's full scale; the
encoders at 50 rad/s, about twice the motors' top speed.

{fields_markdown(OBSERVATION_LAYOUT)}

### Height Scan

`height_scan=True` (default False, on the single-bot tasks) appends 11 ground heights
ahead of the bot: `Box(16,)`. Each is the ground's height at a point on the bot's
heading, so many metres ahead of the axle, minus the axle's height (flat ground reads
-0.1, the wheel radius), clipped to +-3 m, read from the episode's heightmap at the node
nearest each point (no ray casts). The first five values are the blind observation,
unchanged: one policy plays every task. A height-scan task is a different spec
(`spec.with_height_scan()`) with its own fingerprint.

{height_scan_markdown()}

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
