"""A mixed team's policy file (issue 67): one ONNX policy per robot group, in one zip.

A mixed team's bots act in their own robots' spaces (`TaskSpec.robots`), and a MARL
library trains one policy per group of bots of one robot (`TaskSpec.robot_groups`,
BenchMARL's agent groups). The team's file holds one ONNX model per group, each an
ordinary bbbench ONNX policy with its own contract, and a manifest that names the
groups:

    team.zip
      team.json            {"format": "bbbench-team/1",
                            "groups": {"wheel-legged": "wheel-legged.onnx",
                                       "two-wheel": "two-wheel.onnx"}}
      wheel-legged.onnx    the wheel-legged robots' policy
      two-wheel.onnx       the two-wheel bots'

The zip is read as untrusted (`bbbench.policies.archive`: bounded members, nothing
else in it), and each model as any ONNX file (`bbbench.policies.onnx.reader`). A team
file plays the mixed tasks whose groups it names, every one: a file that lacks a group
of the task is refused in one line. `write_team` writes one.
"""

from __future__ import annotations

import hashlib
import io
import json
import zipfile
from pathlib import Path
from typing import Any

from bbbench.files import write_atomic
from bbbench.policies.archive import Archive, read_file
from bbbench.policies.errors import PolicyError, RefusedForSafety
from bbbench.policies.onnx.policy import OnnxPolicy
from bbbench.policies.onnx.reader import MAX_FILE_BYTES, parse_onnx
from bbbench.policies.policy import Actor, Policy, TeamActor, describe_space
from bbbench.robots import ROBOTS
from bbbench.tasks.suite import group_spaces, list_tasks, spec

FORMAT = "bbbench-team/1"
MANIFEST = "team.json"
_MANIFEST_BYTES = 64 * 1024
_KIND = "a mixed team's policy file (team.json and an ONNX model per robot group)"


def is_team_file(path: Path) -> bool:
    """Whether `path` is a zip whose members name a team's manifest: read from its central
    directory only, never trusted beyond that (`TeamFilePolicy` reads it safely)."""
    try:
        if path.suffix.lower() != ".zip" or path.stat().st_size > len(ROBOTS) * MAX_FILE_BYTES:
            return False
        with zipfile.ZipFile(path) as archive:
            return MANIFEST in archive.namelist()
    except (OSError, zipfile.BadZipFile, EOFError, ValueError, NotImplementedError):
        return False


class TeamFilePolicy(Policy):
    """A mixed team's policy file: an `OnnxPolicy` per robot group (`groups`)."""

    deterministic_only = "its graphs give no sampling distribution"

    def __init__(self, path: str | Path) -> None:
        path = Path(path)
        self._read(path, read_file(path, len(ROBOTS) * MAX_FILE_BYTES + _MANIFEST_BYTES, _KIND))

    @classmethod
    def from_bytes(cls, content: bytes, name: str) -> TeamFilePolicy:
        """A team file held in memory (a training's candidate), read as one on disk is;
        `name` stands for its path in messages."""
        policy = cls.__new__(cls)
        policy._read(Path(name), content)
        return policy

    def _read(self, path: Path, content: bytes) -> None:
        self.name = path.name
        self.sha256 = hashlib.sha256(content).hexdigest()
        names = _member_names(path, content)
        limits = {MANIFEST: _MANIFEST_BYTES, **dict.fromkeys(names, MAX_FILE_BYTES)}
        archive = Archive(path, content, limits, required=(MANIFEST,), kind=_KIND)
        groups = _manifest(path, archive.read(MANIFEST))
        self.groups: dict[str, OnnxPolicy] = {}
        for group, member in groups.items():
            if member not in archive:
                raise PolicyError(
                    f"{path}: team.json names {member!r} for the {group} group, and the zip "
                    f"holds no such member"
                )
            model = parse_onnx(archive.read(member), f"{path}:{member}", member)
            self.groups[group] = OnnxPolicy(model)
        modes = {policy.action_mode for policy in self.groups.values()}
        if len(modes) != 1:
            raise PolicyError(
                f"{path}: its groups act in {' and '.join(sorted(modes))} modes; a team acts in "
                f"one, the mode its robots share"
            )
        (self.action_mode,) = modes
        self.algorithm = "/".join(dict.fromkeys(p.algorithm for p in self.groups.values()))

    def mismatch(self, task_id: str) -> str | None:
        """Why the team cannot play `task_id`: not a mixed task, a group of the task the
        file lacks (or one it has that the task does not), or a group's spaces."""
        task = spec(task_id)
        if not task.mixed:
            mixed = [t for t in list_tasks(multi_agent=True, latest=True) if spec(t).mixed]
            return f"{task_id} is not a mixed team's task; a team file plays {', '.join(mixed)}"
        wanted = task.robot_groups
        lacking = [group for group in wanted if group not in self.groups]
        if lacking:
            return (
                f"{task_id} has the groups {', '.join(wanted)}; {self.name} lacks a policy for "
                f"{' and '.join(lacking)} (a member named in its team.json)"
            )
        extra = [group for group in self.groups if group not in wanted]
        if extra:
            return f"{task_id} has no {' or '.join(extra)} bots; its groups are {', '.join(wanted)}"
        if self.action_mode not in task.action_modes:
            return f"{task_id}'s robots act in {' or '.join(task.action_modes)} mode"
        observed = group_spaces(task_id)
        for group, policy in self.groups.items():
            observation, action = observed[group]
            if not policy.reads(observation, action):
                return (
                    f"{task_id}'s {group} bots observe {describe_space(observation)} and act in "
                    f"{describe_space(action)}; the file's {group} policy reads "
                    f"{policy.spaces_text()}"
                )
        return None

    def spaces_text(self) -> str:
        return "; ".join(f"{group}: {p.spaces_text()}" for group, p in self.groups.items())

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        actors = {group: policy.actor(task_id) for group, policy in self.groups.items()}
        return TeamActor(actors, spec(task_id).robots)

    def record(self) -> dict[str, Any]:
        return {**super().record(), "groups": {g: p.sha256 for g, p in self.groups.items()}}


def _member_names(path: Path, content: bytes) -> list[str]:
    """The members a team file holds (limits are set per name before any is read)."""
    try:
        names = zipfile.ZipFile(io.BytesIO(content)).namelist()
    except (zipfile.BadZipFile, EOFError, ValueError, NotImplementedError) as error:
        raise PolicyError(f"{path}: not a readable zip ({error}); expected {_KIND}") from None
    models = [name for name in names if name != MANIFEST]
    strange = [name for name in models if not name.endswith(".onnx") or "/" in name]
    if strange or len(models) > len(ROBOTS):
        raise RefusedForSafety(
            f"{path}: members {strange or models}; {_KIND} holds team.json and at most "
            f"{len(ROBOTS)} .onnx models at its top level"
        )
    return models


def _manifest(path: Path, text: bytes) -> dict[str, str]:
    """team.json's groups (robot name: member), checked."""
    try:
        manifest = json.loads(text)
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise PolicyError(f"{path}: team.json is not JSON ({error})") from None
    groups = manifest.get("groups") if isinstance(manifest, dict) else None
    if (
        not isinstance(manifest, dict)
        or manifest.get("format") != FORMAT
        or not isinstance(groups, dict)
        or not groups
        or not all(isinstance(g, str) and isinstance(m, str) for g, m in groups.items())
    ):
        raise PolicyError(
            f'{path}: team.json must be {{"format": "{FORMAT}", "groups": {{robot: '
            f"member.onnx, ...}}}}, got {text[:120]!r}"
        )
    unknown = [group for group in groups if group not in ROBOTS]
    if unknown:
        raise PolicyError(
            f"{path}: team.json names the group(s) {unknown}; a group is a robot, one of "
            f"{', '.join(ROBOTS)}"
        )
    return groups


def write_team(path: Path, models: dict[str, bytes]) -> None:
    """Write a team file atomically: `models` maps each robot group to its ONNX bytes."""
    write_atomic(Path(path), team_bytes(models))


def team_bytes(models: dict[str, bytes]) -> bytes:
    """A team file's bytes (the same for the same models): `models` maps each robot group
    to its ONNX bytes."""
    unknown = [group for group in models if group not in ROBOTS]
    if unknown or not models:
        raise ValueError(
            f"a team file holds an ONNX model per robot group ({', '.join(ROBOTS)}), got "
            f"{unknown or 'none'}"
        )
    buffer = io.BytesIO()
    manifest = {"format": FORMAT, "groups": {group: f"{group}.onnx" for group in models}}
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in [(MANIFEST, json.dumps(manifest, indent=1).encode())] + [
            (f"{group}.onnx", data) for group, data in models.items()
        ]:
            info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))  # the same bytes
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, data)
    return buffer.getvalue()
