"""What a file is from its first bytes, where laminid reads text and is given a binary file by
mistake: one table of signatures (leading bytes) for the readers that say so, each adding its
own words (a specimen: :func:`laminid_cli.specimen.not_a_specimen`; an FRF text file:
:func:`laminid_cli.frf.io.describe_content`; batch's inputs: ``HDF5_MAGIC``)."""

from __future__ import annotations

#: leading bytes of an HDF5 file (an FRF, result or modes file of laminid, or another tool's)
HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"

#: (leading bytes, key, what the file is) of the binary files given for a text file
SIGNATURES = (
    (HDF5_MAGIC, "hdf5", "an HDF5 file"),
    (b"%PDF", "pdf", "a PDF document"),
    (b"PK\x03\x04", "zip", "a ZIP archive (an Excel or Word file?)"),
    (b"\x89PNG", "png", "a PNG image"),
    (b"\x1f\x8b", "gzip", "a gzip archive"),
)


def binary_kind(head: bytes) -> tuple[str, str] | None:
    """(key, what it is) of the file whose first bytes are ``head`` when they are one of
    :data:`SIGNATURES`, else None.

    >>> binary_kind(b"%PDF-1.7")
    ('pdf', 'a PDF document')
    """
    return next(((key, what) for magic, key, what in SIGNATURES if head.startswith(magic)),
                None)
