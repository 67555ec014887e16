"""``laminid acquire`` end to end against the loopback emulators (127.0.0.1 only).

Every run reaches the emulator through pyvisa-py as ``TCPIP::127.0.0.1::<port>::SOCKET``;
timeouts are short so the fault tests stay fast.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.frf import store
from tests.instrument.emulator import (PLATE_MODES, Fault, HP35670AEmulator, PlateSimulator,
                                       SR785Emulator)

FAST = ["--timeout", "0.5", "--averages", "3", "--span", "1600", "--lines", "800"]


def read_frf_h5(path):
    """Read back a file this test has just written, in this process. The child-process probe
    of store.read_frf_h5 guards against files of unknown origin that crash libhdf5 (its own
    tests: test_hostile_input.py, test_fuzz.py) and costs an interpreter start (~0.3 s) per
    read; the reads inside ``laminid acquire --resume`` and ``fit-frf`` still probe."""
    return store.read_frf_h5(path, probe=False)


def run(args, input=None):
    return CliRunner().invoke(cli, args, input=input, catch_exceptions=False)


@pytest.fixture
def hp():
    with HP35670AEmulator() as emu:
        yield emu


@pytest.fixture
def sr():
    with SR785Emulator() as emu:
        yield emu


def acquire(emu, out, *extra, points=3, input=None):
    return run(["acquire", "--analyser", emu.resource, *FAST, "--points", str(points),
                "-o", str(out), *extra], input=input)


# ------------------------------------------------------------------------- happy paths
@pytest.mark.parametrize("emu_cls, model", [(HP35670AEmulator, "35670A"),
                                            (SR785Emulator, "SR785")])
def test_acquire_writes_every_point_with_identity_settings_and_units(tmp_path, emu_cls, model):
    out = tmp_path / "plate.frf.h5"
    with emu_cls() as emu:
        r = acquire(emu, out, "--no-prompt", "--units", "Pa/N")
    assert r.exit_code == 0, r.output
    assert "point 3: 3 hits, coherence at resonances" in r.output
    s = read_frf_h5(out)
    assert s.n_points == 3 and s.labels == ("1", "2", "3") and s.units == "Pa/N"
    assert s.meta["complete"] is True
    assert s.meta["instrument"]["model"] == model
    assert s.meta["instrument"]["idn"] == emu.idn
    assert s.meta["settings"]["span_hz"] == 1600.0 and s.meta["settings"]["lines"] == 800
    assert s.meta["settings"]["averages"] == 3
    assert s.meta["points"]["n_averages"] == [3, 3, 3]
    np.testing.assert_allclose(s.freq, np.arange(801) * 2.0)
    # the averaged H1 is the plate's FRF within the noise (FRF peak vs truth at point 2)
    truth, _ = PlateSimulator().average(s.freq, 2, 1000, emu.exp_tau_s(), measurement=99)
    k = int(np.argmax(np.abs(truth)))
    assert abs(s.frf[1, k] - truth[k]) < 0.02 * abs(truth[k])
    assert np.all(s.coherence[:, k] > 0.99)


def test_prompted_session_skips_quits_and_repeats_a_poor_point(tmp_path, hp):
    out = tmp_path / "p.h5"
    # point 1: go, coherence poor (threshold 1.0) -> repeat "y", then "n"; point 2: skip;
    # point 3: quit
    r = acquire(hp, out, "--coherence-min", "1.0", input="\ny\nn\ns\nq\n")
    # issue 12: points missing -> non-zero exit (3) with the resume hint
    assert r.exit_code == 3, r.output
    assert r.output.count("POOR coherence") == 2
    assert "Repeat point 1?" in r.output
    assert "1 of 3 point(s) saved; continue with:" in r.output and "--resume" in r.output
    # not a terminal: one progress line per event, no carriage returns
    assert "\r" not in r.output
    assert "point 1 (1/3): waiting for 3 hits\npoint 1 (1/3): 3/3 hits averaged\n" in r.output
    s = read_frf_h5(out)
    assert s.labels == ("1",) and s.meta["complete"] is False


def test_json_summary_on_stdout_for_shell_batches(tmp_path, hp):
    """--json: stdout is one JSON document (file, points saved, each point's quality as the
    file records it); quality lines and prompts go to stderr. With points missing (quit) it is
    printed too, complete false, with the resume command (exit 3)."""
    import json

    out = tmp_path / "j.h5"
    r = acquire(hp, out, "--no-prompt", "--json", "--units", "Pa/N", points=2)
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    s = read_frf_h5(out)
    assert d["file"] == str(out) and d["complete"] is True and d["resume"] is None
    assert d["points_requested"] == d["points_saved"] == 2 and d["measured"] == ["1", "2"]
    assert d["frf_unit"] == "Pa/N" and d["lines"] == s.freq.size == 801
    assert d["units"] == "Pa/N"            # frf_unit's old name, kept for 0.2.x
    assert (d["f_start_hz"], d["f_stop_hz"]) == (s.freq[0], s.freq[-1])
    assert d["instrument"]["model"] == "35670A"
    assert [p["label"] for p in d["points"]] == list(s.labels)
    pts = s.meta["points"]
    for p, n_avg, ovl in zip(d["points"], pts["n_averages"], pts["overloads"]):
        assert (p["n_averages"], p["overloads"]) == (n_avg, ovl) == (3, 0)
        assert 0.9 <= p["coherence_resonance"] <= 1.0 and p["ok"] is True
    assert "coherence at resonances" not in r.stdout and "coherence at resonances" in r.stderr
    # prompted, poor coherence, point 1 kept after one repeat, then quit: exit 3, JSON printed
    r = acquire(hp, tmp_path / "q.h5", "--coherence-min", "1.0", "--json",
                input="\ny\nn\nq\n")
    assert r.exit_code == 3, r.output
    d = json.loads(r.stdout)
    assert d["complete"] is False and d["points_saved"] == 1 and d["quit"] is True
    assert d["repeated"] == 1 and d["points"][0]["ok"] is False
    assert "--resume" in d["resume"] and "--json" in d["resume"]
    assert "Repeat point 1?" in r.stderr and "Repeat point 1?" not in r.stdout
    # a session the operator ended is no error: "laminid: stopped: ..."
    assert "laminid: stopped: " in r.stderr and "laminid: error:" not in r.stderr


def test_resume_continues_an_incomplete_file(tmp_path, hp):
    out = tmp_path / "r.h5"
    assert acquire(hp, out, "--no-prompt", points=2).exit_code == 0
    r = acquire(hp, out, "--no-prompt", "--resume", points=4)
    assert r.exit_code == 0, r.output
    assert "resuming, 2 of 4 point(s) already measured" in r.output
    assert read_frf_h5(out).labels == ("1", "2", "3", "4")


def test_resume_without_a_file_starts_one_and_says_so(tmp_path, hp):
    """Scripts may pass --resume every time: without the file it starts a new one, with a note
    on stderr (it used to be silent)."""
    out = tmp_path / "new.h5"
    r = acquire(hp, out, "--no-prompt", "--resume", points=2)
    assert r.exit_code == 0, r.output
    assert f"laminid: note: {out}: no file to resume; starting a new one" in r.stderr
    assert read_frf_h5(out).labels == ("1", "2")


def test_resume_refuses_other_windows_before_touching_the_analyser(tmp_path, hp):
    """A file measured with --exp-window 0.1 (force window 0.01 s): --resume --points 8
    --exp-window 0.5 --force-window 0.05 is refused (exit 2) naming the file, both settings,
    recorded and requested values; the file and the analyser's set-up are left as they were."""
    out = tmp_path / "w.h5"
    assert acquire(hp, out, "--no-prompt", "--exp-window", "0.1", points=2).exit_code == 0
    before = out.read_bytes()
    hp.settings.clear()
    r = CliRunner().invoke(cli, ["acquire", "--analyser", hp.resource, *FAST, "--points", "8",
                                 "--no-prompt", "--resume", "--exp-window", "0.5",
                                 "--force-window", "0.05", "-o", str(out)])
    assert r.exit_code == 2, r.output
    assert "Traceback" not in r.output
    assert (f"{out}: cannot resume, its points were measured with other settings than this "
            "run's (force window: recorded 0.01 s, requested 0.05 s (--force-window); exp "
            "window: recorded 0.1 s, requested 0.5 s (--exp-window))") in r.output
    assert "resume with the recorded values (--force-window 0.01 --exp-window 0.1" in r.output
    assert out.read_bytes() == before
    s = read_frf_h5(out)
    assert s.n_points == 2 and s.meta["settings"]["exp_window_s"] == 0.1
    assert "WIND2:EXP" not in hp.settings        # refused before anything was sent
    # a different pre-trigger is refused the same way; --averages may differ
    r = CliRunner().invoke(cli, ["acquire", "--analyser", hp.resource, *FAST, "--points", "3",
                                 "--no-prompt", "--resume", "--pretrigger", "0.02", "-o",
                                 str(out)])
    assert r.exit_code == 2 and "pretrigger: recorded 0.005 s, requested 0.02 s" in r.output
    r = run(["acquire", "--analyser", hp.resource, "--timeout", "0.5", "--averages", "2",
             "--points", "3", "--no-prompt", "--resume", "-o", str(out)])
    assert r.exit_code == 0, r.output
    s = read_frf_h5(out)
    assert s.labels == ("1", "2", "3") and s.meta["points"]["n_averages"] == [3, 3, 2]
    assert s.meta["settings"]["exp_window_s"] == 0.1


def test_resume_refuses_other_units_before_touching_the_analyser(tmp_path, hp):
    """A Pa/N file resumed with --units V/V (or without --units: V/V) is refused like a
    different window: exit 2, naming the file, the recorded and the requested unit and the
    option that resumes it; before anything is sent to the analyser (it used to configure the
    analyser first, then say only "FRF units differ (Pa/N vs V/V)"), --keep-setup too."""
    out = tmp_path / "u.h5"
    assert acquire(hp, out, "--no-prompt", "--units", "Pa/N", points=1).exit_code == 0
    before = out.read_bytes()
    hp.settings.clear()
    for extra in ([], ["--units", "(m/s^2)/N"], ["--keep-setup"]):
        r = acquire(hp, out, "--no-prompt", "--resume", *extra, points=2)
        assert r.exit_code == 2, r.output
        requested = "(m/s^2)/N" if extra[:1] == ["--units"] else "V/V"
        assert (f"{out}: cannot resume, its points were measured with other settings than "
                f"this run's (units: recorded Pa/N, requested {requested} (--units))") \
            in r.output
        assert "resume with the recorded values (--units Pa/N" in r.output
        assert "35670A at" not in r.output        # the analyser was not even opened
        assert hp.settings == {}
    assert out.read_bytes() == before
    r = acquire(hp, out, "--no-prompt", "--resume", "--units", "Pa/N", points=2)
    assert r.exit_code == 0, r.output
    assert read_frf_h5(out).labels == ("1", "2")


def test_resume_with_fewer_points_than_saved_is_refused(tmp_path, hp):
    """--resume --points 2 on an unfinished file of 3 points (a session of 5, quit at point
    4) measures nothing: refused (exit 2) naming the file, its points and the least --points
    that resumes it; the file is left as it was (it was marked complete with n_points 2 while
    holding 3 points, after "resuming, 3 of 2 point(s) already measured"). A complete file:
    test_resume_of_a_complete_file_..."""
    out = tmp_path / "n.h5"
    assert acquire(hp, out, points=5, input="\n\n\nq\n").exit_code == 3
    before = out.read_bytes()
    hp.settings.clear()
    r = acquire(hp, out, "--no-prompt", "--resume", points=2)
    assert r.exit_code == 2, r.output
    assert (f"laminid: error: {out}: cannot resume, the file already holds 3 points (1, 2, 3) "
            "and --points 2 asks for fewer: nothing to measure; give the session's number of "
            "points (at least --points 3) to measure the rest") in r.output
    assert "of 2 point(s) already measured" not in r.output
    assert out.read_bytes() == before and hp.settings == {}
    s = read_frf_h5(out)
    assert s.meta["settings"]["n_points"] == 5 and s.labels == ("1", "2", "3")
    assert s.meta["complete"] is False


def _free_port_resource() -> str:
    """A VISA resource on a local port nobody listens on: opening it fails."""
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"TCPIP::127.0.0.1::{s.getsockname()[1]}::SOCKET"


def test_resume_of_a_complete_file_says_so_without_opening_the_analyser(tmp_path, hp):
    """--resume of a file that has every point: exit 0, saying it is complete (its points,
    axis and units) and what to do next (fit-frf; another -o or --force to measure again;
    more --points to add some), without opening the analyser (none at --analyser: it failed
    with "no analyser at ..."; one there was opened, and the file rewritten) and with the
    file unchanged byte for byte."""
    out = tmp_path / "done.frf.h5"
    assert acquire(hp, out, "--no-prompt", "--units", "Pa/N", points=3).exit_code == 0
    before = out.read_bytes()
    r = run(["acquire", "--analyser", _free_port_resource(), *FAST, "--points", "3",
             "--units", "Pa/N", "--no-prompt", "--resume", "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "no analyser at" not in r.output and "Traceback" not in r.output
    assert (f"{out}: already complete: 3 points (1, 2, 3), 801 lines 0-1600 Hz, Pa/N; "
            "nothing to measure: the analyser was not opened and the file is unchanged"
            ) in r.stderr
    assert (f"next: laminid fit-frf {out} --into specimen.yaml; to measure the plate again "
            "write another file (-o NEW.frf.h5) or replace this one (--force, without "
            "--resume: its 3 points would be lost); to add points --resume --points 4 or "
            "more") in r.stderr
    assert out.read_bytes() == before
    # with the analyser there: not a command sent to it; --json the summary, nothing measured
    n_log = len(hp.log)
    r = acquire(hp, out, "--no-prompt", "--units", "Pa/N", "--resume", "--json", points=3)
    assert r.exit_code == 0, r.output
    assert len(hp.log) == n_log and "35670A at" not in r.stderr
    d = json.loads(r.stdout)
    assert d["already_complete"] is True and d["complete"] is True
    assert d["points_saved"] == 3 and d["points_requested"] == 3 and d["measured"] == []
    assert d["frf_unit"] == d["units"] == "Pa/N"
    assert d["lines"] == 801 and d["f_stop_hz"] == 1600.0
    assert d["instrument"]["model"] == "35670A" and d["resume"] is None
    assert out.read_bytes() == before
    # fewer --points than the complete file holds: complete too, and said
    r = acquire(hp, out, "--no-prompt", "--units", "Pa/N", "--resume", points=2)
    assert r.exit_code == 0, r.output
    assert "it holds more points than --points 2 asks for" in r.stderr
    assert len(hp.log) == n_log and out.read_bytes() == before
    # other settings than the file's: refused as for a file with points to add (it said
    # "already complete", exit 0, as if the file were what was asked for)
    r = run(["acquire", "--analyser", _free_port_resource(), *FAST, "--points", "3",
             "--units", "Pa/N", "--span", "800", "--no-prompt", "--resume", "-o", str(out)])
    assert r.exit_code == 2 and "already complete" not in r.stderr, r.output
    assert f"laminid: error: {out}: cannot resume" in r.stderr and "800" in r.stderr
    assert "1600" in r.stderr and out.read_bytes() == before
    # more --points: the rest is measured as before
    r = acquire(hp, out, "--no-prompt", "--units", "Pa/N", "--resume", points=4)
    assert r.exit_code == 0, r.output
    assert "resuming, 3 of 4 point(s) already measured" in r.stderr
    assert read_frf_h5(out).labels == ("1", "2", "3", "4")


def test_resume_of_a_file_with_every_point_not_marked_complete_leaves_it_alone(tmp_path):
    """A session that saved its last point and stopped before marking the file complete: its
    --resume has nothing to measure either; said so, nothing opened, the file unchanged."""
    out = tmp_path / "all.frf.h5"
    freq = np.linspace(0, 1600, 801)
    w = store.FrfWriter(out, freq, units="V/V", settings={"n_points": 2})
    for label in ("1", "2"):
        w.add_point(label, np.ones(freq.size, complex), np.ones(freq.size))
    assert read_frf_h5(out).meta["complete"] is False
    before = out.read_bytes()
    r = run(["acquire", "--analyser", _free_port_resource(), "--points", "2", "--keep-setup",
             "--resume", "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert (f"{out}: every point measured (the file is not marked complete: its session "
            "stopped after saving the last point): 2 points (1, 2), 801 lines 0-1600 Hz, V/V; "
            "nothing to measure") in r.stderr
    assert out.read_bytes() == before


def test_resume_with_keep_setup_of_a_configured_file_is_refused(tmp_path, hp):
    """--keep-setup cannot read the windows back: resuming a file whose windows are recorded
    would record them as unknown for every point; refused, naming the options to use."""
    out = tmp_path / "k.h5"
    assert acquire(hp, out, "--no-prompt", points=1).exit_code == 0
    r = CliRunner().invoke(cli, ["acquire", "--analyser", hp.resource, "--keep-setup",
                                 "--no-prompt", "--timeout", "0.5", "--points", "2", "--resume",
                                 "-o", str(out)])
    assert r.exit_code == 2, r.output
    assert "exp window: recorded 0.1 s, requested unknown (--keep-setup does not read it " \
           "back)" in r.output
    assert "(--pretrigger 0.005 --force-window 0.01 --exp-window 0.1, without --keep-setup)" \
        in r.output
    assert read_frf_h5(out).n_points == 1


def test_resuming_a_file_that_does_not_record_its_window_says_so_and_why(tmp_path, hp):
    """A file written by another program (here as scripts/example_frf.py writes one: span and
    lines only) said 'exp window: recorded not recorded (--keep-setup)', blaming an option its
    maker never had. It now says the file does not record its window, why that matters and
    that only another file (-o) takes the new points; nothing is sent to the analyser."""
    out = tmp_path / "synthetic.frf.h5"
    freq = np.arange(801) * 2.0
    store.write_frf_h5(out, freq, np.ones((2, freq.size), complex), units="V/V",
                       instrument={"model": "synthetic (scripts/example_frf.py)"},
                       settings={"span_hz": 1600.0, "lines": 800})
    r = acquire(hp, out, "--no-prompt", "--resume")
    assert r.exit_code == 2, r.output
    text = " ".join(r.output.split())
    assert "recorded not recorded" not in text and "(--keep-setup)" not in text
    assert (f"laminid: error: {out}: cannot resume, the file does not record its start, "
            "pretrigger, force window and exp window (it was not measured by laminid acquire, "
            "which records its set-up; its instrument: synthetic (scripts/example_frf.py)), so "
            "this run's --start 0 Hz, --pretrigger 0.005 s, --force-window 0.01 s, "
            "--exp-window 0.1 s cannot be checked against what its points measured; an "
            "exponential window's 1/tau is in every pole's damping, so points of unknown "
            "windows would not compare; write the new points to another file (-o)") in text
    assert hp.log == []
    assert read_frf_h5(out).n_points == 2


def test_resuming_a_keep_setup_file_with_a_set_up_says_keep_setup_resumes_it(tmp_path, hp):
    """A file measured with --keep-setup (its windows NaN) resumed with a set-up: the message
    says the windows were the analyser's own, not read back, and that --keep-setup resumes
    it; which it does."""
    out = tmp_path / "k.h5"
    keep = ["--keep-setup", "--no-prompt", "--timeout", "0.5"]
    assert acquire(hp, tmp_path / "setup.h5", "--no-prompt", points=1).exit_code == 0
    assert run(["acquire", "--analyser", hp.resource, *keep, "--points", "1",
                "-o", str(out)]).exit_code == 0
    r = acquire(hp, out, "--no-prompt", "--resume")
    assert r.exit_code == 2, r.output
    text = " ".join(r.output.split())
    assert (f"laminid: error: {out}: cannot resume, the file does not record its pretrigger, "
            "force window and exp window (it was measured with --keep-setup, the analyser's "
            "own set-up, whose windows and pre-trigger laminid cannot read back), so this "
            "run's --pretrigger 0.005 s, --force-window 0.01 s, --exp-window 0.1 s cannot be "
            "checked against what its points measured;") in text
    assert text.endswith("resume it with --keep-setup and the analyser's set-up unchanged, or "
                         "write the new points to another file (-o)")
    r = run(["acquire", "--analyser", hp.resource, *keep, "--points", "2", "--resume",
             "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert read_frf_h5(out).n_points == 2


def test_frf_writer_resume_keeps_settings_the_run_does_not_state(tmp_path):
    from laminid_cli.frf.store import FrfWriter

    freq = np.arange(10.0)
    path = tmp_path / "x.h5"
    with FrfWriter(path, freq, settings={"exp_window_s": 0.2, "averages": 3}) as w:
        w.add_point("1", np.ones(10))
    with FrfWriter(path, freq, settings={"averages": 5}, resume=True) as w:
        w.add_point("2", np.ones(10))
    assert read_frf_h5(path).meta["settings"] == {"exp_window_s": 0.2, "averages": 5}


def test_keep_setup_records_the_analysers_own_settings(tmp_path, hp):
    out = tmp_path / "k.h5"
    assert acquire(hp, out, "--no-prompt", points=1).exit_code == 0  # leaves 1600 Hz/800 lines
    out2 = tmp_path / "k2.h5"
    r = run(["acquire", "--analyser", hp.resource, "--keep-setup", "--no-prompt", "--timeout",
             "0.5", "--span", "400", "-o", str(out2)])
    assert r.exit_code == 0, r.output
    settings = read_frf_h5(out2).meta["settings"]
    assert settings["span_hz"] == 1600.0 and settings["lines"] == 800
    assert not settings["configured"]


# ------------------------------------------------------------------------------ faults
@pytest.mark.parametrize("emu_cls, fault, message", [
    (HP35670AEmulator, Fault("CALC1:DATA?", "silent", 2),
     "did not answer within 0.5 s (waiting for the answer to 'CALC1:DATA?'"),
    (HP35670AEmulator, Fault("CALC1:DATA?", "truncate", 2), "truncated binary transfer"),
    (HP35670AEmulator, Fault("CALC2:DATA?", "drop", 2), "analyser TCPIP::127.0.0.1::"),
    (SR785Emulator, Fault("DSPB?", "truncate", 3), "expected 6408 bytes"),
    (SR785Emulator, Fault("DSPS?", "silent", 2), "did not answer within 0.5 s"),
])
def test_faults_exit_1_and_keep_every_finished_point(tmp_path, emu_cls, fault, message):
    out = tmp_path / "f.h5"
    with emu_cls(faults=[fault]) as emu:
        r = acquire(emu, out, "--no-prompt")
    assert r.exit_code == 1, r.output
    assert message in r.output
    n_done = fault.measurement - 1
    assert f"{n_done} point(s) saved in" in r.output and "--resume" in r.output
    s = read_frf_h5(out)
    assert s.n_points == n_done and s.meta["complete"] is False
    assert s.labels == tuple(str(k + 1) for k in range(n_done))
    # and --resume against a healthy analyser finishes the file
    with emu_cls() as emu:
        r = acquire(emu, out, "--no-prompt", "--resume")
    assert r.exit_code == 0, r.output
    assert read_frf_h5(out).labels == ("1", "2", "3")


@pytest.mark.parametrize("emu_cls, command, sent", [
    (HP35670AEmulator, "*ESR?", "*ESR?"),
    (HP35670AEmulator, "STAT:QUES:VOLT:EVEN?", "STAT:QUES:VOLT:EVEN?"),
    (HP35670AEmulator, "SYST:ERR?", "SYST:ERR?"),
    (SR785Emulator, "DSPS? 1", "DSPS? 1"),
    (SR785Emulator, "NAVG?", "NAVG? 0"),
    (SR785Emulator, "INPS?", "INPS?"),
    (SR785Emulator, "DSPN?", "DSPN? 0"),
    (SR785Emulator, "ERRS?", "ERRS?"),
])
def test_a_garbled_answer_stops_in_one_line_and_keeps_the_finished_points(
        tmp_path, emu_cls, command, sent):
    """A status or count query answered with no number (line noise, another talker) raised
    a ValueError traceback (the 35670A's *ESR?, the SR785's NAVG?, DSPN?...) or, for the
    SR785's DSPS? 1, was taken for "not done yet" and polled for ever; it is an analyser
    fault: one line naming the resource, the command and the answer, exit 1, point 1 kept."""
    out = tmp_path / "g.h5"
    with emu_cls(faults=[Fault(command, "garbage", 2)]) as emu:
        r = acquire(emu, out, "--no-prompt")
        resource = emu.resource
    assert r.exit_code == 1, r.output
    line = r.output.strip().splitlines()[-1]
    assert line.startswith("laminid: error: point 2: analyser TCPIP0::127.0.0.1::"
                           f"{resource.split('::')[2]}::SOCKET: the ")
    assert f"answered {sent} with '\\x15#?garbage'" in line
    assert "point 2 not saved; 1 point(s) saved in" in line and "--resume" in line
    s = read_frf_h5(out)
    assert s.labels == ("1",) and s.meta["complete"] is False


def test_a_garbled_trace_block_names_the_analyser_and_the_query(tmp_path):
    """A 35670A trace answered with no IEEE 488.2 block said only "expected an IEEE 488.2
    definite-length block ..., got b'\\x15#'": not which analyser nor which query."""
    out = tmp_path / "b.h5"
    with HP35670AEmulator(faults=[Fault("CALC1:DATA?", "garbage", 2)]) as emu:
        r = acquire(emu, out, "--no-prompt")
        port = emu.resource.split("::")[2]
    assert r.exit_code == 1, r.output
    assert (f"laminid: error: point 2: analyser TCPIP0::127.0.0.1::{port}::SOCKET: answer to "
            "'CALC1:DATA?': expected an IEEE 488.2 definite-length block ('#<n><length>'), "
            "got b'\\x15#'; point 2 not saved; 1 point(s) saved in") in r.output
    assert read_frf_h5(out).labels == ("1",)


def test_hp_error_queue_after_configuring_exits_1(tmp_path):
    out = tmp_path / "e.h5"
    with HP35670AEmulator(faults=[Fault("WIND2:EXP", "error", 0)]) as emu:
        r = acquire(emu, out, "--no-prompt")
    assert r.exit_code == 1
    assert ("35670A rejected 1 command(s) while configuring: 'WIND2:EXP 0.1' -> "
            '-222,"Data out of range"') in r.output
    assert not out.exists()  # nothing was measured


def test_emulator_rejects_the_old_35670a_trigger_commands_and_the_message_names_them(hp):
    """The emulator follows the public evidence: INP1 is no trigger source (-224) and there is
    no TRIGger:DELay node (-113); each rejected command is named with the analyser's text."""
    from laminid_cli.errors import InstrumentError
    from laminid_cli.instrument.registry import open_analyser

    with open_analyser(hp.resource, timeout=0.5) as dsa:
        with pytest.raises(InstrumentError) as info:
            dsa.send_checked(["TRIG:SOUR INP1", "TRIG:SOUR INT1", "TRIG:DEL1 -0.005 S",
                              "TRIG:STAR1 -0.005"])
    assert str(info.value) == (
        "35670A rejected 2 command(s) while configuring: 'TRIG:SOUR INP1' -> "
        '-224,"Illegal parameter value" | \'TRIG:DEL1 -0.005 S\' -> '
        '-113,"Undefined header; TRIG:DEL1"')


@pytest.mark.parametrize("model", ["hp35670a", "Agilent35670A", "KEYSIGHT35670A", "35670a"])
def test_model_names_a_lab_types_select_the_35670a(tmp_path, hp, model):
    r = acquire(hp, tmp_path / "m.h5", "--model", model, "--no-prompt", points=1)
    assert r.exit_code == 0, r.output
    assert read_frf_h5(tmp_path / "m.h5").meta["instrument"]["model"] == "35670A"


def test_model_sr785_is_case_insensitive(tmp_path, sr):
    r = acquire(sr, tmp_path / "m.h5", "--model", "sr785", "--no-prompt", points=1)
    assert r.exit_code == 0, r.output
    assert read_frf_h5(tmp_path / "m.h5").meta["instrument"]["model"] == "SR785"


# ------------------------------------ issue 15: an error flagged during a data transfer
@pytest.mark.parametrize("emu_cls, command, trace", [
    (HP35670AEmulator, "CALC1:DATA?", "FRF"),
    (HP35670AEmulator, "CALC2:DATA?", "coherence"),
    (SR785Emulator, "DSPB? 0", "FRF"),
    (SR785Emulator, "DSPB? 1", "coherence"),
])
def test_error_flagged_during_a_transfer_refuses_the_point_and_resume_completes(
        tmp_path, emu_cls, command, trace):
    out = tmp_path / "t.h5"
    with emu_cls(faults=[Fault(command, "flag", 2)]) as emu:   # flagged on every read
        r = acquire(emu, out, "--no-prompt")
    assert r.exit_code == 1, r.output
    model = emu_cls.IDN.split(",")[1]
    assert f"point 2: {model} flagged an error during the {trace} transfer, twice" in r.output
    text = '-230,"Data corrupt or stale"' if model == "35670A" else "*ESR? = 16 (bit 4"
    assert text in r.output
    assert "point 2 not saved; 1 point(s) saved in" in r.output and "--resume" in r.output
    s = read_frf_h5(out)                      # valid file with the earlier point only
    assert s.labels == ("1",) and s.meta["complete"] is False
    with emu_cls() as emu:
        r = acquire(emu, out, "--no-prompt", "--resume")
    assert r.exit_code == 0, r.output
    assert read_frf_h5(out).labels == ("1", "2", "3")


@pytest.mark.parametrize("emu_cls, command", [(HP35670AEmulator, "CALC2:DATA?"),
                                              (SR785Emulator, "DSPB? 0")])
def test_error_flagged_once_is_cured_by_one_more_read(tmp_path, emu_cls, command):
    out = tmp_path / "once.h5"
    with emu_cls(faults=[Fault(command, "flag", 2, times=1)]) as emu:
        r = acquire(emu, out, "--no-prompt")
        reads = sum(1 for c in emu.log if c == command)
    assert r.exit_code == 0, r.output
    assert reads == 4                         # 3 points + the one re-read of point 2
    assert read_frf_h5(out).labels == ("1", "2", "3")


def _interrupt_on_second_point(monkeypatch):
    """A Ctrl-C while point 2 is assessed (after it is saved); the real function returned."""
    import laminid_cli.instrument.session as session

    real = session.assess_point
    calls = []

    def interrupt_on_second(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(session, "assess_point", interrupt_on_second)
    return real


def test_ctrl_c_keeps_the_file_and_prints_the_resume_command(tmp_path, hp, monkeypatch):
    _interrupt_on_second_point(monkeypatch)
    out = tmp_path / "c.h5"
    r = acquire(hp, out, "--no-prompt")
    assert r.exit_code == 130
    assert "interrupted; 2 point(s) saved in" in r.output  # point 2 was saved before the ^C
    assert "--resume" in r.output
    assert read_frf_h5(out).n_points == 2
    # the measurement was stopped on the analyser (its server thread may lag a little)
    import time

    deadline = time.monotonic() + 2.0
    while hp.log[-1] != "ABOR" and time.monotonic() < deadline:
        time.sleep(0.01)
    assert hp.log[-1] == "ABOR"


@pytest.mark.parametrize("emu_cls", [HP35670AEmulator, SR785Emulator])
def test_ctrl_c_after_the_last_hit_saves_the_point_being_read(tmp_path, emu_cls, monkeypatch):
    """Ctrl-C while point 2's FRF is read (every hit taken: an operator stopping just after
    the last hit) threw the point away ('1 point(s) saved'); the stop now waits until the
    point is read and saved, then ends the session as before (exit 130, --resume)."""
    import os
    import signal

    from laminid_cli.instrument import hp35670a, sr785

    driver = hp35670a.HP35670A if emu_cls is HP35670AEmulator else sr785.SR785
    real = driver.read_frf
    calls = []

    def ctrl_c_during_the_second_transfer(self):
        calls.append(1)
        if len(calls) == 2:
            os.kill(os.getpid(), signal.SIGINT)   # delivered at once, in the main thread
        return real(self)

    monkeypatch.setattr(driver, "read_frf", ctrl_c_during_the_second_transfer)
    out = tmp_path / "k.h5"
    with emu_cls() as emu:
        r = acquire(emu, out, "--no-prompt")
    assert r.exit_code == 130, r.output
    assert "point 2: 3 hits, coherence at resonances" in r.output
    assert "interrupted; 2 point(s) saved in" in r.output and "--resume" in r.output
    s = read_frf_h5(out)
    assert s.labels == ("1", "2") and s.meta["complete"] is False
    assert np.all(np.isfinite(s.frf[1])) and np.abs(s.frf[1]).max() > 0


def test_a_fault_while_a_stop_waits_for_the_point_is_said_with_the_stop(tmp_path, monkeypatch):
    """Ctrl-C while point 2 is read waits for it; if the transfer then fails (no answer
    within --timeout), the stop said only 'interrupted; 1 point(s) saved', not why point 2,
    whose hits were all taken, is not in the file."""
    import os
    import signal

    from laminid_cli.instrument import hp35670a

    real = hp35670a.HP35670A.read_frf
    calls = []

    def ctrl_c_during_the_second_transfer(self):
        calls.append(1)
        if len(calls) == 2:
            os.kill(os.getpid(), signal.SIGINT)
        return real(self)

    monkeypatch.setattr(hp35670a.HP35670A, "read_frf", ctrl_c_during_the_second_transfer)
    out = tmp_path / "s.h5"
    with HP35670AEmulator(faults=[Fault("CALC1:DATA?", "silent", 2)]) as emu:
        r = acquire(emu, out, "--no-prompt")
    assert r.exit_code == 130, r.output
    line = r.output.strip().splitlines()[-1]
    assert line.startswith(f"laminid: stopped: interrupted; 1 point(s) saved in {out}; point 2: "
                           "analyser TCPIP0::127.0.0.1::"), line
    assert ("did not answer within 0.5 s (waiting for the answer to 'CALC1:DATA?', binary "
            "read)); point 2 not saved; continue with: ") in line
    assert read_frf_h5(out).labels == ("1",)


@pytest.mark.parametrize("emu_cls, said", [
    (HP35670AEmulator, r"point 2 stopped before its 3 hits were taken, not saved"),
    (SR785Emulator, r"point 2 stopped at [12] of 3 hits, not saved"),   # 1 (a hit may land)
])
def test_ctrl_c_during_the_hits_says_which_points_hits_are_discarded(tmp_path, emu_cls, said,
                                                                      monkeypatch):
    """Ctrl-C while point 2's hits were taken said only '1 point(s) saved': nothing told the
    operator that point 2's hits so far were gone; the stop message says so."""
    import re

    from laminid_cli.instrument import hp35670a, sr785

    driver = hp35670a.HP35670A if emu_cls is HP35670AEmulator else sr785.SR785
    real = driver.is_done
    points_done, seen_hit = [], []

    def ctrl_c_once_point_2_has_a_hit(self):
        done = real(self)
        if done:
            points_done.append(1)
        elif len(points_done) == 1:                       # waiting for point 2's hits
            if seen_hit:                                  # the poll after: progress said it
                raise KeyboardInterrupt
            if self.hits_done() != 0:                     # a hit (the 35670A: -1, unknown)
                seen_hit.append(1)
        return done

    monkeypatch.setattr(driver, "is_done", ctrl_c_once_point_2_has_a_hit)
    out = tmp_path / "h.h5"
    with emu_cls(hit_interval_s=0.2) as emu:
        r = acquire(emu, out, "--no-prompt")
    assert r.exit_code == 130, r.output
    assert re.search(f"interrupted; 1 point\\(s\\) saved in {re.escape(str(out))}; {said}; "
                     "continue with: ", r.output), r.output
    assert read_frf_h5(out).labels == ("1",)


def test_json_summary_also_when_the_session_is_interrupted(tmp_path, hp, monkeypatch):
    """--json with Ctrl-C during point 2 (saved, then interrupted): stdout still holds the
    summary (it held nothing, exit 130): point 1 measured and saved in this run, 2 in the
    file, the resume command and why it stopped; likewise a closed stdin at the prompt of
    point 2 (exit 2)."""
    import json

    import laminid_cli.instrument.session as session

    real = _interrupt_on_second_point(monkeypatch)
    out = tmp_path / "c.h5"
    r = acquire(hp, out, "--no-prompt", "--json")
    assert r.exit_code == 130
    d = json.loads(r.stdout)
    assert d["complete"] is False and d["points_requested"] == 3
    assert d["points_saved"] == 2 == read_frf_h5(out).n_points
    assert d["measured"] == ["1"] and [p["label"] for p in d["points"]] == ["1"]
    assert d["stopped"].startswith("interrupted; 2 point(s) saved in")
    assert d["resume"].endswith("--resume") and "--json" in d["resume"]
    assert "laminid: stopped: interrupted" in r.stderr
    monkeypatch.setattr(session, "assess_point", real)
    out2 = tmp_path / "s.h5"
    r = acquire(hp, out2, "--json", input="\n")       # Enter for point 1, then end of input
    assert r.exit_code == 2
    d = json.loads(r.stdout)
    assert d["points_saved"] == 1 and d["measured"] == ["1"] and d["complete"] is False
    assert "standard input is closed" in d["stopped"] and "--resume" in d["resume"]


def test_raw_socket_sends_each_command_at_once(hp):
    """TCPIP SOCKET through pyvisa-py: Nagle's algorithm is off (TCP_NODELAY, NI-VISA's
    default), so a query after a command with no answer is not held back ~40 ms waiting for
    the analyser's delayed ACK."""
    import socket

    import pyvisa

    from laminid_cli.instrument.transport import open_transport

    t = open_transport(hp.resource, timeout=0.5)
    try:
        assert t._inst.get_visa_attribute(pyvisa.constants.VI_ATTR_TCPIP_NODELAY)
        sock = t._rm.visalib.sessions[t._inst.session].interface
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) == 1
        t.write("FORM:DATA REAL,64")
        assert t.query("*ESR?") == "+0"
    finally:
        t.close()


# --------------------------------------------------------------------------- bad input
def test_unknown_resource_string_exits_2(tmp_path):
    r = run(["acquire", "--analyser", "NOT-A-RESOURCE", "-o", str(tmp_path / "x.h5")])
    assert r.exit_code == 2
    assert "'NOT-A-RESOURCE' is not a VISA resource string" in r.output


def test_nothing_listening_at_the_address_exits_2(tmp_path):
    import socket

    with socket.socket() as s:  # a free local port with nobody listening
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    r = run(["acquire", "--analyser", f"TCPIP::127.0.0.1::{port}::SOCKET", "--timeout", "0.5",
             "-o", str(tmp_path / "x.h5")])
    assert r.exit_code == 2
    assert f"no analyser at TCPIP0::127.0.0.1::{port}::SOCKET (connection refused)" in r.output


def test_end_of_input_at_the_prompt_says_to_run_unattended(tmp_path, hp):
    """Standard input closed at a prompt (a script without --no-prompt): exit 2 saying to use
    --no-prompt; the finished point stays in the file, with the resume command. With no point
    finished there is no file, so no resume command either."""
    out = tmp_path / "eof.h5"
    r = acquire(hp, out, input="\n")  # point 1 measured, then no answer for point 2
    assert r.exit_code == 2, r.output
    assert ("laminid: error: no answer to the prompt: standard input is closed (a script or a "
            "pipe?); run unattended with --no-prompt; 1 point(s) saved in") in r.output
    assert "continue with: laminid acquire" in r.output and "--resume" in r.output
    assert read_frf_h5(out).n_points == 1
    out2 = tmp_path / "none.h5"
    r = acquire(hp, out2, input="")
    assert r.exit_code == 2 and "no point finished" in r.output
    assert "--resume" not in r.output and not out2.exists()


def test_unsupported_idn_exits_2(tmp_path):
    with HP35670AEmulator(idn="KEITHLEY INSTRUMENTS INC.,MODEL 2000,1,A02") as emu:
        r = acquire(emu, tmp_path / "x.h5")
    assert r.exit_code == 2
    assert "answers *IDN? with 'KEITHLEY INSTRUMENTS INC.,MODEL 2000,1,A02', which no laminid " \
           "driver supports (supported: 35670A, SR785)" in r.output


@pytest.mark.parametrize("emu_cls, args, message", [
    (HP35670AEmulator, ["--span", "102400", "--force-window", "0.001", "--pretrigger", "0",
                        "--exp-window", "0.005"],
     "35670A does not offer --span 102400 Hz; spans (Hz): 51200, 25600"),
    (SR785Emulator, ["--averages", "1"],
     "SR785 averages at least 2 records (FAVN 2-32767; got --averages 1)"),
])
def test_settings_the_identified_analyser_does_not_offer_exit_2(tmp_path, emu_cls, args, message):
    """--model auto: the model's own ranges are checked after *IDN?, before any set-up."""
    with emu_cls() as emu:
        r = acquire(emu, tmp_path / "x.h5", *args)
    assert r.exit_code == 2
    assert message in r.output
    assert emu.log == ["*IDN?"]  # nothing sent but the identification


@pytest.mark.parametrize("args, message", [
    (["--lines", "0"],
     "Invalid value for '--lines': 0 lines: the analysers offer 100, 200, 400, 800."),
    (["--lines", "-5"],
     "Invalid value for '--lines': -5 lines: the analysers offer 100, 200, 400, 800."),
    (["--lines", "1600"],
     "Invalid value for '--lines': 1600 lines: the analysers offer 100, 200, 400, 800."),
    (["--averages", "10000"],
     "Invalid value for '--averages': 10000 is not in the range 1<=x<=9999."),
    (["--span", "1000"],
     "Invalid value for '--span': 1000 Hz is not a span the analysers offer: 102400 Hz / "
     "2^k: 102400, 51200, 25600, 12800, 6400, 3200, 1600, 800, 400, 200, 100, 50, ... "
     "0.195312 Hz."),
    (["--pretrigger", "5"], "laminid: error: --pretrigger 5 s must be within the time record "
                            "(0-0.5 s = --lines 800 / --span 1600 Hz)"),
    (["--exp-window", "10"], "laminid: error: --exp-window 10 s must be within the time "
                             "record (0-0.5 s = --lines 800 / --span 1600 Hz)"),
    (["--force-window", "0.6"], "laminid: error: --force-window 0.6 s must be within the time "
                                "record (0-0.5 s = --lines 800 / --span 1600 Hz)"),
    (["--start", "200000"], "laminid: error: --start 200000 Hz + --span 1600 Hz is above every "
                            "supported analyser's range (35670A 0-51200 Hz, SR785 0-102400 Hz)"),
    (["--model", "35670a", "--start", "51200"],
     "laminid: error: --start 51200 Hz + --span 1600 Hz is outside 35670A's range 0-51200 Hz"),
    (["--model", "sr785", "--averages", "1"],
     "laminid: error: SR785 averages at least 2 records (FAVN 2-32767; got --averages 1)"),
    (["--model", "HP3562A"], "laminid: error: --model 'HP3562A': unknown analyser model; "
                             "choose auto or one of: hp35670a"),
    (["--model", "HP3562A", "--keep-setup"], "--model 'HP3562A': unknown analyser model"),
], ids=["lines-0", "lines-negative", "lines-1600", "averages-10000", "span-1000",
        "pretrigger-over-record", "exp-window-over-record", "force-window-over-record",
        "start-over-every-range", "start-over-35670a-range", "sr785-one-average",
        "unknown-model", "unknown-model-keep-setup"])
def test_bad_acquire_options_are_refused_before_the_analyser_is_opened(tmp_path, hp, args,
                                                                       message):
    """`acquire --lines 0` (or -5) connected to the analyser and only then said '35670A does
    not offer 0 lines'; a bad value of any numeric option, or an unknown --model, is now
    refused before the analyser is opened (not even *IDN? sent), exit 2, naming the option
    and the values allowed."""
    out = tmp_path / "x.h5"
    r = acquire(hp, out, "--no-prompt", *args)
    assert r.exit_code == 2, r.output
    assert message in " ".join(r.output.split()), r.output
    assert hp.log == []                         # the analyser was never asked anything
    assert not out.exists()


def test_existing_output_is_not_overwritten(tmp_path, hp):
    out = tmp_path / "exists.h5"
    out.write_bytes(b"precious")
    r = acquire(hp, out, "--no-prompt")
    assert r.exit_code == 2 and "file exists" in r.output
    assert out.read_bytes() == b"precious"
    assert hp.log == []  # checked before talking to the analyser


def test_an_unfinished_acquisition_named_again_without_resume_points_at_resume(tmp_path, hp):
    """The same acquire command run again on a session that was interrupted or quit (the
    file marked not complete) said "file exists; use --force to overwrite it or choose
    another name with -o": the option that throws the measured points away. It names the
    saved points and --resume; the file is left as it was, the analyser not asked."""
    out = tmp_path / "p.h5"
    r = acquire(hp, out, input="\nq\n")                     # point 1 saved, then quit
    assert r.exit_code == 3, r.output
    before = out.read_bytes()
    n_log = len(hp.log)
    r = acquire(hp, out, "--no-prompt")
    assert r.exit_code == 2, r.output
    assert r.output.splitlines()[-1] == (
        f"laminid: error: {out}: an unfinished acquisition (saved: point 1); add --resume to "
        "measure the rest, or choose another name with -o (--force would start it again and "
        "lose the saved points)")
    assert out.read_bytes() == before and len(hp.log) == n_log
    r = acquire(hp, out, "--no-prompt", "--resume")            # what it says works
    assert r.exit_code == 0, r.output
    assert read_frf_h5(out).labels == ("1", "2", "3")


# ------------------------------------------------------------------ acquire -> fit-frf
#: the issue's acceptance tolerance on the natural frequencies
FREQ_TOL = 5e-4


def _relative_errors(found):
    truth = np.array([f for f, _ in PLATE_MODES])
    found = np.asarray(found, dtype=float)
    return np.array([np.min(np.abs(found - f)) / f for f in truth])


def test_acquire_then_rfp_estimator_gives_back_the_emulators_modes(tmp_path, sr):
    """The acquired file carries the plate's modes: the project's RFP estimator finds them.

    Measured on the SR785 emulator (float32 transfer, the coarser of the two formats): max
    error about 0.012 % (mode 1, 212.4 Hz, 1.6 % apparent damping with the exponential
    window), all modes under 0.05 %.
    """
    rfp = pytest.importorskip("laminid_cli.frf.rfp")
    out = tmp_path / "plate.frf.h5"
    assert acquire(sr, out, "--no-prompt", points=4).exit_code == 0
    s = read_frf_h5(out)
    fit = rfp.find_modes(s.freq, s.frf)
    err = _relative_errors(fit.freq_hz)
    assert np.all(err < FREQ_TOL), (fit.freq_hz, err)


@pytest.mark.parametrize("emu_cls", [HP35670AEmulator, SR785Emulator])
def test_acquire_then_fit_frf_gives_back_the_emulators_modes(tmp_path, emu_cls):
    """laminid acquire -> laminid fit-frf, both analysers with the evidenced command sets:
    the emulator's modal frequencies within 0.05 %."""
    import json

    out = tmp_path / "plate.frf.h5"
    with emu_cls() as emu:
        r = acquire(emu, out, "--no-prompt", "--units", "Pa/N", points=4)
    assert r.exit_code == 0, r.output
    r = run(["fit-frf", str(out), "--json"])
    assert r.exit_code == 0, r.output
    result = json.loads(r.output)
    err = _relative_errors([m["freq_hz"] for m in result["modes"]])
    assert np.all(err < FREQ_TOL), (result, err)


def test_a_closed_or_unreadable_stdin_is_no_operator_input(monkeypatch, tmp_path):
    """Standard input closed at the OS level (sys.stdin None: `laminid acquire ... <&-`) or not
    text is the same as its end: NoOperatorInput, not an AttributeError traceback; the repeat
    prompt asks again on an answer it does not know."""
    import io
    import sys

    from laminid_cli.commands.acquire import _ClickUI
    from laminid_cli.instrument.session import NoOperatorInput

    ui = _ClickUI(tmp_path / "x.h5", tty=False)
    monkeypatch.setattr(sys, "stdin", None)
    with pytest.raises(NoOperatorInput, match="run unattended with --no-prompt"):
        ui.ready("1", 1, 3)

    class Bad(io.StringIO):
        def readline(self, *a):
            raise UnicodeDecodeError("utf-8", b"\xff", 0, 1, "invalid start byte")

    monkeypatch.setattr(sys, "stdin", Bad())
    with pytest.raises(NoOperatorInput):
        ui.ready("1", 1, 3)
    monkeypatch.setattr(sys, "stdin", io.StringIO("q\nmaybe\nn\n"))
    quality = type("Q", (), {"label": "2"})()
    assert ui.repeat(quality) is False            # 'q' and 'maybe' asked again, then 'n'


def test_output_through_a_symbolic_link_keeps_the_link(tmp_path, hp):
    """-o naming a symbolic link: the measured file is its target; the link stays a link."""
    target = tmp_path / "real" / "target.h5"
    target.parent.mkdir()
    link = tmp_path / "link.h5"
    link.symlink_to(target)
    r = acquire(hp, link, "--no-prompt")
    assert r.exit_code == 0, r.output
    assert link.is_symlink() and read_frf_h5(target).n_points == read_frf_h5(link).n_points > 0


def test_an_exponential_window_that_would_zero_the_response_is_refused(tmp_path, hp):
    """--exp-window 1e-9 s on a 0.5 s record (800 lines / 1600 Hz) was accepted and zeroed
    the response (fit-frf then found no peak); under a thousandth of the record it is refused
    before any point is measured, naming the record."""
    out = tmp_path / "w.h5"
    r = acquire(hp, out, "--no-prompt", "--exp-window", "1e-9")
    assert r.exit_code == 2, r.output
    assert "--exp-window 1e-09 s is under a thousandth of the time record (0.5 s" in r.stderr
    assert not out.exists()
    assert acquire(hp, out, "--no-prompt", "--exp-window", "0.0005").exit_code == 0


@pytest.mark.parametrize("model", ["35670a", "sr785"])
def test_the_emulator_script_serves_an_acquire_and_stops_on_sigint(tmp_path, model):
    """scripts/analyser_emulator.py (README: trying acquire without an analyser) prints the
    address and the commands to try; acquire from it gives the emulated plate's modes, and
    SIGINT stops it at once (also when started in the background, SIGINT ignored)."""
    import json
    import re
    import signal
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "scripts/analyser_emulator.py", "--model", model,
                             "--hit-interval", "0.01"], stdout=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        first = proc.stdout.readline()
        m = re.match(rf"emulated {model.upper()} at (TCPIP::127\.0\.0\.1::\d+::SOCKET) ", first)
        assert m, first
        assert f"try:  laminid acquire --analyser {m.group(1)} --points 3" in proc.stdout.readline()
        out = tmp_path / "try.frf.h5"
        r = run(["acquire", "--analyser", m.group(1), "--points", "1", "--no-prompt",
                 "--averages", "2", "-o", str(out)])
        assert r.exit_code == 0, r.output
        r = run(["fit-frf", str(out), "--json"])
        assert r.exit_code == 0, r.output
        found = [x["freq_hz"] for x in json.loads(r.stdout)["modes"]]
        for f, _ in PLATE_MODES:
            assert min(abs(np.array(found) - f)) / f < 2e-3, (f, found)
    finally:
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=5) == 0


@pytest.mark.parametrize("model", ["35670a", "sr785"])
def test_the_emulator_scripts_noise_and_overloads_show_as_acquire_reports_them(tmp_path, model):
    """scripts/analyser_emulator.py --noise 0.2 --overload 2 --overload 3:2 (a lab trying
    what a bad point looks like before a real test): point 2's hammer input and point 3's
    response go over range on the emulated analyser's own status word, and the noise takes
    the coherence at the weakest resonance below acquire's 0.9 (about 0.8 with 5 hits)."""
    import json
    import re
    import signal
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "scripts/analyser_emulator.py", "--model", model,
                             "--hit-interval", "0.01", "--noise", "0.2", "--overload", "2",
                             "--overload", "3:2"], stdout=subprocess.PIPE, text=True)
    try:
        lines = [proc.stdout.readline() for _ in range(6)]
        resource = re.match(r"emulated \S+ at (\S+) ", lines[0]).group(1)
        # the points are the emulator's measurements since it started: said (it printed
        # "point 2" alone, and a second acquire's point 2 measured cleanly)
        assert lines[3:6] == ["point 2: hammer input over range\n",
                              "point 3: response input over range\n",
                              "(the emulator's measurements since it started: the points of "
                              "the first acquire only; restart the emulator to see them "
                              "again)\n"], lines
        r = run(["acquire", "--analyser", resource, "--points", "3", "--no-prompt",
                 "--averages", "5", "--json", "-o", str(tmp_path / "bad.frf.h5")])
        assert r.exit_code == 0, r.output
        points = json.loads(r.stdout)["points"]
        assert [p["overloaded_channels"] for p in points] == [[], [1], [2]]
        assert [p["ok"] for p in points] == [False, False, False]
        assert all(0.6 < p["coherence_resonance"] < 0.9 for p in points), points
        assert "overloads 1 (ch1 hammer) - POOR coherence, OVERLOAD" in r.stderr, r.stderr
        r = run(["acquire", "--analyser", resource, "--points", "3", "--no-prompt",
                 "--averages", "5", "--json", "-o", str(tmp_path / "again.frf.h5")])
        assert r.exit_code == 0, r.output
        assert [p["overloaded_channels"] for p in json.loads(r.stdout)["points"]] == [[]] * 3
        # the noise hides the plate's 212.4 Hz mode from fit-frf's automatic bands: named in a
        # note with the band that finds it (before: six modes from 318.9 Hz, no word)
        r = run(["fit-frf", str(tmp_path / "bad.frf.h5"), "--json"])
        assert r.exit_code == 0, r.output
        doc = json.loads(r.stdout)
        assert all(abs(m["freq_hz"] - 212.4) > 4 for m in doc["modes"]), doc["modes"]
        missed = [n for n in doc["notes"] if n.startswith("the summed |H| peaks at 212.0 Hz (2")]
        assert len(missed) == 1, doc["notes"]
        assert "(--band 170:254)" in missed[0]
        r = run(["fit-frf", str(tmp_path / "bad.frf.h5"), "--band", "170:254", "--json"])
        assert r.exit_code == 0, r.output
        assert [round(m["freq_hz"]) for m in json.loads(r.stdout)["modes"]] == [212]
    finally:
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=5) == 0


@pytest.mark.parametrize("args, message", [
    (["--overload", "x"], "--overload 'x': give POINT or POINT:CHANNEL, e.g. 2 or 3:2"),
    (["--overload", "2:3"], "--overload '2:3': the point is 1 or more, the channel 1 (hammer) "
                            "or 2 (response)"),
    (["--overload", "0"], "--overload '0': the point is 1 or more"),
    (["--noise", "-1"], "--noise -1: must be 0 or more"),
    (["--hit-interval", "0"], "--hit-interval 0: must be above 0 s")])
def test_the_emulator_script_refuses_bad_options_in_one_line(args, message):
    import subprocess
    import sys

    p = subprocess.run([sys.executable, "scripts/analyser_emulator.py", *args],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2, p.stderr
    assert message in p.stderr and "Traceback" not in p.stderr, p.stderr


class _OverloadOnPoint2:
    """An emulator whose input status flags ``word`` during measurement 2 (the hammer hit
    too hard, or the response over range)."""

    word = 0

    def begin_measurement(self):
        super().begin_measurement()
        if self.measurement == 2:
            self.overload_word = self.word


@pytest.mark.parametrize("emu_cls, word, channels, names", [
    (HP35670AEmulator, 1, [1], "ch1 hammer"),              # STAT:QUES:VOLT bit 0
    (HP35670AEmulator, 3, [1, 2], "ch1 hammer, ch2 response"),
    (SR785Emulator, 1 << 10, [2], "ch2 response")])        # INPS? bit 10
def test_an_overloaded_point_names_its_channel_and_every_fault(tmp_path, emu_cls, word,
                                                               channels, names):
    """The quality line's 'overloads 2' was a count of channels that a reader took for hits,
    without saying which input (the hammer hit too hard, or the response's range), and a
    point both poorly coherent and overloaded said only 'POOR coherence'. --json gives the
    channels (1 hammer, 2 response)."""
    import json

    emu = type("Emu", (_OverloadOnPoint2, emu_cls), {"word": word})()
    with emu:
        r = acquire(emu, tmp_path / "o.h5", "--no-prompt", "--json", points=2)
        assert r.exit_code == 0, r.output
        assert "point 1: 3 hits" in r.stderr and "overloads 0 - ok\n" in r.stderr
        assert (f"Hz), overloads {len(channels)} ({names}) - OVERLOAD\n") in r.stderr
        d = json.loads(r.stdout)
        assert [(p["overloads"], p["overloaded_channels"], p["ok"]) for p in d["points"]] == [
            (0, [], True), (len(channels), channels, False)]
        r = acquire(emu, tmp_path / "p.h5", "--no-prompt", "--coherence-min", "1.0", points=1)
        assert r.exit_code == 0, r.output     # measurement 3 of the emulator: no overload
        assert "overloads 0 - POOR coherence\n" in r.output
    assert read_frf_h5(tmp_path / "o.h5").meta["points"]["overloads"] == [0, len(channels)]


def test_overloads_an_analyser_cannot_tell_are_null_in_json(tmp_path, hp, monkeypatch):
    """An analyser that cannot report its overloads: '?' in the quality line, null in --json
    (was -1, a count)."""
    import json

    from laminid_cli.instrument.hp35670a import HP35670A

    monkeypatch.setattr(HP35670A, "overloaded_channels", lambda self: None)
    r = acquire(hp, tmp_path / "u.h5", "--no-prompt", "--json", points=1)
    assert r.exit_code == 0, r.output
    assert "overloads ? - ok\n" in r.stderr
    p = json.loads(r.stdout)["points"][0]
    assert p["overloads"] is None and p["overloaded_channels"] is None and p["ok"] is True


def test_the_acquire_file_reads_with_h5py_alone_every_number_with_its_unit(tmp_path, hp):
    """Another tool reads the FRF file as README's acquire section lays it out: named
    datasets, each number with a units attribute (the per-point counts had none), settings
    with the unit in their names, the values --json reported."""
    import json

    import h5py

    out = tmp_path / "plate.frf.h5"
    r = acquire(hp, out, "--no-prompt", "--json", "--units", "Pa/N", points=2)
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    with h5py.File(out, "r") as f:
        assert f.attrs["format"] == "laminid-frf" and f.attrs["schema_version"] == 1
        assert bool(f.attrs["complete"]) is True
        freq, frf, coh = f["frequency"], f["frf"], f["coherence"]
        assert freq.shape == (801,) and frf.shape == coh.shape == (2, 801)
        assert frf.dtype == np.complex128
        assert (freq.attrs["units"], frf.attrs["units"], frf.attrs["quantity"],
                coh.attrs["units"]) == ("Hz", "Pa/N", "response/force", "1")
        assert (freq[0], freq[-1]) == (d["f_start_hz"], d["f_stop_hz"])
        pts = f["points"]
        assert [x.decode() for x in pts["label"][()]] == d["measured"] == ["1", "2"]
        for key in ("n_averages", "overloads"):
            assert pts[key].attrs["units"] == "1"
        assert pts["n_averages"][()].tolist() == [p["n_averages"] for p in d["points"]]
        assert pts["overloads"][()].tolist() == [p["overloads"] for p in d["points"]]
        s = f["settings"].attrs
        assert (s["span_hz"], s["lines"], s["averages"], s["exp_window_s"]) == (1600.0, 800, 3,
                                                                                0.1)
        assert f["instrument"].attrs["model"] == d["instrument"]["model"] == "35670A"


def test_fit_frf_of_noisy_or_overloaded_points_says_so(tmp_path):
    """An acquire run with --no-prompt keeps its poor points (coherence 0.7 at the resonances,
    an overload on point 2): fit-frf then found 2 of the plate's 7 modes, exit 0, without a
    word on the data. It names the points, their coherence against the file's
    --coherence-min, and the overloaded one."""
    import json

    emu = type("Emu", (_OverloadOnPoint2, HP35670AEmulator), {"word": 2})(
        plate=PlateSimulator(noise=0.3))
    out = tmp_path / "noisy.frf.h5"
    with emu:
        r = acquire(emu, out, "--no-prompt", points=3)
    assert r.exit_code == 0 and r.output.count("POOR coherence") == 3
    coh = [float(line.split("coherence at resonances ")[1].split()[0])
           for line in r.output.splitlines() if "coherence at resonances" in line]
    r = run(["fit-frf", str(out), "--json"])
    assert r.exit_code == 0, r.output
    notes = json.loads(r.output)["notes"]
    assert notes[:2] == [
        f"points 1, 2, 3 of 3: coherence at the resonances {min(coh):.2f}-{max(coh):.2f}, "
        "below 0.9, the acquisition's --coherence-min: noisy FRFs, in which the fit misses "
        "modes or takes noise for them; measure them again",
        "point 2: an input went over range while averaging (the hammer hit too hard, or the "
        "response's range too small): the FRF is distorted; measure again"]
    # a good file: no such note
    with HP35670AEmulator() as good:
        assert acquire(good, tmp_path / "good.h5", "--no-prompt", points=2).exit_code == 0
    assert json.loads(run(["fit-frf", str(tmp_path / "good.h5"), "--json"]).output)["notes"] \
        == []


def test_sigterm_stops_the_session_as_ctrl_c_does_with_the_resume_command(tmp_path, hp):
    """`kill PID` (SIGTERM: `timeout`, a job scheduler) of an acquire killed the process at
    once: exit 143 by the signal, nothing on stderr, an empty stdout under --json, no resume
    command, where Ctrl-C says all three. Now it stops the session as Ctrl-C does: the points
    finished before it kept, the message and the --json summary with the resume command,
    exit 143; and --resume completes the file."""
    import signal

    out = tmp_path / "k.frf.h5"
    proc, seen, stdout, stderr = _signalled_at_point_2(hp, out, signal.SIGTERM)
    assert proc.returncode == 143, "".join(seen) + stderr
    assert "laminid: stopped: terminated (SIGTERM);" in stderr
    d = json.loads(stdout)
    n = read_frf_h5(out).n_points
    assert 2 <= n < 40 and d["points_saved"] == n and d["complete"] is False
    assert d["stopped"].startswith(f"terminated (SIGTERM); {n} point(s) saved in")
    assert d["resume"].endswith("--resume")
    r = run(["acquire", "--analyser", hp.resource, *FAST, "--points", str(n + 1),
             "--no-prompt", "-o", str(out), "--resume"])
    assert r.exit_code == 0, r.output
    assert read_frf_h5(out).n_points == n + 1


def test_kill_int_stops_a_session_started_with_sigint_ignored_as_ctrl_c_does(tmp_path, hp):
    """`laminid acquire ... &` from a script: the shell starts it with SIGINT ignored, and
    Python kept it ignored, so `kill -INT PID` did nothing (the session ran on to its last
    point) where SIGTERM stopped it. acquire now takes SIGINT as Ctrl-C there too: the points
    finished before it kept, 'laminid: stopped: interrupted' with the resume command, the
    --json summary, exit 130."""
    import signal

    out = tmp_path / "i.frf.h5"
    proc, seen, stdout, stderr = _signalled_at_point_2(
        hp, out, signal.SIGINT,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert proc.returncode == 130, "".join(seen) + stderr
    assert "laminid: stopped: interrupted;" in stderr
    n = read_frf_h5(out).n_points
    assert 2 <= n < 40
    assert f"interrupted; {n} point(s) saved in {out}" in stderr
    d = json.loads(stdout)
    assert d["points_saved"] == n and d["complete"] is False
    assert d["stopped"].startswith(f"interrupted; {n} point(s) saved in")
    assert d["resume"].endswith("--resume") and "--points 40" in d["resume"]
    assert d["resume"] in stderr


def _signalled_at_point_2(hp, out, sig, preexec_fn=None):
    """A 40-point `acquire --json` session on the emulator in a subprocess, sent ``sig`` once
    point 2 is saved and assessed: (process, its stderr lines up to then, stdout, the rest of
    stderr)."""
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-m", "laminid_cli", "acquire", "--analyser", hp.resource, *FAST,
         "--points", "40", "--no-prompt", "--json", "-o", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=preexec_fn)
    try:
        seen = []
        for line in proc.stderr:               # quality lines go to stderr under --json
            seen.append(line)
            if line.startswith("point 2:"):    # point 2 saved and assessed
                proc.send_signal(sig)
                break
        stdout, stderr = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc, seen, stdout, stderr


@pytest.mark.parametrize("signame, exit_code", [("SIGINT", 130), ("SIGTERM", 143)])
def test_a_stop_before_the_first_point_says_so_and_json_has_a_document(tmp_path, monkeypatch,
                                                                        signame, exit_code):
    """Ctrl-C while acquire connected to or set up the analyser said "laminid: interrupted"
    and --json printed nothing (a reader got no document); SIGTERM there killed acquire
    without a word. Both now stop as the session does: one line saying nothing was measured
    or written, the error document with --json, exit 130 / 143."""
    import os
    import signal

    import laminid_cli.instrument.registry as registry

    def stopped(*args, **kw):
        os.kill(os.getpid(), getattr(signal, signame))
        for _ in range(1000):       # the eval loop runs the Python handler within this
            pass
        raise AssertionError("the signal did not stop acquire")

    monkeypatch.setattr(registry, "open_analyser", stopped)
    out = tmp_path / "c.h5"
    def not_acquires(signum, frame):     # without acquire's own, SIGTERM ended pytest
        raise RuntimeError("SIGTERM reached the default handler")

    previous = signal.signal(signal.SIGTERM, not_acquires)
    try:
        r = CliRunner().invoke(cli, ["acquire", "--analyser", "TCPIP::127.0.0.1::5025::SOCKET",
                                     "--no-prompt", "--json", "-o", str(out)])
        assert signal.getsignal(signal.SIGTERM) is not_acquires   # acquire put it back
    finally:
        signal.signal(signal.SIGTERM, previous)
    what = "interrupted" if signame == "SIGINT" else "terminated (SIGTERM)"
    message = (f"{what} while connecting to or setting up the analyser, before the first "
               f"point: no point measured; nothing written to {out}")
    assert r.exit_code == exit_code
    assert r.stderr == f"laminid: stopped: {message}\n"
    error = json.loads(r.stdout)["error"]
    assert error["message"] == message and error["exit_code"] == exit_code
    assert not out.exists()


def test_resume_on_an_analyser_of_another_model_is_refused(tmp_path, hp, sr):
    """A 35670A's unfinished file resumed on an SR785 went on, and the file's /instrument
    then named the SR785 for every point. Refused now before the set-up is sent, naming both
    models (exit 2, the file unchanged); the same model resumes."""
    out = tmp_path / "p.h5"
    assert acquire(hp, out, "--no-prompt", points=1).exit_code == 0
    with h5py_file(out, "r+") as f:
        f.attrs["complete"] = False          # a session that stopped after point 1
    before = out.read_bytes()
    r = acquire(sr, out, "--no-prompt", "--resume", points=2)
    assert r.exit_code == 2
    assert (f"laminid: error: {out}: cannot resume on another analyser model: its points "
            "were measured with the 35670A (HEWLETT-PACKARD,35670A,") in r.stderr
    assert (f"the analyser at {sr.resource.replace('TCPIP::', 'TCPIP0::')} is the SR785; the "
            "file records one instrument for all its points: resume on the 35670A") in r.stderr
    assert out.read_bytes() == before
    r = acquire(sr, out, "--no-prompt", "--resume", "--json", points=2)
    assert json.loads(r.stdout)["error"]["file"] == str(out)
    r = acquire(hp, out, "--no-prompt", "--resume", points=2)
    assert r.exit_code == 0 and read_frf_h5(out).labels == ("1", "2")


def h5py_file(path, mode):
    import h5py

    return h5py.File(path, mode)


def test_nothing_answering_idn_is_bad_input_with_what_to_check(tmp_path):
    """A port or GPIB address where nothing answers *IDN? (a listening socket that never
    replies here) was an analyser fault, exit 1, naming the timeout only; nothing was
    measured there, as with a refused connection: exit 2, with what to check."""
    import socket

    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(1)                  # the connection completes, nothing ever answers
        resource = f"TCPIP::127.0.0.1::{silent.getsockname()[1]}::SOCKET"
        out = tmp_path / "x.h5"
        r = run(["acquire", "--analyser", resource, "--timeout", "0.2", "--no-prompt", "-o",
                 str(out)])
    assert r.exit_code == 2
    assert r.stderr.startswith(f"laminid: error: analyser {resource.replace('TCPIP', 'TCPIP0')} "
                               "did not answer within 0.2 s (waiting for the answer to '*IDN?', "
                               "read): no analyser answering there; check the address")
    assert "(--timeout)" in r.stderr and len(r.stderr.splitlines()) == 1 and not out.exists()


def test_the_resume_command_keeps_the_timeout_given(tmp_path, hp, monkeypatch):
    """The --resume command printed when a session stops dropped --timeout: a slow link (a
    GPIB gateway) given --timeout 20 timed out again on the command it was told to run."""
    _interrupt_on_second_point(monkeypatch)
    out = tmp_path / "c.h5"
    r = acquire(hp, out, "--no-prompt")          # FAST has --timeout 0.5
    assert r.exit_code == 130
    assert "--timeout 0.5" in r.stderr.split("continue with: ")[1]


def test_a_forced_model_that_contradicts_a_known_identity_is_refused(tmp_path, hp):
    """--model sr785 on an analyser that identifies as a 35670A: a warning, then a timeout
    on the SR785's first query ('FSTR? 0'), exit 1, naming neither model as the cause. Now
    refused after *IDN?, before any set-up, naming both (exit 2)."""
    out = tmp_path / "m.h5"
    r = acquire(hp, out, "--model", "SR785", "--no-prompt", points=1)
    assert r.exit_code == 2
    assert r.stderr.startswith(
        f"laminid: error: --model SR785: the analyser at {hp.resource.replace('TCPIP', 'TCPIP0')}"
        " identifies as the 35670A ('HEWLETT-PACKARD,35670A,")
    assert "not the SR785; use --model auto or the 35670A's name" in r.stderr
    assert not out.exists() and not any(c.startswith("FSTR") for c in hp.log)


def test_acquire_lines_escape_a_non_printable_character_of_the_folder(tmp_path, hp):
    """acquire's closing line ('<out>: 1 point(s) ...; next: laminid fit-frf <out> ...') and
    those of a complete file given --resume printed the path as it was: a folder 'bd\u202e'
    reversed them; escaped as the error line escapes it, the file written where asked."""
    folder = tmp_path / "bd\u202e"
    folder.mkdir()
    out = folder / "plate.frf.h5"
    r = acquire(hp, out, "--no-prompt", points=1)
    assert r.exit_code == 0, r.output
    shown = f"{tmp_path}/bd\\u202e/plate.frf.h5"
    assert f"{shown}: 1 point(s), 801 lines 0-1600 Hz; next: laminid fit-frf {shown} " in r.stderr
    assert "\u202e" not in r.stderr and read_frf_h5(out).n_points == 1
    r = acquire(hp, out, "--no-prompt", "--resume", points=1)
    assert r.exit_code == 0, r.output
    assert f"{shown}: already complete: 1 point (1), 801 lines" in r.stderr
    assert "\u202e" not in r.stderr
