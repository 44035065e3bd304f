"""`Body`: what every robot's body in a bullet world shares.

Loading its URDF (with the file's inertias), its wheels' contact threshold, the
perturbations that act on any torso (a payload, a shifted centre of mass, a push),
and leaving and re-entering an episode (`move_clear`, `set_aside`). A robot's own
class (`BalanceBot`, `WheelLeggedBot`) adds its actuators, `act`, `reset` and `read`.
"""

from __future__ import annotations

import functools
import math
import os
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import pybullet
from pybullet_utils.bullet_client import BulletClient

from bbbench.sim import bullet_client_id

# Only wheel contacts closer than this (m) reach the solver. A rolling wheel leaves
# its last contact points behind it, rising only slowly off the ground (a cycloid
# starts vertically); Bullet keeps them for several steps, and the solver iterated
# over up to 4 per wheel. Measured when the terrain tasks were tuned (commit 15a0c26):
# 0 makes driving cheapest but bumpy ground becomes a train of small impacts (the PD
# baseline fell on 9/20 Bumps seeds, against 1/20 with Bullet's default, 3/20 at 1-2
# mm); 1 mm keeps most of the speed.
WHEEL_CONTACT_PROCESSING_THRESHOLD = 0.001

# (group, mask) of a dynamic body's links as pybullet loads them: collide with everything.
_DYNAMIC_COLLISION_FILTER = (1, -1)
# Where reset() moves a bot, clear of everything, before placing it (y grows with the body id).
_CLEAR_OF_EVERYTHING = (-1000.0, 10.0, 10.0)


def urdf_parts(urdf_path: Path) -> tuple[dict[str, ET.Element], dict[str, ET.Element]]:
    """A URDF's joints and links by name: what each robot's model reads its facts from."""
    robot = ET.parse(urdf_path).getroot()
    joints = {joint.get("name"): joint for joint in robot.iter("joint")}
    links = {link.get("name"): link for link in robot.iter("link")}
    return joints, links


def rolling_radius(links: dict[str, ET.Element], wheel_joint: ET.Element) -> float:
    """The radius (m) of the wheel a joint drives: its collision shape's, as that is what
    rolls (a sphere or a cylinder, a radius either way)."""
    wheel = links[wheel_joint.find("child").get("link")]
    return float(wheel.find("collision/geometry/*[@radius]").get("radius"))


class WheeledModel:
    """What every robot model (`RobotModel`, `LeggedModel`) has: wheels of a radius (m)
    and a top speed (rad/s), both read from its URDF, and what follows from them."""

    urdf_path: Path
    wheel_radius: float
    wheel_speed_limit: float

    @property
    def top_speed(self) -> float:
        """Forward speed at the wheel-speed limit, m/s."""
        return self.wheel_speed_limit * self.wheel_radius


@functools.cache
def shifted_urdf(urdf_path: Path, com_forward: float) -> str:
    """The URDF's text with the torso's centre of mass moved `com_forward` m along +y
    (forward); its mass and inertia about the centre of mass are unchanged."""
    tree = ET.parse(urdf_path)
    robot = tree.getroot()
    torso = robot.find("joint/parent").get("link")
    origin = next(link for link in robot.iter("link") if link.get("name") == torso).find(
        "inertial/origin"
    )
    x, y, z = (float(value) for value in origin.get("xyz").split())
    origin.set("xyz", f"{x!r} {y + com_forward!r} {z!r}")
    return ET.tostring(robot, encoding="unicode")


class Body:
    """One robot's body in a bullet world: the parts every robot shares.

    Args:
        client: the world's bullet client (one per environment).
        urdf_path: the robot's URDF, loaded with `URDF_USE_INERTIA_FROM_FILE` so that
            pybullet uses the file's inertias.
        wheel_joint_names: the joints whose links roll on the ground.

    Subclasses write `_actuate()` (send the actuators' commands again, after a reload
    or when set aside: `_stop()`), `act`, `reset` and `read`; `wheel_command` is the
    wheel speed (rad/s) the servos hold, the shared observation's `wheel_command`.
    """

    wheel_command: float

    def __init__(
        self, client: BulletClient, urdf_path: Path, wheel_joint_names: tuple[str, ...]
    ) -> None:
        self._client = client
        # The hot path calls pybullet directly: BulletClient builds a partial per call.
        self._client_id = bullet_client_id(client)
        self._urdf_path = urdf_path
        self._wheel_joint_names = wheel_joint_names
        self._com_forward = 0.0  # m: the torso's centre of mass ahead of the URDF's
        self.body = self._load(str(urdf_path))
        self._torso_mass = client.getDynamicsInfo(self.body, -1)[0]  # kg, as the URDF says
        self._payload = 0.0
        self._set_aside = False

    def _load(self, urdf_path: str) -> int:
        client = self._client
        body = client.loadURDF(
            urdf_path, basePosition=(0.0, 0.0, 0.0), flags=pybullet.URDF_USE_INERTIA_FROM_FILE
        )
        self.joint_index = {
            client.getJointInfo(body, j)[1].decode(): j for j in range(client.getNumJoints(body))
        }
        self.wheel_joints = tuple(self.joint_index[name] for name in self._wheel_joint_names)
        for joint in self.wheel_joints:
            client.changeDynamics(
                body, joint, contactProcessingThreshold=WHEEL_CONTACT_PROCESSING_THRESHOLD
            )
        # Every link that collides: the torso (-1), then the joints' links in order.
        self._links = (-1, *sorted(self.joint_index.values()))
        return body

    def _actuate(self) -> None:
        """Send the actuators' present commands to the servos again."""
        raise NotImplementedError

    def _stop(self) -> None:
        """Command the actuators to rest (a body set aside)."""
        raise NotImplementedError

    def act(self, decoded) -> float:
        """Apply a decoded action (`Robot.action_decoder`); return the wheel command now held
        (rad/s, the shared observation's `wheel_command`)."""
        raise NotImplementedError

    def read(self):
        """The body's state, whose fields begin with `BotState`'s (`bbbench.robots.balancebot`)."""
        raise NotImplementedError

    def reset(
        self,
        pitch: float = 0.0,
        yaw: float = 0.0,
        xy: tuple[float, float] = (0.0, 0.0),
        ground_height: float = 0.0,
        drop_contacts: bool = True,
    ) -> None:
        """Put the body at rest with its wheels on the ground at `xy`, leaning by `pitch`
        rad about the axle, facing `yaw`. Velocities, joints and commands are zeroed (the
        legs standing). `drop_contacts=False` skips dropping the last episode's contact
        points, for a caller that has moved every bot clear (`move_clear`) and run
        collision detection once itself."""
        self._enter(drop_contacts)
        client, body = self._client, self.body
        position, orientation = self._spawn_pose(pitch, yaw, xy, ground_height)
        client.resetBasePositionAndOrientation(body, position, orientation)
        client.resetBaseVelocity(body, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        for joint, angle in self._joints_at_rest():
            client.resetJointState(body, joint, targetValue=angle, targetVelocity=0.0)
        self._hold_still()

    def _spawn_pose(self, pitch: float, yaw: float, xy, ground_height: float):
        """The base's position and orientation for `reset` (pybullet's base pose)."""
        raise NotImplementedError

    def _joints_at_rest(self) -> list[tuple[int, float]]:
        """(joint, angle) of every joint `reset` sets: the wheels at 0."""
        return [(joint, 0.0) for joint in self.wheel_joints]

    def _hold_still(self) -> None:
        """The end of `reset`: commands (and any delayed actions) at rest."""
        raise NotImplementedError

    @property
    def client(self) -> BulletClient:
        """The bullet client of the body's world."""
        return self._client

    @property
    def client_id(self) -> int:
        """The `physicsClientId` of the body's world."""
        return self._client_id

    # -- perturbations (the hooks `bbbench.tasks.perturbations` calls) ---------

    def set_motor_strength(self, factor: float) -> None:
        """Actuators `factor` times as strong as the URDF's torque limits (1: as built)."""
        raise NotImplementedError

    def set_action_delay(self, steps: int) -> None:
        """Act on each command `steps` commands later (0: at once)."""
        raise NotImplementedError

    def set_payload(self, kg: float) -> None:
        """Carry `kg` more at the torso's centre of mass (0: the robot as built)."""
        if kg != self._payload:
            self._client.changeDynamics(self.body, -1, mass=self._torso_mass + kg)
            self._payload = kg

    def set_com_offset(self, forward: float) -> None:
        """Move the torso's centre of mass `forward` m ahead of the URDF's (0: as built).

        pybullet fixes a body's centre of mass when it loads it, so a new value reloads
        the body from the shifted URDF, with the payload as it was; the body id is the
        one freed, so the world's pair order stays. Call it before `reset()`.
        """
        if forward == self._com_forward:
            return
        client = self._client
        client.removeBody(self.body)
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "shifted.urdf")
            with open(path, "w") as file:
                file.write(shifted_urdf(self._urdf_path, forward))
            self.body = self._load(path)
        client.changeDynamics(self.body, -1, mass=self._torso_mass + self._payload)
        self._com_forward = forward
        self._set_aside = False  # a new body collides with everything
        self._actuate()

    def push(self, impulse: float, duration: float) -> None:
        """Push the torso horizontally along its heading with `impulse` N s (negative:
        backwards), as a force at its centre of mass over the next `duration` s (one
        world step: pybullet clears external forces after each)."""
        client_id = self._client_id
        position, orientation = pybullet.getBasePositionAndOrientation(self.body, client_id)
        matrix = pybullet.getMatrixFromQuaternion(orientation)
        fx, fy = matrix[1], matrix[4]  # the body's y axis (forward), horizontal part
        length = math.hypot(fx, fy) or 1.0
        force = impulse / duration / length
        pybullet.applyExternalForce(
            self.body,
            -1,
            (force * fx, force * fy, 0.0),
            position,
            pybullet.WORLD_FRAME,
            physicsClientId=client_id,
        )

    # -- leaving and entering an episode -----------------------------------------

    @property
    def is_set_aside(self) -> bool:
        """Whether `set_aside` took the body out (until its next `reset`)."""
        return self._set_aside

    def move_clear(self) -> None:
        """Move the body clear of everything (its own spot, far from the world)."""
        x, y, z = _CLEAR_OF_EVERYTHING
        self._client.resetBasePositionAndOrientation(
            self.body, (x, y * (1 + self.body), z), (0.0, 0.0, 0.0, 1.0)
        )

    def set_aside(self, place: tuple[float, float, float]) -> None:
        """Take the body out of the world until its next `reset()`: it collides with
        nothing and is moved to `place`, far from everything (it falls freely there).

        Cheaper than removing the body, but not without a trace: pybullet re-adds a
        link's collider to the world when its filter changes, and where the colliders
        and their broadphase proxies sit decides the order the solver meets contacts in.
        `Scene.reset` builds a fresh world after an episode that set a bot aside.
        """
        client, body = self._client, self.body
        for link in self._links:
            client.setCollisionFilterGroupMask(body, link, 0, 0)
        client.resetBasePositionAndOrientation(body, place, (0.0, 0.0, 0.0, 1.0))
        client.resetBaseVelocity(body, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        self._stop()
        self._set_aside = True

    def _enter(self, drop_contacts: bool) -> None:
        """The start of `reset`: collide again if set aside; with `drop_contacts`, drop
        the last episode's contact points.

        Bullet keeps the contact points of touching bodies from step to step and
        warm-starts its solver from them: points left from the last episode would
        change this one's first steps. Collision detection with the body clear of
        everything drops them. Repositioning (not reloading) stays cheap, and
        tests/test_determinism.py checks that an episode does not depend on the ones
        the world ran before it. `drop_contacts=False` is for a caller that has moved
        every bot clear (`move_clear`) and run collision detection once itself.
        """
        client, body = self._client, self.body
        if self._set_aside:
            for link in self._links:
                client.setCollisionFilterGroupMask(body, link, *_DYNAMIC_COLLISION_FILTER)
            self._set_aside = False
        if drop_contacts:
            self.move_clear()
            client.performCollisionDetection()
