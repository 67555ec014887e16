"""The one reader of an HDF5 file's ``format`` attribute (laminid_cli.h5open.format_of) and its
callers: batch (what a named input is), export (mode shapes or FRFs), identify's derived
result name (replace an earlier result, refuse anything else) and the result reader (show,
report)."""

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.h5open import file_format, format_of

#: format attributes another tool may write, and how format_of gives them (opaque data, HDF5's
#: H5T_OPAQUE, was its bytes in hex escapes: "b'\\x01\\x02\\x6C...'")
ODD_FORMATS = [(np.bytes_(b"\xff\xfe"), "\ufffd\ufffd"), (np.array([1, 2, 3]), "[1 2 3]"),
               (7, "7"), (np.void(b"\x01\x02laminid"), "<opaque data, 9 bytes>")]


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def h5(path, **attrs):
    with h5py.File(path, "w") as f:
        f.attrs.update(attrs)
    return path


def test_format_of_gives_text_whatever_the_attribute(tmp_path):
    assert file_format(h5(tmp_path / "none.h5")) == ""
    assert file_format(h5(tmp_path / "r.h5", format="laminid-result")) == "laminid-result"
    assert file_format(h5(tmp_path / "b.h5", format=np.bytes_(b"laminid-modes"))) == \
        "laminid-modes"
    for k, (value, text) in enumerate(ODD_FORMATS):
        assert file_format(h5(tmp_path / f"odd{k}.h5", format=value)) == text
    # a 0-d array, as resultfile.decode took it: its element (h5py gives scalars)
    for value in (np.array(b"laminid-result"), np.array("laminid-result")):
        assert format_of(type("F", (), {"attrs": {"format": value}})) == "laminid-result"
    with pytest.raises(FileNotFoundError):
        file_format(tmp_path / "missing.h5")
    (tmp_path / "text.h5").write_text("not hdf5")
    with pytest.raises(OSError):
        file_format(tmp_path / "text.h5")


@pytest.mark.parametrize("value, text", ODD_FORMATS)
def test_a_format_attribute_of_another_tool_is_no_traceback(tmp_path, value, text):
    """export and identify's default result name read the attribute themselves: undecodable
    bytes (UnicodeDecodeError) and an array (ValueError: truth value ambiguous) ended in a
    traceback; batch's reader (with which they now share format_of) named them. Each now
    answers as for any file that is not a laminid one."""
    odd = h5(tmp_path / "odd.h5", format=value)
    r = run("export", odd, "-o", tmp_path / "odd.unv")
    assert r.exit_code == 2 and isinstance(r.exception, SystemExit), repr(r.exception)
    assert r.output == (f"laminid: error: {odd}: not a laminid FRF file and no complex dataset "
                        "(FRF) in it; datasets: none\n")
    spec = tmp_path / "S1.4.yaml"
    spec.write_text(open("specimens/example1/S1.4.yaml").read())
    h5(tmp_path / "S1.4.result.h5", format=value)
    r = run("identify", spec, "--mesh", "4x4")
    assert r.exit_code == 2, r.output
    assert r.output == (f"laminid: error: {tmp_path / 'S1.4.result.h5'}: exists and is not a "
                        "laminid result file; move it or name the result with -o\n")
    for command in ("show", "report"):            # resultfile's reader: UnicodeDecodeError
        r = run(command, odd)
        assert r.exit_code == 2, r.output
        assert r.output == (f"laminid: error: {odd}: not a laminid identification result "
                            f"(a {text!r} file; expected format 'laminid-result'); make one "
                            "with laminid identify SPEC.yaml (or laminid identify A.yaml "
                            "B.yaml --joint, laminid batch FOLDER)\n")
    r = run("batch", odd, "--out", tmp_path / "out")
    assert r.exit_code == 2
    assert f"laminid: error: {odd}: an HDF5 file (format {text!r}), not a specimen file" in r.output


@pytest.mark.parametrize("value, text", ODD_FORMATS)
def test_the_frf_readers_read_the_format_with_format_of(tmp_path, value, text):
    """laminid's FRF reader (acquire --resume, fit-frf of a laminid-frf file) read the
    attribute itself: undecodable bytes were a UnicodeDecodeError, said as a "damaged or
    malformed laminid FRF file"; they are now a file of another format, named as format_of
    gives it, as fit-frf's reader of other tools' files (with its own copy, _text) did."""
    from laminid_cli.errors import FrfError
    from laminid_cli.frf.store import read_frf_h5

    odd = h5(tmp_path / "odd.h5", format=value)
    with pytest.raises(FrfError) as err:
        read_frf_h5(odd, probe=False)
    assert str(err.value) == (f"{odd}: not a laminid FRF file (attribute 'format' is "
                              f"{text!r}, expected 'laminid-frf')")
    with pytest.raises(FrfError) as err:
        read_frf_h5(h5(tmp_path / "none.h5"), probe=False)
    assert str(err.value) == (f"{tmp_path / 'none.h5'}: not a laminid FRF file (no attribute "
                              "'format', expected 'laminid-frf')")


def test_acquire_resume_of_a_file_with_an_undecodable_format_names_it(tmp_path):
    from tests.instrument.emulator import HP35670AEmulator

    odd = h5(tmp_path / "odd.h5", format=np.bytes_(b"laminid-fr\xff"))
    with HP35670AEmulator() as emu:
        r = run("acquire", "--analyser", emu.resource, "--timeout", "0.5", "--points", "2",
                "--no-prompt", "--resume", "-o", odd)
    assert r.exit_code == 2, r.output
    assert r.output == (f"laminid: error: {odd}: not a laminid FRF file (attribute 'format' is "
                        "'laminid-fr\ufffd', expected 'laminid-frf')\n")
