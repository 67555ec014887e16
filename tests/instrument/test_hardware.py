"""Opt-in tests against a real analyser.

Skipped unless ``LAMINID_ANALYSER`` holds a VISA resource (e.g. ``GPIB0::5``); run with
``pytest -m hardware tests/instrument/test_hardware.py``. ``LAMINID_VISA_BACKEND`` selects the
pyvisa backend (default ``@py``). ``LAMINID_ANALYSER_HIT=1`` also measures one point: hit the
plate (channel 1 = hammer) when the test says so.

These tests are the check of the command details the drivers flag as "to confirm on a real
instrument" (overload bits, index tables, binary byte order).
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from laminid_cli.instrument.base import AcquisitionSettings
from laminid_cli.instrument.registry import open_analyser

RESOURCE = os.environ.get("LAMINID_ANALYSER")
pytestmark = [pytest.mark.hardware,
              pytest.mark.skipif(not RESOURCE, reason="set LAMINID_ANALYSER=<VISA resource>")]

SETTINGS = AcquisitionSettings(span_hz=1600.0, lines=400, averages=2)


@pytest.fixture
def analyser():
    with open_analyser(RESOURCE, timeout=10.0) as dsa:
        yield dsa


def test_identity_and_configuration_without_errors(analyser):
    assert analyser.matches(analyser.idn)
    analyser.configure(SETTINGS)            # raises on any error-queue / ESR entry, by command
    freq = analyser.read_frequency()
    analyser.check_axis(SETTINGS, freq)     # the resolution command was taken as lines
    assert freq.size in (SETTINGS.lines, SETTINGS.lines + 1)
    assert freq[0] == pytest.approx(0.0, abs=1e-9)
    assert np.all(np.diff(freq) > 0)
    assert freq[-1] == pytest.approx(SETTINGS.span_hz, rel=0.01)


@pytest.mark.skipif(os.environ.get("LAMINID_ANALYSER_HIT") != "1",
                    reason="set LAMINID_ANALYSER_HIT=1 and hit the plate to measure a point")
def test_one_point_with_hits(analyser, capsys):
    analyser.configure(SETTINGS)
    with capsys.disabled():
        print(f"\nhit the plate {SETTINGS.averages} times")
    m = analyser.measure(SETTINGS.averages)
    assert m.frf.shape == m.freq.shape == m.coherence.shape
    assert np.all(np.isfinite(m.frf)) and 0 <= m.coherence.min() <= m.coherence.max() <= 1
