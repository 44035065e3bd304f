"""Trainings count the trainings beside them, as measured: other processes' held locks,
not what a script asked for."""

import subprocess
import sys
import textwrap

from bbbench.training.beside import described, trainings_beside

HOLD = textwrap.dedent(
    """
    import sys
    from bbbench.training.beside import trainings_beside
    with trainings_beside(every=3600, root=sys.argv[1]):
        print("holding", flush=True)
        sys.stdin.read()
    """
)


def _holder(root):
    process = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(root)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert process.stdout.readline() == "holding\n"
    return process


def test_a_training_counts_the_others_running_and_not_those_that_died(tmp_path):
    first, second = _holder(tmp_path), _holder(tmp_path)
    with trainings_beside(every=3600, root=tmp_path) as beside:
        assert beside.sample() == 2
        second.kill()  # no clean exit: its file stays, its lock dies with it
        second.wait()
        assert len(list((tmp_path / "bbbench-trainings").glob("*.lock"))) == 3
        assert beside.sample() == 1
        assert len(list((tmp_path / "bbbench-trainings").glob("*.lock"))) == 2
        first.communicate("")  # a clean end removes its own file
        assert beside.sample() == 0
    assert beside.record() == {"most": 2, "mean": 1.0, "samples": 5}
    assert list((tmp_path / "bbbench-trainings").glob("*.lock")) == []


def test_two_trainings_in_one_process_see_each_other(tmp_path):
    with (
        trainings_beside(every=3600, root=tmp_path) as one,
        trainings_beside(every=3600, root=tmp_path) as other,
    ):
        assert (one.sample(), other.sample()) == (1, 1)
    assert one.record()["most"] == 1


def test_the_board_says_what_was_measured():
    assert described(None) == ""
    assert described({"most": 0, "mean": 0.0, "samples": 9}) == "one training"
    assert described({"most": 1, "mean": 1.0, "samples": 9}) == "2 trainings side by side"
    assert (
        described({"most": 1, "mean": 0.4, "samples": 9})
        == "up to 2 trainings side by side (1.4 on average)"
    )
