"""Option audit: mistaken or hostile option values of every command are refused with one line
naming the option and what is wrong (exit 2), before any work and without touching any file.

Each test asserts the exit code, the message and the files left behind.
"""

from pathlib import Path

import pytest

from tests.clihelp import run

S11 = Path("specimens/example1/S1.1.yaml")


def no_traceback(r):
    assert "Traceback" not in r.output
    assert r.exception is None or isinstance(r.exception, SystemExit), repr(r.exception)


# ------------------------------------------------------------------------------- --seed
@pytest.mark.parametrize("command", ["identify", "batch"])
@pytest.mark.parametrize("seed", ["-1", "99999999999999999999999"])
def test_seed_outside_what_the_random_generator_and_the_file_take_is_refused(
        tmp_path, command, seed):
    # was: numpy's "ValueError: expected non-negative integer" as a traceback (identify) or
    # as "internal error" of every specimen (batch); a seed above 2**63 failed writing the
    # result file (h5py: "Object dtype has no native HDF5 equivalent")
    out = tmp_path / "out"
    where = ["-o", out] if command == "identify" else ["--out", out]
    r = run(command, S11, "--mesh", "4x4", "--monte-carlo", "2", "--seed", seed, *where)
    no_traceback(r)
    assert r.exit_code == 2
    assert (f"Invalid value for '--seed': {seed} is not in the range "
            "0<=x<=9223372036854775807.") in r.output
    assert not out.exists()

