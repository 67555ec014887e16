"""The one table of file signatures (laminid_cli.filekinds) and its readers: a specimen's
(not_a_specimen) and an FRF text file's (frf.io.describe_content), which had a table each."""

import pytest

from laminid_cli import filekinds
from laminid_cli.filekinds import binary_kind
from laminid_cli.frf.io import describe_content
from laminid_cli.specimen import not_a_specimen

NOT_A_SPECIMEN = ", not a specimen file (YAML text)"

#: what to do with a workbook (a ZIP archive) given as FRFs
SAVE_AS_CSV = ("; a spreadsheet is read once its sheet is saved as CSV (File > Save As > CSV), "
               "the frequency in the first column")

#: first bytes, then the specimen reader's and the FRF reader's words (as each said before)
KINDS = [
    (b"\x89HDF\r\n\x1a\n\x00", "an HDF5 file (an FRF or result file?)" + NOT_A_SPECIMEN +
     ": FRFs go through 'laminid fit-frf FILE --into SPECIMEN.yaml' (or measured.frf_file in "
     "the specimen), a result through 'laminid report FILE'",
     ("an HDF5 file (laminid acquire's FRF file or another tool's)", "hdf5")),
    (b"%PDF-1.7\n", "a PDF document" + NOT_A_SPECIMEN, ("a PDF document", None)),
    (b"PK\x03\x04\x14", "a ZIP archive (an Excel or Word file?)" + NOT_A_SPECIMEN +
     "; write the specimen as YAML text (specimens/README.md)",
     ("a ZIP archive (an Excel or Word file?)" + SAVE_AS_CSV, None)),
    (b"\x89PNG\r\n\x1a\n", "a PNG image" + NOT_A_SPECIMEN, ("a PNG image", None)),
    (b"\x1f\x8b\x08", "a gzip archive" + NOT_A_SPECIMEN + "; unpack it first",
     ("a gzip archive", None)),
]


@pytest.mark.parametrize("head, specimen, frf", KINDS)
def test_each_signature_in_both_readers_words(tmp_path, head, specimen, frf):
    path = tmp_path / "file"
    path.write_bytes(head)
    assert not_a_specimen(head) == specimen
    assert describe_content(path) == frf


def test_text_is_no_binary_kind(tmp_path):
    assert binary_kind(b"name: S1.1\n") is None and not_a_specimen(b"name: S1.1\n") is None
    (tmp_path / "s.yaml").write_bytes(b"name: S1.1\n")
    assert describe_content(tmp_path / "s.yaml") == ("text whose first line is 'name: S1.1'",
                                                     None)


def test_a_signature_added_to_the_table_is_known_to_both_readers(tmp_path, monkeypatch):
    monkeypatch.setattr(filekinds, "SIGNATURES",
                        filekinds.SIGNATURES + ((b"\x7fELF", "elf", "a program (ELF)"),))
    (tmp_path / "a.out").write_bytes(b"\x7fELF\x02\x01")
    assert not_a_specimen(b"\x7fELF\x02\x01") == "a program (ELF)" + NOT_A_SPECIMEN
    assert describe_content(tmp_path / "a.out") == ("a program (ELF)", None)


@pytest.mark.parametrize("name", ["plate.csv", "plate.txt"])
def test_a_workbook_cut_to_its_signature_is_named_as_one(tmp_path, name):
    # 4 bytes 'PK\x03\x04' (an .xlsx cut short) are valid UTF-8: read as a CSV header without
    # data ("header but no data lines"); now a ZIP archive, and what to do with a workbook
    from laminid_cli.errors import FrfError
    from laminid_cli.frf.io import decode_text, read_frf

    path = tmp_path / name
    path.write_bytes(b"PK\x03\x04")
    assert decode_text(b"PK\x03\x04") == (None, None)
    with pytest.raises(FrfError) as err:
        read_frf(path)
    assert str(err.value) == (f"{path}: not a text (CSV) file; it looks like a ZIP archive (an "
                              "Excel or Word file?)" + SAVE_AS_CSV)
