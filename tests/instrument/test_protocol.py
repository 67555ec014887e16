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

#: the 35670A set-up, each string as the public evidence gives it (hp35670a docstring)
HP_COMMANDS = [
    "INST:SEL FFT", "INP2:STAT 1",
    "CALC1:FEED 'XFR:POW:RAT 2,1'", "CALC2:FEED 'XFR:POW:COH 1,2'",
    "FREQ:SPAN 1600", "FREQ:STAR 0", "FREQ:RES 800",
    "AVER:STAT 1", "AVER:TYPE RMS", "AVER:COUN 5",
    "TRIG:SOUR INT1", "TRIG:SLOP POS", "TRIG:LEV 10 PCT",
    "TRIG:STAR1 -0.005", "TRIG:STAR2 -0.005",
    "WIND1:TYPE FORC", "WIND1:FORC 0.01", "WIND2:TYPE EXP", "WIND2:EXP 0.1",
    "FORM:DATA REAL,64", "CALC1:FORM NYQ", "CALC2:FORM MLIN",
]
HP_OK = ("SYST:ERR?", '+0,"No error"')
#: configure = *CLS, then every command followed by one error-queue read
HP_CONFIGURE = [("*CLS", None)] + [step for c in HP_COMMANDS for step in ((c, None), HP_OK)]

SR_COMMANDS = [
    "MGRP 2,0", "MEAS 0,11", "MEAS 1,9",
    "FBAS 2,1", "FSPN 2,1600", "FLIN 2,3", "FSTR 2,0",
    "FAVG 2,1", "FAVM 2,2", "FAVT 2,0", "FAVN 2,5",
    "FWIN 2,5", "W1FE 0", "W2FE 1", "FWFL 2,0.01", "FWTC 2,20",
    "TSRC 1", "TMOD 0", "TSLP 0", "TLVL 10", "TDLA -0.005", "TDLB -0.005",
    "VIEW 0,7", "VIEW 1,1",
]
SR_OK = ("*ESR?", "0")
SR_CONFIGURE = [("*CLS", None)] + [step for c in SR_COMMANDS for step in ((c, None), SR_OK)]


def _with_answers(commands, answers, ok):
    """Configure script where the check after command ``c`` answers ``answers[c]``."""
    steps = []
    for c in commands:
        steps.append((c, None))
        steps += answers.get(c, [ok])
    return steps


# ------------------------------------------------------------------------ 35670A
def test_hp_configure_sends_the_evidenced_setup_and_reads_the_queue_after_each_command():
    with expected_protocol(HP35670A, HP_CONFIGURE) as dsa:
        dsa.configure(SETTINGS)
    sent = dsa.transport.sent
    # issue 12: trigger source INT1 (no INP1 value), delay as TRIGger:STARt<n> in seconds
    assert "TRIG:SOUR INT1" in sent and not any(c.startswith("TRIG:DEL") for c in sent)
    assert sent.count("SYST:ERR?") == len(HP_COMMANDS)


def test_hp_rejected_commands_are_named_with_the_analysers_text():
    steps = [("*CLS", None)] + _with_answers(HP_COMMANDS, {
        "TRIG:SOUR INT1": [("SYST:ERR?", '-224,"Illegal parameter value"'), HP_OK],
        "WIND2:EXP 0.1": [("SYST:ERR?", '-222,"Data out of range"'),
                          ("SYST:ERR?", '-221,"Settings conflict"'), HP_OK],
    }, HP_OK)
    with expected_protocol(HP35670A, steps) as dsa:
        with pytest.raises(InstrumentError) as info:
            dsa.configure(SETTINGS)
    assert str(info.value) == (
        "35670A rejected 2 command(s) while configuring: 'TRIG:SOUR INT1' -> "
        "-224,\"Illegal parameter value\" | 'WIND2:EXP 0.1' -> -222,\"Data out of range\"; "
        "-221,\"Settings conflict\"")


def test_hp_measure_polls_esr_and_reads_big_endian_real64_blocks():
    freq = np.array([0.0, 2.0, 4.0])
    frf = np.array([1 + 2j, -3 + 0.5j, 0.25 - 1j])
    coh = np.array([0.5, 0.99, 1.0])
    pairs = np.column_stack([frf.real, frf.imag]).ravel()
    steps = [("ABOR", None), ("*CLS", None), ("INIT:IMM", None), ("*OPC", None),
             ("*ESR?", "+0"), ("*ESR?", "+0"), ("*ESR?", "+1"),
             ("STAT:QUES:VOLT:EVEN?", "+2"),
             ("CALC1:X:DATA?", ieee_block(doubles_be(freq))),
             ("CALC1:DATA?", ieee_block(doubles_be(pairs))), HP_OK,
             ("CALC2:DATA?", ieee_block(doubles_be(coh))), HP_OK]
    seen = []
    with expected_protocol(HP35670A, steps, poll_s=0.0) as dsa:
        m = dsa.measure(5, progress=lambda hits, n: seen.append((hits, n)))
    np.testing.assert_array_equal(m.freq, freq)
    np.testing.assert_array_equal(m.frf, frf)
    np.testing.assert_array_equal(m.coherence, coh)
    assert m.overloads == 1  # bit 1: channel 2 over range (35670A manual p. 1-19)
    assert seen == [(-1, 5), (5, 5)]  # the 35670A cannot tell the hit count


@pytest.mark.parametrize("word, n", [(1, 1), (2, 1), (3, 2), (4, 0), (8, 0), (256, 0),
                                     (512, 0), (0x303, 2)])
def test_hp_overload_bits_are_the_manuals(word, n):
    """STATus:QUEStionable:VOLTage (35670A manual, Questionable Voltage Register Set): bit 0
    channel 1 over range, bit 1 channel 2; bits 2-3 are channels 3-4 (option AY6, not measured
    here) and bits 8-11 "input half-range", which are not overloads."""
    dsa = HP35670A(ScriptedTransport([("STAT:QUES:VOLT:EVEN?", f"+{word}")]))
    assert dsa.overloads() == n


def test_hp_truncated_block_is_an_instrument_error():
    block = ieee_block(doubles_be([1.0, 2.0, 3.0]))[:-10]
    with expected_protocol(HP35670A, [("CALC2:DATA?", block)]) as dsa:
        with pytest.raises(InstrumentError, match="truncated binary transfer: expected 24 bytes"):
            dsa.read_coherence()


def test_hp_answer_that_is_not_a_block_is_an_instrument_error():
    dsa = HP35670A(ScriptedTransport([("CALC2:DATA?", b"1.0,2.0,3.0\n")]))
    with pytest.raises(InstrumentError, match="definite-length block"):
        dsa.read_coherence()


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
def test_sr785_configure_sends_the_evidenced_setup_and_checks_esr_after_each_command():
    with expected_protocol(SR785, SR_CONFIGURE) as dsa:
        dsa.configure(SETTINGS)
    assert "FBAS 2,1" in dsa.transport.sent   # base frequency 102.4 kHz, both displays


def test_sr785_force_exponential_window_is_chosen_per_channel():
    """Roy SR785 driver (W1FE/W2FE: 0 force, 1 exponential): ch1 force, ch2 exponential, right
    after the force/exponential window is selected."""
    with expected_protocol(SR785, SR_CONFIGURE) as dsa:
        dsa.configure(SETTINGS)
    sent = [c for c in dsa.transport.sent if c != "*ESR?"]
    i = sent.index("FWIN 2,5")
    assert sent[i + 1:i + 3] == ["W1FE 0", "W2FE 1"]


def test_sr785_emulator_windows_the_response_only_when_ch2_is_exponential():
    from tests.instrument.emulator import SR785Emulator

    emu = SR785Emulator()
    for command in ("FSPN 2,1600", "FLIN 2,3", "FWIN 2,5", "FWTC 2,20"):
        emu.dispatch(command)
    assert emu.exp_tau_s() == 0.0            # both channels still on force
    emu.dispatch("W2FE 1")
    assert emu.exp_tau_s() == pytest.approx(0.1)   # 20 % of 800 lines / 1600 Hz


def test_sr785_rejected_command_is_named_with_the_esr_bits():
    steps = [("*CLS", None)] + _with_answers(SR_COMMANDS, {"FWTC 2,20": [("*ESR?", "32")]},
                                             SR_OK)
    with expected_protocol(SR785, steps) as dsa:
        with pytest.raises(InstrumentError) as info:
            dsa.configure(SETTINGS)
    assert str(info.value) == ("SR785 rejected 1 command(s) while configuring: 'FWTC 2,20' -> "
                               "*ESR? = 32 (bit 5: command error (unknown command or bad "
                               "syntax))")


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
             ("DSPN? 0", str(n)), ("DSPB? 0", floats_le(yx)), ("ERRS?", "0"), ("*ESR?", "0"),
             ("DSPN? 1", str(n)), ("DSPB? 1", floats_le(coh)), ("ERRS?", "0"), ("*ESR?", "0")]
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


def test_binary_transfers_decode_the_documented_byte_patterns():
    """Literal bytes, not the ``floats_le``/``doubles_be`` helpers (which share the drivers'
    assumption): SR785 manual p. 5-108/5-109, 4-byte IEEE floats sent least significant byte
    first, a Nyquist bin as Y (imag) then X (real); 35670A ``REAL,64`` doubles most significant
    byte first (fft_dev byte-swaps them on a little-endian PC)."""
    f2, f1, f0, fm2 = (b"\x00\x00\x00\x40", b"\x00\x00\x80\x3f", bytes(4),
                       b"\x00\x00\x00\xc0")                      # 2.0f, 1.0f, 0.0f, -2.0f
    dump = f2 + f1 + f0 + fm2                                    # bins 1+2j, -2+0j as (Y, X)
    with expected_protocol(SR785, [("DSPN? 0", "2"), ("DSPB? 0", dump)]) as dsa:
        np.testing.assert_array_equal(dsa.read_frf(), [1 + 2j, -2 + 0j])
    one, two = b"\x3f\xf0" + bytes(6), b"\x40\x00" + bytes(6)          # 1.0, 2.0 MSB first
    with expected_protocol(HP35670A, [("CALC2:DATA?", ieee_block(one + two))]) as dsa:
        np.testing.assert_array_equal(dsa.read_coherence(), [1.0, 2.0])


def test_sr785_abort_pauses():
    with expected_protocol(SR785, [("PAUS", None)]) as dsa:
        dsa.abort()


# ------------------------------------------------------- settings refused before sending
@pytest.mark.parametrize("driver, settings, message", [
    (HP35670A, AcquisitionSettings(span_hz=1000.0),
     r"span of 1000 Hz; spans \(Hz\): 51200, 25600.*1600"),
    (HP35670A, AcquisitionSettings(lines=3200), "3200 lines; lines: 100, 200, 400, 800$"),
    (SR785, AcquisitionSettings(lines=1600), "1600 lines; lines: 100, 200, 400, 800"),
    (SR785, AcquisitionSettings(exp_window_s=2.0),
     r"exp window 2 s must be within the time record \(0-0.5 s"),
    (SR785, AcquisitionSettings(averages=1), r"SR785 averages at least 2 records \(FAVN "
     r"2-32767; got 1\)$"),
    (SR785, AcquisitionSettings(exp_window_s=0.02),
     r"SR785: exp window 0.02 s is 4 % of the time record \(0.5 s\); its FWTC takes at "
     r"least 5 % \(0.025 s\)$"),
], ids=["hp-span", "hp-lines", "sr785-lines", "window-longer-than-the-record",
        "sr785-one-average", "sr785-fwtc-under-5-percent"])
def test_settings_the_analyser_does_not_offer_are_refused_before_sending_anything(
        driver, settings, message):
    with expected_protocol(driver, []) as dsa:
        with pytest.raises(AnalyserSetupError, match=message):
            dsa.configure(settings)


# ------------------------------------------- issue 15: errors flagged during a transfer
FREQ3 = np.array([0.0, 2.0, 4.0])
FRF3 = np.array([1 + 2j, -3 + 0.5j, 0.25 - 1j])
COH3 = np.array([0.5, 0.75, 1.0])
STALE = np.array([9.0, 9.0, 9.0])   # what a corrupt/stale first transfer carries


def _hp_transfer(trace, frf_pairs, coh, check):
    if trace == "FRF":
        return [("CALC1:DATA?", ieee_block(doubles_be(frf_pairs)))] + check
    return [("CALC2:DATA?", ieee_block(doubles_be(coh)))] + check


def _hp_script(bad_trace, repeats):
    pairs = np.column_stack([FRF3.real, FRF3.imag]).ravel()
    flagged = [("SYST:ERR?", '-230,"Data corrupt or stale"'), HP_OK]
    steps = [("ABOR", None), ("*CLS", None), ("INIT:IMM", None), ("*OPC", None),
             ("*ESR?", "+1"), ("STAT:QUES:VOLT:EVEN?", "+0"),
             ("CALC1:X:DATA?", ieee_block(doubles_be(FREQ3)))]
    for trace in ("FRF", "coherence"):
        if trace == bad_trace:
            steps += _hp_transfer(trace, np.tile(STALE, 2), STALE, flagged)
            good = [HP_OK] if not repeats else flagged
            steps += _hp_transfer(trace, pairs, COH3, good)
            if repeats:
                return steps
        else:
            steps += _hp_transfer(trace, pairs, COH3, [HP_OK])
    return steps


def _sr_transfer(trace, frf, coh, check):
    if trace == "FRF":
        yx = np.column_stack([frf.imag, frf.real]).ravel()
        return [("DSPN? 0", "3"), ("DSPB? 0", floats_le(yx))] + check
    return [("DSPN? 1", "3"), ("DSPB? 1", floats_le(coh))] + check


def _sr_script(bad_trace, repeats):
    ok = [("ERRS?", "0"), ("*ESR?", "0")]
    flagged = [("ERRS?", "4"), ("*ESR?", "16")]
    steps = [("DSPS?", "0"), ("STRT", None), ("DSPS? 1", "1"), ("INPS?", "0"),
             ("FSTR? 0", "0"), ("FSPN? 0", "800"), ("FLIN? 0", "0"), ("DSPN? 0", "3")]
    for trace in ("FRF", "coherence"):
        if trace == bad_trace:
            steps += _sr_transfer(trace, STALE + 0j, STALE, flagged)
            steps += _sr_transfer(trace, FRF3, COH3, flagged if repeats else ok)
            if repeats:
                return steps
        else:
            steps += _sr_transfer(trace, FRF3, COH3, ok)
    return steps


SCRIPTS = {HP35670A: _hp_script, SR785: _sr_script}
ERROR_TEXT = {HP35670A: '-230,"Data corrupt or stale"',
              SR785: "ERRS? = 4 (bit 2: math error); *ESR? = 16 (bit 4: execution error"}


@pytest.mark.parametrize("driver", [HP35670A, SR785])
@pytest.mark.parametrize("trace", ["FRF", "coherence"])
def test_an_error_flagged_once_during_a_transfer_is_cured_by_reading_the_trace_again(
        driver, trace):
    with expected_protocol(driver, SCRIPTS[driver](trace, repeats=False), poll_s=0.0) as dsa:
        m = dsa.measure(5)
    # the values of the second (clean) transfer, not the stale first one
    np.testing.assert_allclose(m.frf, FRF3, rtol=1e-6)
    np.testing.assert_allclose(m.coherence, COH3, rtol=1e-6)


@pytest.mark.parametrize("driver", [HP35670A, SR785])
@pytest.mark.parametrize("trace", ["FRF", "coherence"])
def test_an_error_flagged_twice_during_a_transfer_refuses_the_point(driver, trace):
    from laminid_cli.instrument.base import TransferError

    with expected_protocol(driver, SCRIPTS[driver](trace, repeats=True), poll_s=0.0) as dsa:
        with pytest.raises(TransferError) as info:
            dsa.measure(5)
    msg = str(info.value)
    assert msg.startswith(f"{driver.MODEL} flagged an error during the {trace} transfer, "
                          "twice (read again once): ")
    assert ERROR_TEXT[driver] in msg and info.value.trace == trace


def test_axis_with_other_lines_than_set_is_refused_by_name():
    dsa = HP35670A(ScriptedTransport([]))
    dsa.check_axis(SETTINGS, np.arange(801.0))          # 800 lines -> 801 bins: fine
    with pytest.raises(InstrumentError, match=r"^35670A: the analyser returns 101 frequency "
                                              r"lines but 800 lines were set \(span 1600 Hz\); "
                                              r"the resolution command was not taken"):
        dsa.check_axis(SETTINGS, np.arange(101.0))


def test_an_identity_with_a_control_character_is_kept_printable():
    """An *IDN? answer with an ESC or a bidi override inside (stripped at its ends only) went
    into the FRF file acquire writes, whose readers refuse such text: the file acquire wrote
    could not be read by fit-frf. Each such character is written as '?'."""
    dsa = SR785(ScriptedTransport([("*IDN?", "Stanford\x1b[31m,SR785\u202e,s/n1,ver1")]))
    assert dsa.idn == "Stanford?[31m,SR785?,s/n1,ver1"
    assert dsa.identity()["idn"] == dsa.idn
