"""Hostile or mistaken input never crashes, hangs, leaks processes or eats memory.

Each small file or flag here cost gigabytes, minutes, a traceback or stray
processes before; now each is a one-line error with exit code 2 (or a clean
stop), checked before any episode is played.
"""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import threading
import time
import zipfile
from pathlib import Path

import gymnasium as gym
import pytest
import torch
from stable_baselines3 import PPO, SAC

import bbbench
from bbbench import evaluation
from bbbench.cli import main
from bbbench.files import write_atomic
from bbbench.policies import PolicyError, load_policy
from conftest import FLAT, rewrite

EVAL_FLAT = ["--task", FLAT, "--episodes", "1", "--workers", "1"]


@pytest.fixture(scope="module")
def ppo_zip(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("ppo") / "ppo.zip"
    PPO("MlpPolicy", bbbench.make(FLAT), n_steps=64, batch_size=64, device="cpu").save(path)
    return path


def one_line_exit_2(capsys, *argv: str) -> str:
    code = main(list(argv))
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("bbbench: error:"), err
    assert len(err.strip().splitlines()) == 1, err
    return err


def run_bbbench(*argv: str, **kwargs) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "bbbench", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        **kwargs,
    )


def children(pid: int) -> list[int]:
    """The processes whose parent is `pid` (Linux /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                found.append(int(entry.name))
    return found


def alive(pid: int) -> bool:
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def wait_for_workers(process: subprocess.Popen, count: int) -> list[int]:
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        workers = children(process.pid)
        if len(workers) >= count:
            time.sleep(1.0)  # let them start playing
            return workers
        time.sleep(0.1)
    process.kill()
    raise AssertionError(f"no {count} workers appeared: {process.communicate()}")


# -- 5. bounded resources --------------------------------------------------------------


def test_a_small_file_declaring_a_huge_tensor_is_refused_without_allocating_it(ppo_zip, tmp_path):
    state = PPO.load(ppo_zip, device="cpu").policy.state_dict()
    state["action_net.bias"] = torch.zeros(1).as_strided((2**29,), (0,))  # 2 GiB as float32
    weights = io.BytesIO()
    torch.save(state, weights)
    hostile = rewrite(ppo_zip, tmp_path / "view.zip", members={"policy.pth": weights.getvalue()})
    assert hostile.stat().st_size < 2**20
    # This child's own peak (os.wait4), not RUSAGE_CHILDREN's: that is the largest of every
    # child the test process has waited for, and other tests' children peak above 2 GB.
    child = subprocess.Popen(
        [sys.executable, "-m", "bbbench", "eval", str(hostile), *EVAL_FLAT],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    stderr = child.stderr.read()
    _, status, usage = os.wait4(child.pid, 0)
    child.returncode = os.waitstatus_to_exitcode(status)
    child.stderr.close()
    assert child.returncode == 2, stderr
    assert "parameters" in stderr
    assert len(stderr.strip().splitlines()) == 1
    assert usage.ru_maxrss < 1.5 * 2**20  # KiB: under 1.5 GiB (the view is 2 GiB)


@pytest.mark.parametrize(
    ("algorithm", "kwargs"),
    [("PPO", {"net_arch": [4096] * 8}), ("SAC", {"net_arch": [2048] * 2, "n_critics": 8})],
    ids=["wide-PPO", "SAC-many-critics"],
)
def test_a_declared_architecture_over_the_cap_is_refused_before_building(
    ppo_zip, tmp_path, algorithm, kwargs
):
    source = ppo_zip
    if algorithm == "SAC":
        source = tmp_path / "sac.zip"
        SAC("MlpPolicy", bbbench.make(FLAT, action_mode="continuous"), device="cpu").save(source)

    def huge(data):
        data["policy_kwargs"] = kwargs

    with pytest.raises(PolicyError, match="parameters"):
        load_policy(rewrite(source, tmp_path / "huge.zip", huge))


# -- 6, 7. workers and Ray --------------------------------------------------------------


def test_more_workers_than_cores_is_capped_in_one_line(capsys):
    cores = len(os.sched_getaffinity(0))
    code = main(["eval", "pd", "--task", FLAT, "--episodes", "2", "--workers", str(cores + 50)])
    err = capsys.readouterr().err
    assert code == 0
    assert f"--workers {cores + 50} is more than the {cores} core(s) here: using {cores}" in err


@pytest.mark.parametrize(
    ("address", "expected"),
    [("127.0.0.1:1", "no Ray cluster answers there"), ("not-an-address", "not a Ray address")],
)
def test_an_unreachable_or_malformed_ray_address_is_exit_2_naming_it(capsys, address, expected):
    pytest.importorskip("ray")
    err = one_line_exit_2(capsys, "eval", "pd", "--backend", "ray", "--address", address)
    assert address in err
    assert expected in err


# -- 8, 11. processes -------------------------------------------------------------------


def test_workers_die_with_a_killed_parent():
    command = run_bbbench("eval", "pd", "--task", FLAT, "--workers", "2")
    workers = wait_for_workers(command, 2)
    os.kill(command.pid, signal.SIGKILL)
    command.wait()
    deadline = time.monotonic() + 5
    while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [pid for pid in workers if alive(pid)]


BATCHED_SCRIPT = """
import time
from bbbench.envs.factory import make_batched
env = make_batched("bbbench/Swap-v0", worlds=2, workers=2)
env.reset(seed=0)
time.sleep(120)
"""


@pytest.mark.parametrize("signum", [signal.SIGKILL, signal.SIGTERM])
def test_a_batched_envs_workers_die_with_its_killed_script(signum):
    script = subprocess.Popen([sys.executable, "-c", BATCHED_SCRIPT], start_new_session=True)
    workers = wait_for_workers(script, 1)
    os.kill(script.pid, signum)
    script.wait()
    deadline = time.monotonic() + 5
    while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [pid for pid in workers if alive(pid)]


@pytest.mark.parametrize(("signum", "code", "word"), [
    (signal.SIGINT, 130, "interrupted"),
    (signal.SIGTERM, 143, "terminated"),
])  # fmt: skip
def test_ctrl_c_and_sigterm_stop_in_one_line_leaving_nothing_behind(tmp_path, signum, code, word):
    out = tmp_path / "results.json"
    # As from a terminal: a shell without job control starts background commands (the
    # tests, run with `&`) with Ctrl-C ignored, and children inherit that.
    command = run_bbbench(
        "eval", "pd", "--task", FLAT, "--workers", "2", "--json", str(out),
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    workers = wait_for_workers(command, 2)
    if signum == signal.SIGINT:
        os.killpg(command.pid, signum)  # as a terminal's Ctrl-C: the whole process group
    else:
        os.kill(command.pid, signum)
    _, err = command.communicate(timeout=30)
    assert command.returncode == code, err
    assert err.strip() == f"bbbench: {word}; nothing written"
    assert list(tmp_path.iterdir()) == []  # no results, no temporary file
    time.sleep(0.5)
    assert not [pid for pid in workers if alive(pid)]


@pytest.mark.slow
def test_ctrl_c_stops_a_marl_training_in_one_line_with_no_leaked_semaphore(tmp_path):
    """Ctrl-C in the middle of an IPPO training with worker processes: one line, exit 130,
    no worker left, nothing written, and no warning of leaked semaphores after it."""
    command = run_bbbench(
        "train", "bbbench/Swap-v0", "--algo", "ippo", "--workers", "2",
        "--out", str(tmp_path / "policy.onnx"),
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    workers = wait_for_workers(command, 2)  # the resource tracker and a worlds worker
    time.sleep(5)  # well into the first batch's collection
    os.killpg(command.pid, signal.SIGINT)
    _, err = command.communicate(timeout=60)
    assert command.returncode == 130, err
    assert err.strip() == "bbbench: interrupted; nothing written"
    assert list(tmp_path.iterdir()) == []
    time.sleep(0.5)
    assert not [pid for pid in workers if alive(pid)]


# -- 9, 10. files -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("flag", "name", "expected"),
    [
        ("--json", "{dir}", "is a directory"),
        ("--json", "", "is empty"),
        ("--json", "/", "is a directory"),
        ("--json", "{dir}/sub/", "is a directory"),
        ("--json", "/proc/results.json", "cannot write in /proc"),
        ("--json", "{dir}/missing/results.json", "no directory"),
        ("--video", "{dir}", "is a directory"),
        ("--video", "/proc/episode.gif", "cannot write in /proc"),
    ],
)
def test_output_paths_are_checked_before_any_episode(
    tmp_path, capsys, monkeypatch, flag, name, expected
):
    (tmp_path / "sub").mkdir()

    def never(*args, **kwargs):
        raise AssertionError("an episode was played before the output path was checked")

    monkeypatch.setattr(evaluation, "evaluate", never)
    err = one_line_exit_2(capsys, "eval", "pd", flag, name.format(dir=tmp_path))
    assert expected in err


def test_concurrent_writers_of_one_path_never_collide(tmp_path):
    path = tmp_path / "results.json"
    errors = []

    def write(k: int) -> None:
        try:
            for i in range(30):
                write_atomic(path, json.dumps({"writer": k, "i": i}).encode())
        except Exception as error:  # any collision fails the test
            errors.append(error)

    threads = [threading.Thread(target=write, args=(k,)) for k in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == []
    assert json.loads(path.read_text())["i"] == 29
    assert [p.name for p in tmp_path.iterdir()] == ["results.json"]


def test_a_planted_link_at_the_old_temporary_name_is_not_followed(tmp_path):
    target = tmp_path / "precious.txt"
    target.write_text("keep me")
    (tmp_path / ".results.json.partial").symlink_to(target)
    write_atomic(tmp_path / "results.json", b"{}")
    assert target.read_text() == "keep me"
    assert (tmp_path / "results.json").read_text() == "{}"


# -- 12. clear errors, naming the file --------------------------------------------------


def with_member(source: Path, target: Path, name: str, method: int, flags: int = 0) -> Path:
    """A copy of `source` whose member `name` is stored with another method and flags."""
    members = {}
    with zipfile.ZipFile(source) as archive:
        for info in archive.infolist():
            members[info.filename] = archive.read(info.filename)
    with zipfile.ZipFile(target, "w") as archive:
        for member, content in members.items():
            info = zipfile.ZipInfo(member)
            info.compress_type = method if member == name else zipfile.ZIP_DEFLATED
            archive.writestr(info, content)
    content = bytearray(target.read_bytes())
    if flags:  # set the flag bits in the local header and the central directory entry
        for signature, offset in ((b"PK\x03\x04", 6), (b"PK\x01\x02", 8)):
            start = 0
            while (start := content.find(signature, start)) != -1:
                header_name = content[start + (30 if offset == 6 else 46) :][: len(name)]
                if header_name == name.encode():
                    content[start + offset] |= flags
                start += 4
        target.write_bytes(bytes(content))
    return target


def corrupt_member(path: Path, name: str) -> Path:
    """Flip bytes in the middle of a member's compressed stream."""
    with zipfile.ZipFile(path) as archive:
        info = archive.getinfo(name)
    content = bytearray(path.read_bytes())
    start = info.header_offset + 30 + len(name) + len(info.extra)
    for i in range(start + 4, start + min(info.compress_size, 40)):
        content[i] ^= 0x5A
    path.write_bytes(bytes(content))
    return path


def test_unreadable_and_malformed_zips_are_one_line_errors_naming_the_file(
    ppo_zip, tmp_path, capsys
):
    deep_list = tmp_path / "deep-list.zip"
    rewrite(ppo_zip, deep_list, members={"data": b"[" * 5000 + b"]" * 5000})
    deep_dict = tmp_path / "deep-dict.zip"

    def nested(data):
        value = {}
        for _ in range(900):
            value = {"x": value}
        data["policy_kwargs"] = value

    rewrite(ppo_zip, deep_dict, nested)
    cases = {
        deep_list: "nests",
        deep_dict: "nests",
        with_member(ppo_zip, tmp_path / "encrypted.zip", "data", zipfile.ZIP_DEFLATED, 0x1): (
            "encrypted"
        ),
        with_member(ppo_zip, tmp_path / "bzip2.zip", "policy.pth", zipfile.ZIP_BZIP2): "bzip2",
        with_member(ppo_zip, tmp_path / "lzma.zip", "policy.pth", zipfile.ZIP_LZMA): "lzma",
        corrupt_member(rewrite(ppo_zip, tmp_path / "corrupt.zip"), "policy.pth"): "policy.pth",
    }
    for path, expected in cases.items():
        err = one_line_exit_2(capsys, "eval", str(path), *EVAL_FLAT)
        assert expected in err, (path.name, err)
        assert str(path) in err, (path.name, err)


def test_a_member_inflating_beyond_its_declared_size_is_called_a_zip_bomb(ppo_zip, tmp_path):
    big = b"{" + b" " * 100_000 + b"}"
    path = rewrite(ppo_zip, tmp_path / "liar.zip", members={"data": big})
    content = bytearray(path.read_bytes())
    size = len(big).to_bytes(4, "little")
    path.write_bytes(bytes(content.replace(size, (10).to_bytes(4, "little"))))
    with pytest.raises(PolicyError, match="inflates beyond the 10 bytes its header declares"):
        load_policy(path)


def test_an_unreadable_policy_file_is_a_one_line_error(ppo_zip, capsys, monkeypatch):
    from bbbench.policies import archive

    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(archive, "open", denied, raising=False)
    err = one_line_exit_2(capsys, "eval", str(ppo_zip), *EVAL_FLAT)
    assert f"{ppo_zip}: cannot read it (Permission denied)" in err


@pytest.mark.parametrize(
    ("space", "expected"),
    [
        ({"n": "²"}, "Discrete"),
        ({"low": "[2.]", "high": "[1.]"}, "low <= high"),
        ({"low": "[nan]"}, "finite"),
    ],
)
def test_odd_spaces_name_the_file(tmp_path, space, expected):
    env = bbbench.make(FLAT, action_mode="discrete" if "n" in space else "continuous")
    path = tmp_path / "odd.zip"
    PPO("MlpPolicy", env, n_steps=64, batch_size=64, device="cpu").save(path)
    odd = rewrite(path, tmp_path / "odder.zip", lambda data: data["action_space"].update(space))
    with pytest.raises(PolicyError, match=expected) as raised:
        load_policy(odd)
    assert str(odd) in str(raised.value)


@pytest.mark.parametrize("command", ["terrain", "rollout"])
def test_a_negative_seed_is_exit_2(tmp_path, capsys, command):
    extra = ["--out", str(tmp_path / "t.obj")] if command == "terrain" else []
    err = one_line_exit_2(capsys, command, "--seed", "-1", *extra)
    assert "--seed -1" in err


# -- 13-16. the APIs ----------------------------------------------------------------------


def test_keyword_mistakes_say_what_is_wrong():
    with pytest.raises(TypeError, match=r"unknown keyword argument\(s\) \['foo'\] for"):
        gym.make("bbbench/Bumps-v0", foo=1)
    with pytest.raises(ValueError, match=r"difficulty must be a number in \[0, 1\], got 'abc'"):
        gym.make("bbbench/Bumps-v0", difficulty="abc")
    env = bbbench.make_parallel("bbbench/MultiBalance-v0")
    env.reset(seed=0)
    with pytest.raises(TypeError, match="step\\(\\) takes a dict of actions"):
        env.step(None)


def test_each_multi_bot_task_is_named_after_itself():
    env = bbbench.make_parallel("bbbench/MultiBumps-v0")
    assert env.metadata["name"] == str(env) == "bbbench_multibumps"
    assert str(bbbench.make_parallel("bbbench/MultiBalance-v0")) == "bbbench_multibalance"


def test_human_rendering_without_a_display_is_a_python_error_not_an_exit():
    script = (
        "import bbbench, gymnasium as gym\n"
        "from gymnasium.utils.env_checker import check_env\n"
        "env = gym.make('bbbench/FlatBalance-v0')\n"
        "try:\n"
        "    check_env(env.unwrapped)\n"
        "except RuntimeError as error:\n"
        "    print('raised:', error)\n"
    )
    environment = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=environment, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert 'raised: render_mode="human"' in done.stdout
    assert "DISPLAY is not set" in done.stdout


# -- 17, 18. one list of policies; no banners ---------------------------------------------


def test_rollout_and_eval_share_the_built_in_policies_and_rollout_takes_a_zip(ppo_zip, capsys):
    assert main(["eval", "zero", "--task", FLAT, "--episodes", "1", "--workers", "1"]) == 0
    assert main(["rollout", "--policy", "reference", "--episodes", "1"]) == 0
    assert main(["rollout", "--policy", str(ppo_zip), "--episodes", "1"]) == 0
    assert main(["rollout", "--policy", "random", "--episodes", "1"]) == 0
    out = capsys.readouterr().out
    assert "'random' policy (random actions)" in out
    assert "deterministic" not in out.split("'random' policy")[1].splitlines()[0]
    main(["eval", "random", "--task", FLAT, "--episodes", "1", "--workers", "1"])
    assert "random (random, discrete actions, sampled)" in capsys.readouterr().out


def test_commands_print_no_pybullet_banner():
    done = subprocess.run(
        [sys.executable, "-m", "bbbench", "eval", "pd", *EVAL_FLAT],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    for text in (done.stdout, done.stderr):
        assert "pybullet build time" not in text
        assert "argv[0]" not in text
    assert done.stderr == ""


def test_a_world_whose_connect_was_interrupted_is_collected_without_a_traceback(
    capsys, monkeypatch
):
    import gc

    import pybullet

    from bbbench.sim import World

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt  # a Ctrl-C inside pybullet.connect

    unraisable = []  # what Python prints as "Exception ignored in ..."
    monkeypatch.setattr(sys, "unraisablehook", unraisable.append)
    monkeypatch.setattr(pybullet, "connect", interrupted)
    with pytest.raises(KeyboardInterrupt):
        World(time_step=0.01).client  # noqa: B018 (connects)
    gc.collect()  # the half-made client's __del__ (pybullet_utils') ran: it read `_client`
    assert unraisable == []
    assert capsys.readouterr().err == ""
