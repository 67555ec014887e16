"""GPIB-style resource names, auto-detection and error cases through pyvisa-sim."""

from __future__ import annotations

import pytest
import yaml
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.instrument.hp35670a import HP35670A
from laminid_cli.instrument.registry import open_analyser
from laminid_cli.instrument.transport import AnalyserSetupError, normalise_resource
from tests.instrument.test_protocol import HP_COMMANDS, SETTINGS

HP_IDN = "HEWLETT-PACKARD,35670A,0,A.02.01"


def _device(idn, commands):
    return {
        "eom": {"GPIB INSTR": {"q": "\n", "r": "\n"}},
        "error": {"error_queue": [{"q": "SYST:ERR?", "default": '+0,"No error"',
                                   "command_error": '-113,"Undefined header"'}]},
        "dialogues": [{"q": "*IDN?", "r": idn}] + [{"q": c} for c in commands],
    }


@pytest.fixture
def sim_backend(tmp_path):
    config = ["*CLS"] + HP_COMMANDS
    spec = {
        "spec": "1.0",
        "devices": {
            "hp_ok": _device(HP_IDN, config),
            # a firmware that rejects the span command: the error queue must report it
            "hp_rejects_span": _device(HP_IDN, [c for c in config if not c.startswith("FREQ:SPAN")]),
            "dmm": _device("KEITHLEY INSTRUMENTS INC.,MODEL 2000,1,A02", []),
        },
        "resources": {"GPIB0::5::INSTR": {"device": "hp_ok"},
                      "GPIB0::6::INSTR": {"device": "hp_rejects_span"},
                      "GPIB0::9::INSTR": {"device": "dmm"}},
    }
    path = tmp_path / "analysers.yaml"
    path.write_text(yaml.safe_dump(spec))
    return f"{path}@sim"


@pytest.mark.parametrize("written, full", [
    ("GPIB0::5", "GPIB0::5::INSTR"), ("GPIB::5", "GPIB0::5::INSTR"),
    ("gpib1::12::INSTR", "GPIB1::12::INSTR"), ("GPIB0::5::3", "GPIB0::5::3::INSTR"),
    ("TCPIP::10.0.0.7::5025::SOCKET", "TCPIP0::10.0.0.7::5025::SOCKET"),
    ("TCPIP::dsa.lab::INSTR", "TCPIP0::dsa.lab::inst0::INSTR"),
])
def test_resource_strings_as_users_write_them(written, full):
    assert normalise_resource(written) == full


@pytest.mark.parametrize("bad", ["GPIB0", "FOO::5::INSTR", "", "TCPIP::host::notaport::SOCKET"])
def test_unparseable_resource_is_bad_input(bad):
    with pytest.raises(AnalyserSetupError, match="is not a VISA resource string"):
        normalise_resource(bad)


def test_gpib_short_name_autodetects_the_35670a_and_configures(sim_backend):
    with open_analyser("GPIB0::5", backend=sim_backend, timeout=0.5) as dsa:
        assert isinstance(dsa, HP35670A)
        assert dsa.transport.resource == "GPIB0::5::INSTR"
        assert dsa.idn == HP_IDN
        dsa.configure(SETTINGS)  # error queue empty -> no exception


def _acquire(backend, resource, tmp_path):
    return CliRunner().invoke(cli, ["acquire", "--analyser", resource, "--visa-backend", backend,
                                    "--timeout", "0.5", "--no-prompt",
                                    "-o", str(tmp_path / "x.h5")])


def test_error_queue_entry_after_configuring_exits_1(sim_backend, tmp_path):
    r = _acquire(sim_backend, "GPIB0::6", tmp_path)
    assert r.exit_code == 1
    # the rejected command is named, with the analyser's error text
    assert ("35670A rejected 1 command(s) while configuring: 'FREQ:SPAN 1600' -> "
            '-113,"Undefined header"') in r.output
    assert not (tmp_path / "x.h5").exists()


def test_unsupported_instrument_on_gpib_exits_2(sim_backend, tmp_path):
    r = _acquire(sim_backend, "GPIB0::9", tmp_path)
    assert r.exit_code == 2
    assert "KEITHLEY INSTRUMENTS INC.,MODEL 2000,1,A02', which no laminid driver supports" \
        in r.output


@pytest.mark.filterwarnings("ignore:read string doesn't end with termination")
def test_absent_resource_exits_2(sim_backend, tmp_path):
    r = _acquire(sim_backend, "GPIB0::17", tmp_path)
    assert r.exit_code == 2, r.output
    assert "instrument at GPIB0::17::INSTR gave an empty answer to *IDN?" in r.output


def test_gpib_without_a_gpib_library_names_the_extra_to_install():
    pytest.importorskip("pyvisa_py")
    try:
        import gpib_ctypes  # noqa: F401
        pytest.skip("gpib-ctypes is installed here")
    except ImportError:
        pass
    with pytest.raises(AnalyserSetupError) as info:
        open_analyser("GPIB0::5", backend="@py", timeout=0.5)
    msg = str(info.value)
    assert "pip install 'laminid[gpib]'" in msg and "--visa-backend @ivi" in msg


def test_progress_uses_carriage_returns_only_on_a_terminal(capsys):
    from laminid_cli.commands.acquire import _ClickUI

    for tty, expected in ((True, "\rpoint 1 (1/2): 2/5 hits averaged, waiting for hit 3"),
                          (False, "point 1 (1/2): 2/5 hits averaged, waiting for hit 3\n")):
        _ClickUI(path=None, tty=tty).progress("1", 1, 2, 2, 5)
        err = capsys.readouterr().err
        assert err.startswith(expected) and (("\r" in err) == tty)
