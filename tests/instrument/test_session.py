"""Roving-hammer workflow without click or sockets: a fake analyser and a scripted UI."""

from __future__ import annotations

import numpy as np
import pytest

from laminid_cli.errors import InstrumentError
from laminid_cli.frf.store import FrfWriter
from laminid_cli.frf.store import read_frf_h5 as _read_frf_h5
from laminid_cli.instrument.base import AcquisitionSettings, Measurement
from laminid_cli.instrument.session import (AcquisitionInterrupted, SessionOptions,
                                            assess_point, run_session)

FREQ = np.linspace(0.0, 100.0, 51)


class FakeAnalyser:
    """Serves a list of outcomes: a coherence level (float) or an exception to raise."""

    MODEL = "FAKE"

    def __init__(self, outcomes):
        self.outcomes = list(outcomes)
        self.aborted = 0

    def measure(self, n_averages, progress=None, averaged=None):
        outcome = self.outcomes.pop(0)
        if isinstance(outcome, BaseException):
            raise outcome
        if progress:
            progress(n_averages, n_averages)
        if averaged:
            averaged()
        frf = 1.0 / (50.0 ** 2 - FREQ ** 2 + 2j * 0.02 * 50.0 * FREQ)
        return Measurement(freq=FREQ, frf=frf, coherence=np.full(FREQ.shape, outcome),
                           n_averages=n_averages, overloads=0)

    def abort(self):
        self.aborted += 1


class ScriptUI:
    def __init__(self, ready=(), repeat=()):
        self.ready_answers, self.repeat_answers = list(ready), list(repeat)
        self.lines, self.progress_seen = [], []

    def ready(self, label, index, total):
        return self.ready_answers.pop(0)

    def progress(self, label, index, total, hits, n):
        self.progress_seen.append((label, hits, n))

    def summary(self, quality):
        self.lines.append(quality.line())

    def repeat(self, quality):
        return self.repeat_answers.pop(0)


SETTINGS = AcquisitionSettings(averages=4)


def read_frf_h5(path):
    """Read back the file the session has just written, in this process (no child-process
    probe: that guards against files of unknown origin, and costs ~0.3 s per read)."""
    return _read_frf_h5(path, probe=False)


def writer(tmp_path, **kw):
    return FrfWriter(tmp_path / "s.h5", FREQ, units="Pa/N", **kw)


def test_poor_point_is_repeated_and_replaced_in_the_file(tmp_path):
    ui = ScriptUI(ready=["go", "go"], repeat=[True])
    w = writer(tmp_path)
    result = run_session(FakeAnalyser([0.5, 0.99, 0.98]), w, SETTINGS,
                         SessionOptions(n_points=2, coherence_min=0.9), ui)
    assert result.complete and result.repeated == 1 and result.measured == ["1", "2"]
    assert "POOR coherence" in ui.lines[0] and ui.lines[1].endswith("- ok")
    s = read_frf_h5(tmp_path / "s.h5")
    assert s.labels == ("1", "2") and s.meta["complete"] is True
    np.testing.assert_allclose(s.coherence[0], 0.99)  # the repeat replaced the poor point
    assert ("1", 4, 4) in ui.progress_seen


def test_skip_and_quit_leave_an_incomplete_but_valid_file(tmp_path):
    ui = ScriptUI(ready=["go", "skip", "quit"])
    result = run_session(FakeAnalyser([0.99]), writer(tmp_path), SETTINGS,
                         SessionOptions(n_points=4), ui)
    assert result.quit and result.skipped == ["2"] and not result.complete
    s = read_frf_h5(tmp_path / "s.h5")
    assert s.labels == ("1",) and s.meta["complete"] is False


def test_no_prompt_keeps_poor_points_without_asking(tmp_path):
    ui = ScriptUI()
    result = run_session(FakeAnalyser([0.3, 0.3]), writer(tmp_path), SETTINGS,
                         SessionOptions(n_points=2, prompt=False), ui)
    assert result.complete and len(ui.lines) == 2


def test_ctrl_c_aborts_the_analyser_and_keeps_finished_points(tmp_path):
    fake = FakeAnalyser([0.99, KeyboardInterrupt()])
    with pytest.raises(AcquisitionInterrupted) as info:
        run_session(fake, writer(tmp_path), SETTINGS,
                    SessionOptions(n_points=3, prompt=False, resume_hint="laminid ... --resume"),
                    ScriptUI())
    assert info.value.exit_code == 130
    assert "1 point(s) saved in" in str(info.value) and "laminid ... --resume" in str(info.value)
    assert fake.aborted == 1
    assert read_frf_h5(tmp_path / "s.h5").n_points == 1


def test_instrument_fault_keeps_finished_points_and_says_so(tmp_path):
    fake = FakeAnalyser([0.99, 0.99, InstrumentError("analyser X did not answer within 1 s")])
    with pytest.raises(InstrumentError, match=r"^point 3: analyser X did not answer within 1 s; "
                                              r"point 3 not saved; 2 point\(s\) saved"):
        run_session(fake, writer(tmp_path), SETTINGS, SessionOptions(n_points=3, prompt=False),
                    ScriptUI())
    assert read_frf_h5(tmp_path / "s.h5").n_points == 2


def test_resume_measures_only_the_missing_points(tmp_path):
    w = writer(tmp_path)
    run_session(FakeAnalyser([0.99]), w, SETTINGS, SessionOptions(n_points=1, prompt=False),
                ScriptUI())
    w2 = writer(tmp_path, resume=True)
    result = run_session(FakeAnalyser([0.99, 0.99]), w2, SETTINGS,
                         SessionOptions(n_points=3, prompt=False), ScriptUI())
    assert result.measured == ["2", "3"] and result.complete


def test_quality_uses_coherence_at_the_resonances_not_the_antiresonances():
    frf = 1.0 / (50.0 ** 2 - FREQ ** 2 + 2j * 0.02 * 50.0 * FREQ)
    coh = np.where(np.abs(frf) > np.quantile(np.abs(frf), 0.5), 0.97, 0.2)
    q = assess_point("7", Measurement(FREQ, frf, coh, 5, 0), coherence_min=0.9)
    assert q.ok and q.peak_freq_hz == 50.0 and q.peak_coherence == pytest.approx(0.97)
    assert q.line() == ("point 7: 5 hits, coherence at resonances 0.970 (peak 0.970 at 50.0 Hz), "
                        "overloads 0 - ok")


FULL_DISK_SCRIPT = """
import resource, signal, sys
import numpy as np
from pathlib import Path
from laminid_cli.frf.store import FrfWriter
from laminid_cli.instrument.session import PointNotWritten, SessionOptions, run_session
from tests.instrument.test_session import SETTINGS, FakeAnalyser, ScriptUI

path = Path(sys.argv[1])
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)      # a write past the limit: EFBIG, as ENOSPC
w = FrfWriter(path, np.linspace(0.0, 100.0, 51), units="Pa/N")
w.add_point("1", np.ones(51), np.ones(51))
size = path.stat().st_size
resource.setrlimit(resource.RLIMIT_FSIZE, (size + 200, size + 200))   # no room for point 2
fake = FakeAnalyser([0.99, 0.99])
try:
    run_session(fake, w, SETTINGS, SessionOptions(n_points=3, prompt=False,
                                                  resume_hint="laminid ... --resume"), ScriptUI())
except PointNotWritten as exc:
    print("exit", exc.exit_code, "aborted", fake.aborted, "saved", exc.result.n_saved)
    print(exc)
"""


def test_a_full_disk_stops_the_session_cleanly_and_keeps_the_saved_points(tmp_path):
    """The disk filling while a point is written (here a file-size limit, which HDF5 meets
    the same way): HDF5 writing to the disk itself failed on close, h5py printed tracebacks
    and the process died of a segmentation fault. Now: PointNotWritten naming the file and
    the point, the analyser stopped, no temporary file left, the saved point readable."""
    import subprocess
    import sys
    from pathlib import Path

    path = tmp_path / "s.h5"
    root = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-c", FULL_DISK_SCRIPT, str(path)], cwd=root,
                         capture_output=True, text=True, timeout=60,
                         env={**__import__("os").environ, "PYTHONPATH": str(root)})
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stderr == ""
    head, message = run.stdout.splitlines()
    assert head == "exit 2 aborted 1 saved 1"
    assert message.startswith(f"point 2: cannot write {path}: File too large; point 2 not saved")
    assert "1 point(s) saved in" in message and message.endswith("laminid ... --resume")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.h5"]
    assert read_frf_h5(path).labels == ("1",)


class SignalledWriter(FrfWriter):
    """Ctrl-C (SIGINT) or SIGTERM arrives while the file is being written with point ``at``."""

    def __init__(self, *args, at: str, signum: int, **kw):
        super().__init__(*args, **kw)
        self.at, self.signum = at, signum

    def _write(self, complete):
        import os

        if self.at in self.labels:
            self.at = None
            os.kill(os.getpid(), self.signum)
            for _ in range(1000):      # the eval loop runs a Python handler within this
                pass
        super()._write(complete)


@pytest.mark.parametrize("signame, exit_code", [("SIGINT", 130), ("SIGTERM", 143)])
def test_a_stop_while_a_point_is_written_saves_that_point_first(tmp_path, signame, exit_code):
    """Ctrl-C or SIGTERM while point 2 was written dropped it (the temporary file removed)
    after its hits were averaged; the point is now written and its quality line said, then
    the session stops as asked."""
    import signal

    from laminid_cli.instrument.session import Terminated

    signum = getattr(signal, signame)
    previous = signal.getsignal(signal.SIGTERM)
    if signum == signal.SIGTERM:      # as acquire installs it (_sigterm_stops_the_session)
        signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(Terminated()))
    try:
        w = SignalledWriter(tmp_path / "s.h5", FREQ, units="Pa/N", at="2", signum=signum)
        ui = ScriptUI()
        with pytest.raises(AcquisitionInterrupted) as info:
            run_session(FakeAnalyser([0.99, 0.99, 0.99]), w, SETTINGS,
                        SessionOptions(n_points=3, prompt=False), ui)
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert info.value.exit_code == exit_code
    assert "; 2 point(s) saved in" in str(info.value)
    assert info.value.result.measured == ["1", "2"] and info.value.result.n_saved == 2
    assert len(ui.lines) == 2
    assert read_frf_h5(tmp_path / "s.h5").labels == ("1", "2")


def test_a_temporary_file_left_by_a_killed_session_is_removed_by_the_next(tmp_path):
    """SIGKILL while a point was written left '.s.h5.tmp-PID' beside the FRF file for ever
    (a resume completed the file and kept it); the next writer of the file removes it, and
    keeps a temporary file of a process still running."""
    import os
    import subprocess
    import sys

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    stale, live = tmp_path / f".s.h5.tmp-{dead}", tmp_path / f".s.h5.tmp-{os.getppid()}"
    other = tmp_path / f".t.h5.tmp-{dead}"
    for p in (stale, live, other):
        p.write_bytes(b"half a point")
    w = writer(tmp_path)
    run_session(FakeAnalyser([0.99]), w, SETTINGS, SessionOptions(n_points=1, prompt=False),
                ScriptUI())
    assert not stale.exists() and live.exists() and other.exists()
    assert read_frf_h5(tmp_path / "s.h5").labels == ("1",)


def test_an_output_folder_removed_during_the_session_is_said_so(tmp_path):
    """The folder of the FRF file removed while the session ran: the point then measured
    cannot be written, and the message named the temporary file and said 1 point saved in a
    file that was gone."""
    import shutil

    folder = tmp_path / "run"
    folder.mkdir()
    w = FrfWriter(folder / "s.h5", FREQ, units="Pa/N")

    class RemovingUI(ScriptUI):
        def summary(self, quality):
            super().summary(quality)
            shutil.rmtree(folder)

    from laminid_cli.instrument.session import PointNotWritten

    with pytest.raises(PointNotWritten) as info:
        run_session(FakeAnalyser([0.99, 0.99]), w, SETTINGS,
                    SessionOptions(n_points=2, prompt=False, resume_hint="laminid ..."),
                    RemovingUI())
    assert str(info.value) == (
        f"point 2: cannot write {folder / 's.h5'}: No such file or directory; point 2 not saved "
        f"(free some space or fix the folder, then resume); {folder / 's.h5'} is gone, with the "
        "1 point(s) saved in it")


def test_a_full_disk_when_marking_the_file_complete_says_every_point_is_saved(tmp_path):
    """The disk full when the file, every point in it, is rewritten marked complete: the
    OSError left the session, and acquire said only 'laminid: error: No space left on
    device' (no file, no word of the points saved, --json an error document)."""
    import errno

    from laminid_cli.instrument.session import PointNotWritten

    class FullAtClose(FrfWriter):
        def close(self):
            raise OSError(errno.ENOSPC, "No space left on device")

    w = FullAtClose(tmp_path / "s.h5", FREQ, units="Pa/N")
    fake = FakeAnalyser([0.99, 0.99])
    with pytest.raises(PointNotWritten) as info:
        run_session(fake, w, SETTINGS, SessionOptions(n_points=2, prompt=False,
                                                      resume_hint="laminid ... --resume"),
                    ScriptUI())
    assert "--resume" not in str(info.value)       # nothing left to measure
    assert str(info.value).startswith(
        f"every point is measured, but {tmp_path / 's.h5'} could not be marked complete: No "
        "space left on device; its points are all saved and fit-frf reads it as it is; 2 "
        "point(s) saved in")
    assert info.value.result.complete and info.value.result.n_saved == 2
    assert read_frf_h5(tmp_path / "s.h5").labels == ("1", "2")


class StoppedAfterTwoHits(FakeAnalyser):
    """Its second measurement is stopped (Ctrl-C) after two of the hits."""

    def measure(self, n_averages, progress=None, averaged=None):
        if len(self.outcomes) == 1:
            progress(2, n_averages)
            raise KeyboardInterrupt
        return super().measure(n_averages, progress, averaged)


def test_a_stop_during_a_repeats_hits_says_the_point_measured_before_is_kept(tmp_path):
    """The stop message says which point's hits it discarded; for the repeat of a poor point
    it must not read as if that point were lost: its first measurement is in the file."""
    from laminid_cli.instrument.session import AcquisitionInterrupted

    ui = ScriptUI(ready=["go"], repeat=[True])
    with pytest.raises(AcquisitionInterrupted) as info:
        run_session(StoppedAfterTwoHits([0.5, 0.99]), writer(tmp_path), SETTINGS,
                    SessionOptions(n_points=2, coherence_min=0.9), ui)
    assert ("; point 1's repeat stopped at 2 of 4 hits, not saved (the point 1 measured "
            "before is kept)") in str(info.value)
    s = read_frf_h5(tmp_path / "s.h5")
    assert s.labels == ("1",)
    np.testing.assert_allclose(s.coherence[0], 0.5)       # the poor point, as measured
