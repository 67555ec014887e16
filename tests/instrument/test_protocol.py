"""Drivers against the manuals' command/response sequences (scripted transport, no hardware)."""

from __future__ import annotations

import numpy as np
import pytest

from laminid_cli.errors import InstrumentError
from laminid_cli.instrument.base import AcquisitionSettings
from laminid_cli.instrument.hp35670a import HP35670A
from laminid_cli.instrument.sr785 import SR785
from laminid_cli.instrument.testing import (ScriptedTransport, doubles_be, expected_protocol,
                                            floats_le, ieee_block)
from laminid_cli.instrument.transport import AnalyserSetupError

SETTINGS = AcquisitionSettings(span_hz=1600.0, start_hz=0.0, lines=800, averages=5,
                               trigger_level_pct=10.0, pretrigger_s=0.005,
                               force_window_s=0.01, exp_window_s=0.1)

HP_CONFIGURE = [
    ("*CLS", None), ("INST:NSEL 0", None), ("INP2 ON", None),
    ("CALC1:FEED 'XFR:POW:RAT 2,1'", None), ("CALC2:FEED 'XFR:POW:COH 1,2'", None),
    ("FREQ:SPAN 1600 HZ", None), ("FREQ:STAR 0 HZ", None), ("FREQ:RES 800", None),
    ("AVER:STAT ON", None), ("AVER:TYPE RMS", None), ("AVER:COUN 5", None),
    ("TRIG:SOUR INP1", None), ("TRIG:SLOP POS", None), ("TRIG:LEV 10 PCT", None),
    ("TRIG:DEL1 -0.005 S", None), ("TRIG:DEL2 -0.005 S", None),
    ("WIND1:TYPE FORC", None), ("WIND1:FORC 0.01 S", None),
    ("WIND2:TYPE EXP", None), ("WIND2:EXP 0.1 S", None),
    ("FORM:DATA REAL,64", None), ("CALC1:FORM NYQ", None), ("CALC2:FORM MLIN", None),
]

SR_CONFIGURE = [
    ("*CLS", None), ("MGRP 2,0", None), ("MEAS 0,11", None), ("MEAS 1,9", None),
    ("FBAS 2,1", None), ("FSPN 2,1600", None), ("FLIN 2,3", None), ("FSTR 2,0", None),
    ("FAVG 2,1", None), ("FAVM 2,2", None), ("FAVT 2,0", None), ("FAVN 2,5", None),
    ("FWIN 2,5", None), ("FWFL 2,0.01", None), ("FWTC 2,20", None),
    ("TSRC 1", None), ("TMOD 0", None), ("TSLP 0", None), ("TLVL 10", None),
    ("TDLA -0.005", None), ("TDLB -0.005", None),
    ("VIEW 0,7", None), ("VIEW 1,1", None),
]


# ------------------------------------------------------------------------ 35670A
def test_hp_configure_sends_the_impact_setup_and_reads_the_error_queue():
    steps = HP_CONFIGURE + [("SYST:ERR?", '+0,"No error"')]
    with expected_protocol(HP35670A, steps) as dsa:
        dsa.configure(SETTINGS)


def test_hp_error_queue_entries_raise_instrument_error_with_the_text():
    steps = HP_CONFIGURE + [("SYST:ERR?", '-222,"Data out of range"'),
                            ("SYST:ERR?", '-113,"Undefined header"'),
                            ("SYST:ERR?", '+0,"No error"')]
    with expected_protocol(HP35670A, steps) as dsa:
        with pytest.raises(InstrumentError, match=r'-222,"Data out of range"; -113'):
            dsa.configure(SETTINGS)


def test_hp_measure_polls_esr_and_reads_big_endian_real64_blocks():
    freq = np.array([0.0, 2.0, 4.0])
    frf = np.array([1 + 2j, -3 + 0.5j, 0.25 - 1j])
    coh = np.array([0.5, 0.99, 1.0])
    pairs = np.column_stack([frf.real, frf.imag]).ravel()
    steps = [("ABOR", None), ("*CLS", None), ("INIT:IMM", None), ("*OPC", None),
             ("*ESR?", "+0"), ("*ESR?", "+0"), ("*ESR?", "+1"),
             ("STAT:QUES:VOLT:EVEN?", "+4"),
             ("CALC1:X:DATA?", ieee_block(doubles_be(freq))),
             ("CALC1:DATA?", ieee_block(doubles_be(pairs))),
             ("CALC2:DATA?", ieee_block(doubles_be(coh)))]
    seen = []
    with expected_protocol(HP35670A, steps, poll_s=0.0) as dsa:
        m = dsa.measure(5, progress=lambda hits, n: seen.append((hits, n)))
    np.testing.assert_array_equal(m.freq, freq)
    np.testing.assert_array_equal(m.frf, frf)
    np.testing.assert_array_equal(m.coherence, coh)
    assert m.overloads == 1  # bit 2: channel 2 over range
    assert seen == [(-1, 5), (5, 5)]  # the 35670A cannot tell the hit count


def test_hp_truncated_block_is_an_instrument_error():
    block = ieee_block(doubles_be([1.0, 2.0, 3.0]))[:-10]
    with expected_protocol(HP35670A, [("CALC2:DATA?", block)]) as dsa:
        with pytest.raises(InstrumentError, match="truncated binary transfer: expected 24 bytes"):
            dsa.read_coherence()


def test_hp_answer_that_is_not_a_block_is_an_instrument_error():
    dsa = HP35670A(ScriptedTransport([("CALC2:DATA?", b"1.0,2.0,3.0\n")]))
    with pytest.raises(InstrumentError, match="definite-length block"):
        dsa.read_coherence()


def test_hp_rejects_a_span_it_does_not_offer_before_sending_anything():
    with expected_protocol(HP35670A, []) as dsa:
        with pytest.raises(AnalyserSetupError, match=r"span of 1000 Hz; spans \(Hz\): 51200, "
                                                     r"25600.*1600"):
            dsa.configure(AcquisitionSettings(span_hz=1000.0))
        with pytest.raises(AnalyserSetupError, match="3200 lines; lines: 100, 200, 400, 800$"):
            dsa.configure(AcquisitionSettings(lines=3200))


def test_hp_keep_setup_reads_the_settings_back():
    steps = [("FREQ:SPAN?", "+1.60000000000E+003"), ("FREQ:STAR?", "+0.0E+000"),
             ("FREQ:RES?", "+800"), ("AVER:COUN?", "+10")]
    with expected_protocol(HP35670A, steps) as dsa:
        s = dsa.read_settings()
    assert (s.span_hz, s.start_hz, s.lines, s.averages) == (1600.0, 0.0, 800, 10)


def test_context_manager_aborts_a_running_measurement_and_closes():
    steps = [("ABOR", None), ("*CLS", None), ("INIT:IMM", None), ("*OPC", None), ("ABOR", None)]
    with expected_protocol(HP35670A, steps) as dsa:
        with dsa:
            dsa.start()
        assert dsa.transport.closed


# ------------------------------------------------------------------------- SR785
def test_sr785_configure_sends_the_impact_setup_and_checks_esr():
    steps = SR_CONFIGURE + [("*ESR?", "0")]
    with expected_protocol(SR785, steps) as dsa:
        dsa.configure(SETTINGS)


def test_sr785_execution_error_bit_raises():
    steps = SR_CONFIGURE + [("*ESR?", "16")]
    with expected_protocol(SR785, steps) as dsa:
        with pytest.raises(InstrumentError, match="execution error"):
            dsa.configure(SETTINGS)


def test_sr785_measure_uses_navg_dsps_and_headerless_dspb():
    n = 3
    frf = np.array([1 + 2j, -3 + 0.5j, 0.25 - 1j], dtype=np.complex64)
    coh = np.array([0.5, 0.75, 1.0], dtype=np.float32)
    yx = np.column_stack([frf.imag, frf.real]).ravel()   # Nyquist view: Y (imag) then X (real)
    steps = [("DSPS?", "0"), ("STRT", None),
             ("DSPS? 1", "0"), ("NAVG? 0", "0"),
             ("DSPS? 1", "0"), ("NAVG? 0", "2"),
             ("DSPS? 1", "1"),
             ("INPS?", "0"),
             ("FSTR? 0", "100"), ("FSPN? 0", "1600"), ("FLIN? 0", "3"), ("DSPN? 0", str(n)),
             ("DSPN? 0", str(n)), ("DSPB? 0", floats_le(yx)),
             ("DSPN? 1", str(n)), ("DSPB? 1", floats_le(coh))]
    seen = []
    with expected_protocol(SR785, steps, poll_s=0.0) as dsa:
        m = dsa.measure(5, progress=lambda hits, n_avg: seen.append(hits))
    np.testing.assert_allclose(m.freq, [100.0, 102.0, 104.0])
    np.testing.assert_allclose(m.frf, frf)
    np.testing.assert_allclose(m.coherence, coh)
    assert seen == [0, 2, 5] and m.overloads == 0


def test_sr785_short_dspb_transfer_is_an_instrument_error():
    steps = [("DSPN? 1", "801"), ("DSPB? 1", floats_le([0.5] * 100))]
    with expected_protocol(SR785, steps) as dsa:
        with pytest.raises(InstrumentError, match="expected 3204 bytes, received 400"):
            dsa.read_coherence()


def test_sr785_rejects_lines_it_does_not_offer():
    with expected_protocol(SR785, []) as dsa:
        with pytest.raises(AnalyserSetupError, match="1600 lines; lines: 100, 200, 400, 800"):
            dsa.configure(AcquisitionSettings(lines=1600))


def test_sr785_abort_pauses():
    with expected_protocol(SR785, [("PAUS", None)]) as dsa:
        dsa.abort()


def test_window_longer_than_the_record_is_rejected():
    with expected_protocol(SR785, []) as dsa:
        with pytest.raises(AnalyserSetupError, match=r"exp window 2 s must be within the time "
                                                     r"record \(0-0.5 s"):
            dsa.configure(AcquisitionSettings(exp_window_s=2.0))
